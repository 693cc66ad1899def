"""Mortar (segment-to-segment) coupling of a slave and a master contact surface.

What is integrated
------------------
Frictionless contact is enforced weakly: the gap field ``g`` between the surfaces is
tested with a multiplier field ``lambda_h = sum_i Phi_i lambda_i`` on the slave surface.
With the slave's own shape functions as multipliers (``Phi_i = N_i^s``), the weak gap of
slave node ``i`` is::

    g_i = n_i . (sum_j D_ij x_j^s - sum_k M_ik x_k^m)
    D_ij = int N_i^s N_j^s dA        M_ik = int N_i^s N_k^m dA

both integrals over the part of the slave surface that the master covers (the
*overlap*), ``N^m`` evaluated at the point of the master facing the slave point. They
are computed segment to segment (Puso & Laursen 2004; Popp, Gitterle, Gee & Wall 2010):
each slave facet defines an auxiliary plane (its own plane; for a quad, the plane through
its centre normal to its mean normal); every master facet within ``search`` of it and
facing it is projected onto that plane along the plane's normal and clipped with the
slave facet (Sutherland-Hodgman, convex polygons, vectorised over the facet pairs); the
clip polygon is fan-triangulated and integrated with a Gauss rule on each sub-triangle:
degree 2 (exact for products of linears) when both facets are triangles, degree 5 when a
quad is involved (exact for products of bilinears on parallelograms). ``N^s`` and
``N^m`` are the facets' linear (triangle) or bilinear (quad) shape functions at the
point's parametric coordinates in the projected facets. Quads are kept as quads: a hex
mesh's trace on its boundary is bilinear, and splitting its faces into triangles makes
the coupling inconsistent with the bodies: the contact patch test of two hex blocks then
fails by 8 to 15 % of the pressure. Pass ``ElasticBody.contact_faces``, not its
``contact_triangles``.

The gap is measured between the two surfaces smoothed through their nodal normals
(:mod:`contact.solver.smoothing`): ``g0`` gains ``n_i . int N_i^s (b_s - b_m) dA``, each
surface's bulge ``b`` off its flat facet at the paired points, while the displacements
still enter through the facets' shape functions. A coarse mesh's facets lie inside the
curved surface they stand for by their sagitta, as much as a small press: a ball of 6 mm
bricks pressed 1 mm onto a block is 37 % under Hertz by flat facets, 3.5 % over smoothed
(``tests/solver/test_mortar_hertz.py``). Flat faces and sharp edges stay as meshed.

On flat faces the integration is exact: ``D 1 = M 1 = (int N_i^s)_i`` (the row areas),
``sum(D) = sum(M)`` = the covered slave area, and linear fields pass from master to slave
exactly (``D^-1 M x_m = x_s``): the contact patch test is passed (two blocks with
non-matching meshes transmit a uniform pressure uniformly, whichever is the slave and
whichever is the stiffer), which node-to-surface rows do not.

Multipliers: standard, not dual
-------------------------------
Dual multipliers (``int Phi_i N_j^s = delta_ij int N_j^s``) would make ``D`` diagonal, so
that each row involves a single slave node and the active set and the condensation of the
multipliers are node by node. They are the better choice for a primal-dual active-set
Newton solver. This solver works in contact space instead (``W lambda = -gap`` with the
dense Delassus operator ``W``), where a banded ``D`` costs nothing, and standard
multipliers give a pressure field that is positive wherever the nodal values are
(dual shape functions are negative over part of each facet, so a positive
``lambda_i`` can still give a locally negative pressure, and partially covered facets need
special handling). Hence standard multipliers.

How the contact solver uses it
------------------------------
One row per slave node with a nonzero overlap area (``slave_nodes``, a few per facet).
:meth:`MortarCoupling.rows` gives each body's part of the rows in the solver's
convention (``g = g0 + E_slave u_slave + E_master u_master``, the normal ``n_i`` pointing
from the master into the slave, like ``ContactRows.normal``). By default the rows are
divided by their area ``area_i``: the row's gap is then a length (the ``N_i``-weighted
mean gap, :attr:`MortarCoupling.mean_gap0` in the reference geometry) and its multiplier
``lambda_i`` a force, so the existing rows, tolerances and Delassus solve work unchanged;
the nodal contact pressure is ``lambda_i / area_i`` (the pressure field is
``sum_i N_i lambda_i / area_i``). The active set is decided on the weighted gaps ``g_i``
(closed where ``g_i <= 0``) and ``lambda_i >= 0`` (released where negative). The
coupling uses the reference geometry; rebuild it when the surfaces slide by more than a
fraction of a facet.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from fem.elements import TRI_RULE5

from .smoothing import bulge, corner_normals

__all__ = ["MortarCoupling", "mortar_coupling"]

# Gauss rules on a triangle: barycentric points (q, 3), weights as fractions of its area
_RULE2 = (
    np.array([[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]]),
    np.full(3, 1 / 3),
)
_RULE5 = TRI_RULE5
_CHUNK = 20_000  # facet pairs integrated at once
_NEWTON = 30  # iterations cap of the inverse bilinear map


@dataclass(frozen=True)
class MortarCoupling:
    """Mortar integrals of a slave surface against a master surface.

    Attributes
    ----------
    slave_nodes : ndarray of int64, shape (s,)
        Slave surface nodes with a row (a nonzero overlap area), sorted, in the numbering
        of the slave points (the volume mesh's).
    normals : ndarray, shape (s, 3)
        Each row's unit normal: the outward normals of the master facets it overlaps,
        weighted by the row's overlap integrals ``int N_i dA`` over each, pointing from
        the master into the slave (the sense of the node-to-surface rows' normal). The
        master's, not the slave's: ``M`` is kept where it was integrated, and a gap
        along the master's normal does not change when the slave slides along the
        master, where one along a curved slave's normal would (a ball sliding down a
        flat pad would wedge itself).
    d : scipy.sparse.csr_matrix, shape (s, n_slave_points)
        ``D_ij = int N_i^s N_j^s dA`` over the overlap (m^2).
    m : scipy.sparse.csr_matrix, shape (s, n_master_points)
        ``M_ik = int N_i^s N_k^m dA`` over the overlap, ``N^m`` at the projection (m^2).
    gap0 : ndarray, shape (s,)
        Weighted gaps of the reference geometry ``n_i . (D_i x_s - M_i x_m)`` (m^3),
        positive where the surfaces are apart.
    area : ndarray, shape (s,)
        ``int N_i^s dA`` over the overlap: each row's area (m^2).
    """

    slave_nodes: NDArray[np.int64]
    normals: NDArray[np.float64]
    d: sp.csr_matrix
    m: sp.csr_matrix
    gap0: NDArray[np.float64]
    area: NDArray[np.float64]

    def __len__(self) -> int:
        return int(self.slave_nodes.size)

    @property
    def mean_gap0(self) -> NDArray[np.float64]:
        """``gap0 / area``: each row's ``N_i``-weighted mean gap (m), the per-area rows' ``g0``."""
        return self.gap0 / self.area

    def rows(
        self, n_slave_points: int, n_master_points: int, *, per_area: bool = True
    ) -> tuple[sp.csr_matrix, sp.csr_matrix]:
        """Each body's part of the gap rows: ``g = g0 + E_slave u_s + E_master u_m``.

        Parameters
        ----------
        n_slave_points, n_master_points : int
            Nodes of the slave and master bodies (3 DOFs each, DOF ``3 * node + c``).
        per_area : bool
            Divide row ``i`` by ``area_i`` (default): the gap is then a length
            (``g0 = mean_gap0``), its multiplier a force and ``lambda_i / area_i`` the nodal
            pressure. Otherwise ``E_slave = n_i (x) D_i`` and ``E_master = -n_i (x) M_i``
            (``g0 = gap0``, the multiplier a pressure).

        Returns
        -------
        e_slave : scipy.sparse.csr_matrix, shape (s, 3 n_slave_points)
        e_master : scipy.sparse.csr_matrix, shape (s, 3 n_master_points)
        """
        if n_slave_points < self.d.shape[1] or n_master_points < self.m.shape[1]:
            raise ValueError(
                f"the coupling spans {self.d.shape[1]} slave and {self.m.shape[1]} master "
                f"points, got {n_slave_points} and {n_master_points}"
            )
        scale = 1.0 / self.area if per_area else np.ones(len(self))
        return (
            _expand(self.d, scale, self.normals, n_slave_points),
            _expand(self.m, -scale, self.normals, n_master_points),
        )


def _expand(a: sp.csr_matrix, scale: NDArray, normals: NDArray, n_points: int) -> sp.csr_matrix:
    """``scale_i n_i (x) A_i`` as a ``(s, 3 n_points)`` matrix, DOF ``3 * node + c``."""
    c = a.tocoo()
    r = np.repeat(c.row, 3)
    col = (3 * c.col[:, None] + np.arange(3)).ravel()
    v = ((scale[c.row] * c.data)[:, None] * normals[c.row]).ravel()
    return sp.csr_matrix((v, (r, col)), shape=(a.shape[0], 3 * n_points))


def _blocks(facets: ArrayLike | Mapping[str, ArrayLike], name: str) -> list[NDArray[np.int64]]:
    """Facets as a list of ``(F, 3)`` triangle and ``(F, 4)`` quad arrays (empty ones dropped)."""
    if hasattr(facets, "faces"):  # fem.BoundaryFaces
        facets = facets.faces  # type: ignore[union-attr]
    parts = list(facets.values()) if isinstance(facets, Mapping) else [facets]
    out = []
    for p in parts:
        a = np.asarray(p, dtype=np.int64)
        if a.ndim != 2 or a.shape[1] not in (3, 4):
            raise ValueError(f"{name} facets must be (F, 3) triangles or (F, 4) quads")
        if a.size:
            out.append(a)
    if not out:
        raise ValueError(f"no {name} facets")
    return out


@dataclass(frozen=True)
class _Facets:
    """Geometry of a block of facets: centres, unit normals, vector areas, boxes, frames."""

    conn: NDArray[np.int64]
    centre: NDArray[np.float64]
    normal: NDArray[np.float64]
    vector_area: NDArray[np.float64]
    lo: NDArray[np.float64]
    hi: NDArray[np.float64]
    t1: NDArray[np.float64]
    t2: NDArray[np.float64]

    @classmethod
    def of(cls, points: NDArray[np.float64], conn: NDArray[np.int64], name: str) -> _Facets:
        x = points[conn]
        if conn.shape[1] == 3:
            va = 0.5 * np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
        else:
            va = 0.5 * np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 1])
        size = np.linalg.norm(va, axis=1)
        if (size <= 0).any():
            raise ValueError(f"{name} facet {int(np.argmin(size))} has no area")
        n = va / size[:, None]
        t1 = x[:, 1] - x[:, 0]
        t1 -= np.einsum("fi,fi->f", t1, n)[:, None] * n
        t1 /= np.linalg.norm(t1, axis=1)[:, None]
        return cls(conn, x.mean(axis=1), n, va, x.min(axis=1), x.max(axis=1), t1, np.cross(n, t1))


def _candidates(s: _Facets, m: _Facets, search: float) -> tuple[NDArray, NDArray]:
    """Facet pairs whose boxes come within ``search`` and whose normals face each other."""
    rs = (s.hi - s.lo).max(axis=1).max() / 2 if len(s.conn) else 0.0
    rm = (m.hi - m.lo).max(axis=1).max() / 2 if len(m.conn) else 0.0
    cs, cm = (s.lo + s.hi) / 2, (m.lo + m.hi) / 2
    pairs = cKDTree(cs).sparse_distance_matrix(
        cKDTree(cm), rs + rm + search, p=np.inf, output_type="ndarray"
    )
    i, j = pairs["i"].astype(np.int64), pairs["j"].astype(np.int64)
    keep = np.all((s.lo[i] - search <= m.hi[j]) & (m.lo[j] <= s.hi[i] + search), axis=1)
    # facing; a master facet (nearly) perpendicular to the slave projects onto nothing
    keep &= np.einsum("pi,pi->p", s.normal[i], m.normal[j]) < -1e-6
    order = np.lexsort((j[keep], i[keep]))
    return i[keep][order], j[keep][order]


def _cross2(a: NDArray, b: NDArray) -> NDArray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _clip(subject: NDArray, clip: NDArray) -> tuple[NDArray, NDArray]:
    """Sutherland-Hodgman: convex ``subject`` polygons (P, k, 2) clipped by ``clip`` (P, c, 2).

    ``clip`` is counter-clockwise; the result (P, k + c + 2, 2) holds ``count`` (P,) vertices.
    """
    p, k, _ = subject.shape
    c = clip.shape[1]
    w = k + c + 2  # k + c at most for convex polygons; slack for round-off duplicates
    poly = np.zeros((p, w, 2))
    poly[:, :k] = subject
    count = np.full(p, k)
    slots = np.arange(w)
    rows = np.arange(p)[:, None]
    for e in range(c):
        a, b = clip[:, e], clip[:, (e + 1) % c]
        edge = b - a
        tol = 1e-13 * np.einsum("pi,pi->p", edge, edge)[:, None]
        dist = _cross2(edge[:, None], poly - a[:, None])  # > 0 inside
        nxt = slots[None, :] + 1
        nxt = np.where(nxt >= count[:, None], 0, nxt)
        valid = slots[None, :] < count[:, None]
        d_next = dist[rows, nxt]
        p_next = poly[rows, nxt]
        inside, inside_next = dist >= -tol, d_next >= -tol
        keep = valid & inside
        cut = valid & (inside != inside_next)
        with np.errstate(invalid="ignore", divide="ignore"):
            t = np.where(cut, dist / (dist - d_next), 0.0)
        x = poly + t[..., None] * (p_next - poly)
        cand = np.stack([poly, x], axis=2).reshape(p, 2 * w, 2)
        mask = np.stack([keep, cut], axis=2).reshape(p, 2 * w)
        order = np.argsort(~mask, axis=1, kind="stable")[:, :w]
        poly = cand[rows, order]
        count = np.minimum(mask.sum(axis=1), w)
    return poly, count


def _shape(facet: NDArray, x: NDArray) -> NDArray:
    """Shape functions (n, k) of planar triangles or quads (n, k, 2) at points (n, 2)."""
    if facet.shape[1] == 3:
        e1, e2 = facet[:, 1] - facet[:, 0], facet[:, 2] - facet[:, 0]
        det = _cross2(e1, e2)
        r = x - facet[:, 0]
        l1 = _cross2(r, e2) / det
        l2 = _cross2(e1, r) / det
        return np.stack([1 - l1 - l2, l1, l2], axis=-1)
    # bilinear on [0, 1]^2: x = x0 + a xi + b eta + c xi eta, inverted by Newton (exact in
    # one step on parallelograms; quadratic: a step below 1e-12 leaves ~1e-24)
    a = facet[:, 1] - facet[:, 0]
    b = facet[:, 3] - facet[:, 0]
    c = facet[:, 2] - facet[:, 1] - facet[:, 3] + facet[:, 0]
    r0 = facet[:, 0] - x
    xi = np.full(len(x), 0.5)
    eta = np.full(len(x), 0.5)
    for _ in range(_NEWTON):
        r = r0 + a * xi[:, None] + b * eta[:, None] + c * (xi * eta)[:, None]
        jx = a + c * eta[:, None]  # d x / d xi
        je = b + c * xi[:, None]  # d x / d eta
        det = _cross2(jx, je)
        dxi = _cross2(r, je) / det
        deta = _cross2(jx, r) / det
        xi -= dxi
        eta -= deta
        if max(np.abs(dxi).max(initial=0.0), np.abs(deta).max(initial=0.0)) < 1e-12:
            break
    return np.stack([(1 - xi) * (1 - eta), xi * (1 - eta), xi * eta, (1 - xi) * eta], axis=-1)


def _integrate(
    xs: NDArray,
    xm: NDArray,
    s: _Facets,
    i: NDArray,
    rule: tuple[NDArray, NDArray],
    corners: tuple[NDArray, NDArray] | None = None,
) -> tuple[NDArray, NDArray, NDArray]:
    """Local ``D`` (P, ks, ks), ``M`` (P, ks, km) and bulge (P, ks, 3) of slave facets ``i``.

    ``xs`` (P, ks, 3) and ``xm`` (P, km, 3) are the facets' vertices. With ``corners``
    (their corner normals, (P, ks, 3) and (P, km, 3)), the bulge is
    ``int N_i (b_s - b_m) dA``: how far the smoothed surfaces lie from the flat facets
    (:func:`contact.solver.smoothing.bulge`), zero without.
    """
    c, t1, t2 = s.centre[i][:, None], s.t1[i][:, None], s.t2[i][:, None]
    ps = np.stack([((xs - c) * t1).sum(-1), ((xs - c) * t2).sum(-1)], axis=-1)
    pm = np.stack([((xm - c) * t1).sum(-1), ((xm - c) * t2).sum(-1)], axis=-1)
    poly, count = _clip(pm, ps)
    # fan triangles (p0, pa, pb) of the clip polygons with an area
    p0 = poly[:, :1]
    pa, pb = poly[:, 1:-1], poly[:, 2:]
    area = 0.5 * np.abs(_cross2(pa - p0, pb - p0))
    area[np.arange(pa.shape[1])[None, :] + 2 >= count[:, None]] = 0.0
    pair, tri = np.nonzero(area > 0)
    bary, w = rule
    q = len(w)
    pts = np.einsum("qk,tkj->tqj", bary, np.stack([poly[pair, 0], pa[pair, tri], pb[pair, tri]], 1))
    pts = pts.reshape(-1, 2)
    wq = (area[pair, tri][:, None] * w).ravel()
    at = np.repeat(pair, q)
    ns, nm = _shape(ps[at], pts), _shape(pm[at], pts)
    d = np.zeros((len(i), ps.shape[1], ps.shape[1]))
    m = np.zeros((len(i), ps.shape[1], pm.shape[1]))
    lifted = np.zeros((len(i), ps.shape[1], 3))
    if at.size:
        start = np.flatnonzero(np.r_[True, at[1:] != at[:-1]])
        wns = wq[:, None] * ns
        d[at[start]] = np.add.reduceat(wns[:, :, None] * ns[:, None, :], start)
        m[at[start]] = np.add.reduceat(wns[:, :, None] * nm[:, None, :], start)
        if corners is not None:
            b = bulge(xs[at], corners[0][at], ns) - bulge(xm[at], corners[1][at], nm)
            lifted[at[start]] = np.add.reduceat(wns[:, :, None] * b[:, None, :], start)
    return d, m, lifted


def mortar_coupling(
    slave_points: ArrayLike,
    slave_facets: ArrayLike | Mapping[str, ArrayLike],
    master_points: ArrayLike,
    master_facets: ArrayLike | Mapping[str, ArrayLike],
    *,
    search: float,
    min_fraction: float = 1e-13,
    smooth: bool = True,
) -> MortarCoupling:
    """Mortar integrals ``D`` and ``M`` of a slave surface against a master surface.

    Parameters
    ----------
    slave_points : array_like, shape (Ns, 3)
        Nodes of the slave body (e.g. its volume mesh's points).
    slave_facets : array_like or mapping
        Slave surface facets, counter-clockwise seen from outside the slave body:
        ``(F, 3)`` triangles or ``(F, 4)`` (planar, convex) quads, or a mapping
        ``{"triangle": ..., "quad": ...}`` (e.g. a :class:`fem.BoundaryFaces`' ``faces``).
    master_points : array_like, shape (Nm, 3)
        Nodes of the master body.
    master_facets : array_like or mapping
        Master surface facets, outward like the slave's (so that they face it).
    search : float
        Master facets whose bounding boxes come within this distance of a slave facet's
        (and whose normals face it) are integrated against it (m).
    min_fraction : float
        Rows whose overlap area is at most this fraction of the node's tributary area on
        the slave surface (clipping round-off) are dropped.
    smooth : bool
        Measure the gaps between both surfaces smoothed through their nodal normals
        (:mod:`contact.solver.smoothing`; default), so that a coarse mesh's facets do
        not hide a press as deep as their sagitta; the displacements still enter through
        the facets' shape functions. Flat faces and sharp edges stay as meshed.

    Returns
    -------
    MortarCoupling
    """
    xs_all = np.asarray(slave_points, dtype=np.float64)
    xm_all = np.asarray(master_points, dtype=np.float64)
    if xs_all.ndim != 2 or xs_all.shape[1] != 3 or xm_all.ndim != 2 or xm_all.shape[1] != 3:
        raise ValueError("points must be (N, 3) arrays")
    if not search >= 0:
        raise ValueError(f"search must be a non-negative distance, got {search}")
    ns_pts, nm_pts = len(xs_all), len(xm_all)
    s_blocks, m_blocks = _blocks(slave_facets, "slave"), _blocks(master_facets, "master")
    slaves = [_Facets.of(xs_all, b, "slave") for b in s_blocks]
    masters = [_Facets.of(xm_all, b, "master") for b in m_blocks]
    # each block's corner normals, to measure the gaps between the smoothed surfaces
    if smooth:
        s_corner = list(corner_normals(xs_all, dict(enumerate(s_blocks))).values())
        m_corner = list(corner_normals(xm_all, dict(enumerate(m_blocks))).values())
    # tributary areas over the whole slave surface
    trib = np.zeros(ns_pts)
    for s in slaves:
        k = s.conn.shape[1]
        trib += np.bincount(
            s.conn.ravel(), np.repeat(np.linalg.norm(s.vector_area, axis=1) / k, k), ns_pts
        )
    ncov = np.zeros((ns_pts, 3))
    lift = np.zeros((ns_pts, 3))
    dr, dc, dv, mr, mc, mv = [], [], [], [], [], []
    for a, s in enumerate(slaves):
        for b, m in enumerate(masters):
            i_all, j_all = _candidates(s, m, float(search))
            # degree 2 is exact for products of linears; the smoothed bulge is quadratic
            flat = s.conn.shape[1] == m.conn.shape[1] == 3 and not smooth
            rule = _RULE2 if flat else _RULE5
            for lo in range(0, len(i_all), _CHUNK):
                i, j = i_all[lo : lo + _CHUNK], j_all[lo : lo + _CHUNK]
                cs, cm = s.conn[i], m.conn[j]
                corners = (s_corner[a][i], m_corner[b][j]) if smooth else None
                d, mm, bl = _integrate(xs_all[cs], xm_all[cm], s, i, rule, corners)
                for c in range(3):
                    lift[:, c] += np.bincount(cs.ravel(), bl[..., c].ravel(), minlength=ns_pts)
                ks, km = cs.shape[1], cm.shape[1]
                # the normal of a row: the master facets' outward normals weighted by the
                # row's overlap integrals int N_i dA over them
                w = d.sum(axis=2).ravel()
                for c in range(3):
                    ncov[:, c] += np.bincount(
                        cs.ravel(), w * np.repeat(m.normal[j][:, c], ks), minlength=ns_pts
                    )
                dr.append(np.repeat(cs, ks, axis=1).ravel())
                dc.append(np.tile(cs, (1, ks)).ravel())
                dv.append(d.ravel())
                mr.append(np.repeat(cs, km, axis=1).ravel())
                mc.append(np.tile(cm, (1, ks)).ravel())
                mv.append(mm.ravel())

    def _csr(r: list, c: list, v: list, ncol: int) -> sp.csr_matrix:
        if not r:
            return sp.csr_matrix((ns_pts, ncol))
        a = sp.csr_matrix(
            (np.concatenate(v), (np.concatenate(r), np.concatenate(c))), shape=(ns_pts, ncol)
        )
        a.sum_duplicates()
        return a

    d_all, m_all = _csr(dr, dc, dv, ns_pts), _csr(mr, mc, mv, nm_pts)
    area_all = np.asarray(d_all.sum(axis=1)).ravel()
    nodes = np.flatnonzero((area_all > min_fraction * trib) & (trib > 0))
    normals = ncov[nodes] / np.linalg.norm(ncov[nodes], axis=1)[:, None]
    d, m = d_all[nodes], m_all[nodes]
    gap0 = np.einsum("si,si->s", normals, d @ xs_all - m @ xm_all + lift[nodes])
    return MortarCoupling(nodes.astype(np.int64), normals, d, m, gap0, area_all[nodes])
