"""The contact patch of one plane measured in an FE result, against Hertz.

The measure (:func:`measure_contact_patch`) reads the contact patch of one plane from a
:class:`~contact.solver.results.ContactResult`: the nodal contact forces ``f_i`` (normal to the
plane) and the tributary areas ``A_i`` of the contact nodes on the surface that faces the
plane. Two numbers come out, each from the local nodal forces and never from the total
force alone:

- the contact radius, from the second moment of the nodal forces about the load axis.
  For the Hertz profile ``int p r^2 dA / int p dA = 2 a^2 / 5``, so
  ``a^2 = 5/2 sum f_i r_i^2 / sum f_i``. This is a genuine check of the FE solution: it
  depends on how the force is spread over the patch, not on how large it is, while the
  Hertz radius it is compared with comes from the size of the total force. The nodal sum
  is the moment of the FE traction weighted by the bilinear (linear) interpolant of
  ``r^2``, which exceeds ``r^2`` by about ``h^2 / 3`` inside each cell of size ``h``
  (``I(r^2) >= r^2``, ``r^2`` being convex); :func:`measure_contact_patch` removes that
  interpolation excess, node by node, computed exactly by quadrature on the faces
  (:func:`interpolation_excess`). It is a property of the estimator, not of the solution:
  the uncorrected value is reported too.
- the peak pressure, from a least-squares fit of the Hertz profile to the nodal forces of
  the interior of the patch: the consistent nodal forces of ``p0 sqrt(1 - r^2/a^2)`` are
  ``p0 g_i(a)``, ``g_i(a) = int N_i sqrt(1 - r^2/a^2) dA`` (by quadrature on the faces), so
  for each ``a`` the best ``p0`` is a linear least-squares one and ``a`` is found by a
  bounded scalar search on the misfit. Fed the consistent forces of an exact Hertz
  pressure the fit returns ``p0`` and ``a`` to 1e-4 on any mesh, so what it measures on
  an FE solution is the solution's error. Only nodes at least ``edge_cells`` cell sizes
  inside the moment radius take part: at the discrete edge of the patch the forces of the
  cells cut by the true edge are lumped onto the last contact nodes and do not measure
  the pressure there. The fit also gives a second radius. A lumped variant fits
  ``p_i = f_i / A_i`` (force over tributary area: the traction recovered with the lumped
  surface mass matrix), where ``p^2 = p0^2 - (p0/a)^2 r^2`` is linear in ``r^2``; it is
  biased low by the lumping (by less as the cells across ``a`` grow) and is reported
  beside. ``p0 = 3 F / (2 pi a^2)`` with ``a`` the moment radius would be no
  check at all (it is ``F`` and ``a`` again), which is why the peak is fitted to the
  local forces.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import minimize_scalar

import fem

from ..errors import ContactError
from ..geometry.plane import Plane
from ..solver.results import ContactResult
from .hertz_theory import HertzSolution

__all__ = [
    "ContactPatch",
    "HertzErrors",
    "interpolation_excess",
    "measure_contact_patch",
    "moment_radius",
]


def moment_radius(r: ArrayLike, f: ArrayLike) -> float:
    """Contact radius from the second moment of a Hertzian load: ``sqrt(5/2 sum f r^2 / sum f)``.

    ``r`` are the distances of the loaded points from the load axis, ``f`` their normal
    forces. Exact for ``p = p0 sqrt(1 - r^2 / a^2)``, whose ``int p r^2 dA / int p dA`` is
    ``2 a^2 / 5``; nodal forces of an FE traction need the correction of
    :func:`interpolation_excess`, which :func:`measure_contact_patch` applies.
    """
    r = np.asarray(r, dtype=np.float64)
    f = np.asarray(f, dtype=np.float64)
    return math.sqrt(2.5 * float(f @ r**2) / float(f.sum()))


# --- surface quadrature ---------------------------------------------------------------

_G3 = np.array([-math.sqrt(0.6), 0.0, math.sqrt(0.6)])
_W3 = np.array([5.0, 8.0, 5.0]) / 9.0


def _quad_rule(k: int) -> tuple[NDArray, NDArray]:
    """Shape functions ``(q, k)`` and weights ``(q,)`` on the reference face (area 1 or 1/2)."""
    if k == 4:  # bilinear quad on [-1, 1]^2, 3x3 Gauss; weights for the unit square
        u, v = np.meshgrid(_G3, _G3, indexing="ij")
        u, v = u.ravel(), v.ravel()
        w = np.outer(_W3, _W3).ravel() / 4.0
        n = 0.25 * np.stack(
            [(1 - u) * (1 - v), (1 + u) * (1 - v), (1 + u) * (1 + v), (1 - u) * (1 + v)], 1
        )
        return n, w
    # linear triangle: Strang-Fix 6-point rule (degree 4), weights summing to 1
    a, b = 0.445948490915965, 0.091576213509771
    pts = np.array([[a, a], [1 - 2 * a, a], [a, 1 - 2 * a], [b, b], [1 - 2 * b, b], [b, 1 - 2 * b]])
    w = np.array([0.223381589678011] * 3 + [0.109951743655322] * 3)
    n = np.column_stack([1 - pts.sum(1), pts[:, 0], pts[:, 1]])
    return n, w


def _face_geometry(points: NDArray, faces: NDArray[np.int64]) -> tuple[NDArray, NDArray, NDArray]:
    """Shape functions ``(q, k)``, quadrature points ``(f, q, 3)`` and ``dA`` ``(f, q)``."""
    k = faces.shape[1]
    n, w = _quad_rule(k)
    x = points[faces]  # (f, k, 3)
    xq = np.einsum("qk,fkd->fqd", n, x)
    if k == 3:
        area = 0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), axis=1)
        return n, xq, area[:, None] * w[None, :] * 1.0
    u = np.sqrt(0.6) * np.array([-1, 0, 1])
    uu, vv = np.meshgrid(u, u, indexing="ij")
    uu, vv = uu.ravel(), vv.ravel()
    dndu = 0.25 * np.stack([-(1 - vv), (1 - vv), (1 + vv), -(1 + vv)], 1)
    dndv = 0.25 * np.stack([-(1 - uu), -(1 + uu), (1 + uu), (1 - uu)], 1)
    xu = np.einsum("qk,fkd->fqd", dndu, x)
    xv = np.einsum("qk,fkd->fqd", dndv, x)
    jac = np.linalg.norm(np.cross(xu, xv), axis=2)  # (f, q), on [-1, 1]^2
    return n, xq, 4.0 * jac * w[None, :]


def _facing_faces(mesh: fem.Mesh, normal: NDArray, nodes: NDArray[np.int64]) -> list[NDArray]:
    """Boundary faces touching ``nodes`` whose outward normal is within 60 deg of ``-normal``."""
    on = np.zeros(mesh.n_points, dtype=bool)
    on[nodes] = True
    out = []
    for f in mesh.boundary.faces.values():
        if len(f) == 0:
            continue
        x = mesh.points[f]
        nf = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
        if f.shape[1] == 4:
            nf = np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 1])
        cos = -(nf @ normal) / np.linalg.norm(nf, axis=1)
        out.append(f[(cos > 0.5) & on[f].any(axis=1)])
    return out


def _axis_r2(x: NDArray, center: NDArray, normal: NDArray) -> NDArray:
    """Squared distance of points from the axis through ``center`` along ``normal``."""
    d = x - center
    return np.einsum("...d,...d->...", d, d) - (d @ normal) ** 2


def interpolation_excess(
    mesh: fem.Mesh, faces: list[NDArray], center: ArrayLike, normal: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Tributary areas and the excess of the interpolated ``r^2`` over ``r^2``, per node.

    With ``N_i`` the face shape functions and ``I(r^2) = sum_j N_j r_j^2``, node ``i`` gets
    ``A_i = int N_i dA`` and ``c_i = int N_i (I(r^2) - r^2) dA / A_i`` over the given faces
    (3x3 Gauss on quads, a degree-4 rule on triangles). A traction ``p`` with consistent
    nodal forces ``f_i = int N_i p dA`` has ``sum f_i r_i^2 = int p I(r^2) dA``, so
    ``sum f_i (r_i^2 - c_i)`` is ``int p r^2 dA`` up to the variation of ``p`` across one
    cell. ``A_i`` equals the tributary area of :func:`contact.geometry.plane.tributary_areas`
    on flat faces.

    Returns
    -------
    areas, excess : ndarray, shape (n_points,)
        Zero on nodes of no face.
    """
    c = np.asarray(center, dtype=np.float64)
    nrm = np.asarray(normal, dtype=np.float64)
    area = np.zeros(mesh.n_points)
    excess = np.zeros(mesh.n_points)
    for f in faces:
        if len(f) == 0:
            continue
        n, xq, da = _face_geometry(mesh.points, f)
        r2n = _axis_r2(mesh.points[f], c, nrm)  # (f, k)
        e = n @ r2n.T  # (q, f): interpolated r^2
        e = e.T - _axis_r2(xq, c, nrm)  # (f, q)
        area += np.bincount(f.ravel(), np.einsum("qk,fq->fk", n, da).ravel(), mesh.n_points)
        excess += np.bincount(f.ravel(), np.einsum("qk,fq->fk", n, da * e).ravel(), mesh.n_points)
    with np.errstate(invalid="ignore", divide="ignore"):
        return area, np.where(area > 0, excess / np.where(area > 0, area, 1.0), 0.0)


@dataclass(frozen=True)
class ContactPatch:
    """The contact patch of one plane, measured from the nodal contact forces.

    Forces are those of the whole patch: a model cut by symmetry planes holding
    ``fraction`` of it has its forces divided by ``fraction``.

    Attributes
    ----------
    force : float
        Total normal force on the patch (N).
    center : ndarray, shape (3,)
        Centre of the patch: the given one, or the force-weighted centroid of its nodes.
    nodes : ndarray of int
        The contact nodes of this plane.
    r : ndarray
        Their distances from the load axis (undeformed positions, as in linear theory).
    f : ndarray
        Their normal forces, as in the model (N).
    areas : ndarray
        Their tributary areas on the faces facing the plane (m^2).
    pressure : ndarray
        Nodal pressures ``f / areas`` (Pa).
    contact_radius : float
        Moment radius with the interpolation excess removed (m): the estimate.
    contact_radius_nodal : float
        Moment radius from the nodal ``r_i^2`` as they are (m).
    peak_pressure : float
        ``p0`` of the Hertz profile whose consistent nodal forces best fit the interior
        nodal forces (Pa): the estimate.
    fit_radius : float
        ``a`` of that fit (m): an independent radius.
    peak_pressure_lumped, fit_radius_lumped : float
        The same fitted to the lumped nodal pressures ``f_i / A_i`` (Pa, m).
    fit_nodes : int
        Nodes in the fit.
    """

    force: float
    center: NDArray[np.float64]
    nodes: NDArray[np.int64]
    r: NDArray[np.float64]
    f: NDArray[np.float64]
    areas: NDArray[np.float64]
    pressure: NDArray[np.float64]
    contact_radius: float
    contact_radius_nodal: float
    peak_pressure: float
    fit_radius: float
    peak_pressure_lumped: float
    fit_radius_lumped: float
    fit_nodes: int

    def errors(self, hertz: HertzSolution) -> tuple[float, float]:
        """Relative errors of the contact radius and the peak pressure against ``hertz``."""
        return (
            self.contact_radius / hertz.contact_radius - 1.0,
            self.peak_pressure / hertz.peak_pressure - 1.0,
        )


def measure_contact_patch(
    mesh: fem.Mesh,
    result: ContactResult,
    plane: Plane,
    *,
    center: ArrayLike | None = None,
    fraction: float = 1.0,
    edge_cells: float = 2.0,
) -> ContactPatch:
    """Contact radius and peak pressure of the patch against one plane, from nodal forces.

    How (see the module notes): the contact nodes of the plane are those pushed off it
    (``f . n > 0``); ``r_i`` is their distance from the load axis through ``center`` along
    the plane's normal; ``A_i`` their tributary area on the boundary faces that face the
    plane (so symmetry-plane faces are left out). The radius is the moment radius
    ``sqrt(5/2 sum f_i (r_i^2 - c_i) / sum f_i)``, ``c_i`` the interpolation excess of
    :func:`interpolation_excess`; the peak pressure is ``p0`` of the least-squares fit
    ``f_i = p0 int N_i sqrt(1 - r^2/a^2) dA`` (and, lumped, of
    ``p_i^2 = p0^2 - (p0/a)^2 r_i^2`` with ``p_i = f_i / A_i``) over the nodes with
    ``r_i <= a_m - edge_cells h``, ``a_m`` the moment radius and ``h`` the square root of
    the median tributary area in the patch (at least three nodes are kept: the ones
    nearest the centre).

    Parameters
    ----------
    mesh : fem.Mesh
        The body's mesh.
    result : ContactResult
        Its contact solve.
    plane : Plane
        The plane whose patch to measure.
    center : array_like, shape (3,), optional
        A point on the load axis; by default the force-weighted centroid of the patch.
        Give it for a model cut by symmetry planes (the axis is their intersection).
    fraction : float
        Share of the patch in the model: 1 whole, 1/2 or 1/4 when one or two symmetry
        planes through the axis cut it. Only the total force depends on it.
    edge_cells : float
        How many cell sizes inside the moment radius the pressure fit stops.

    Returns
    -------
    ContactPatch

    Raises
    ------
    ContactError
        If the plane has fewer than three contact nodes.
    """
    if not 0 < fraction <= 1:
        raise ContactError(f"fraction must lie in (0, 1], got {fraction!r}")
    nrm = plane.normal
    fn = result.contact_force @ nrm
    nodes = np.flatnonzero(fn > 0)
    if len(nodes) < 3:
        raise ContactError(f"{plane.name}: {len(nodes)} contact nodes, too few to measure")
    f = fn[nodes]
    x = mesh.points[nodes]
    c = (f @ x) / f.sum() if center is None else np.asarray(center, dtype=np.float64)
    faces = _facing_faces(mesh, nrm, nodes)
    area, excess = interpolation_excess(mesh, faces, c, nrm)
    r2 = _axis_r2(x, c, nrm)
    a_nodal = math.sqrt(2.5 * float(f @ r2) / f.sum())
    a_mom = math.sqrt(2.5 * float(f @ (r2 - excess[nodes])) / f.sum())
    areas = area[nodes]
    p = f / areas
    r = np.sqrt(r2)
    h = math.sqrt(float(np.median(areas)))
    inner = r <= a_mom - edge_cells * h
    if inner.sum() < 3:
        inner = np.zeros(len(r), dtype=bool)
        inner[np.argsort(r)[:3]] = True
    # lumped: p_i^2 = p0^2 - (p0^2 / a^2) r_i^2, linear least squares weighted by area
    w = np.sqrt(areas[inner])
    lhs = np.column_stack([np.ones(inner.sum()), -r2[inner]]) * w[:, None]
    sol, *_ = np.linalg.lstsq(lhs, p[inner] ** 2 * w, rcond=None)
    p0_lumped = math.sqrt(max(sol[0], 0.0))
    a_lumped = math.sqrt(sol[0] / sol[1]) if sol[1] > 0 else math.inf
    # consistent: f_i = p0 g_i(a), g_i(a) = int N_i sqrt(1 - r^2/a^2) dA; p0(a) linear,
    # a by a bounded scalar search on the residual
    geo = [(fc, *_face_geometry(mesh.points, fc)) for fc in faces if len(fc)]
    row = np.full(mesh.n_points, -1, dtype=np.int64)
    row[nodes[inner]] = np.arange(inner.sum())
    fi = f[inner]

    def shape(a: float) -> NDArray[np.float64]:
        g = np.zeros(mesh.n_points)
        for fc, n, xq, da in geo:
            prof = np.sqrt(np.clip(1.0 - _axis_r2(xq, c, nrm) / a**2, 0.0, None))
            g += np.bincount(fc.ravel(), np.einsum("qk,fq->fk", n, prof * da).ravel(), len(g))
        return g[nodes[inner]]

    def misfit(a: float) -> float:
        g = shape(a)
        return float(np.sum((fi - (fi @ g) / (g @ g) * g) ** 2))

    best = minimize_scalar(
        misfit,
        bounds=(0.5 * a_mom, 2.0 * a_mom),
        method="bounded",
        options={"xatol": 1e-10 * a_mom},
    )
    a_fit = float(best.x)
    g = shape(a_fit)
    p0 = float(fi @ g / (g @ g))
    return ContactPatch(
        force=float(f.sum()) / fraction,
        center=c,
        nodes=nodes,
        r=r,
        f=f,
        areas=areas,
        pressure=p,
        contact_radius=a_mom,
        contact_radius_nodal=a_nodal,
        peak_pressure=p0,
        fit_radius=a_fit,
        peak_pressure_lumped=p0_lumped,
        fit_radius_lumped=a_lumped,
        fit_nodes=int(inner.sum()),
    )


class HertzErrors:
    """``radius_error`` and ``pressure_error`` of a result's ``patch`` against its ``hertz``.

    A base of the result classes that hold both (plates, two bodies, the SfePy peer).
    """

    patch: ContactPatch
    hertz: HertzSolution

    @property
    def radius_error(self) -> float:
        """Relative error of the measured contact radius against Hertz."""
        return self.patch.errors(self.hertz)[0]

    @property
    def pressure_error(self) -> float:
        """Relative error of the measured peak pressure against Hertz."""
        return self.patch.errors(self.hertz)[1]
