"""Load vectors: body force, surface pressure, point forces, initial stress, a resultant.

Every ``*_load`` function returns a global load vector of shape ``(3 N,)`` in node-major
DOF order; add them up to form ``R``. :func:`resultant_load` spreads a given force and
moment over nodes (``(N, 3)``); :func:`nodal_volumes` gives the lumped weights it takes.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .elements import ELEMENTS, face_quadrature
from .errors import LoadError
from .mapping import gradients
from .material import LinearElastic, materials_by_region
from .mesh import BoundaryFaces, Mesh

__all__ = [
    "STANDARD_GRAVITY",
    "faces_of",
    "gravity_load",
    "initial_stress_load",
    "nodal_volumes",
    "point_load",
    "pressure_load",
    "resultant_load",
    "voigt_to_tensor",
]

STANDARD_GRAVITY = (0.0, 0.0, -9.80665)


def _vector(x: ArrayLike, name: str) -> NDArray[np.float64]:
    v = np.asarray(x, dtype=np.float64)
    if v.shape != (3,) or not np.isfinite(v).all():
        raise LoadError(f"{name} must be 3 finite numbers, got {np.asarray(x).tolist()}")
    return v


def gravity_load(
    mesh: Mesh,
    materials: LinearElastic | Mapping[int, LinearElastic],
    acceleration: ArrayLike = STANDARD_GRAVITY,
) -> NDArray[np.float64]:
    """Consistent nodal forces of a body force ``rho g``: ``f_a = int N_a rho g dV``.

    Parameters
    ----------
    mesh : Mesh
    materials : LinearElastic or mapping of int to LinearElastic
        Their ``density`` is used.
    acceleration : array_like, shape (3,)
        Gravitational acceleration (m/s^2), ``(0, 0, -9.80665)`` by default.
    """
    g = _vector(acceleration, "gravity acceleration")
    mats = materials_by_region(materials, mesh.region_ids)
    ids = np.array(sorted(mats))
    rho_t = np.array([mats[int(r)].density for r in ids])
    f = np.zeros((mesh.n_points, 3))
    for kind, conn in mesh.cells.items():
        elem = ELEMENTS[kind]
        rho = rho_t[np.searchsorted(ids, mesh.regions[kind])]
        _, detj = gradients(mesh.points[conn], elem)
        nq = elem.shape(elem.points)  # (q, n)
        mass = np.einsum("eq,q,qa->ea", detj, elem.weights, nq) * rho[:, None]
        for c in range(3):
            f[:, c] += np.bincount(conn.ravel(), (mass * g[c]).ravel(), minlength=mesh.n_points)
    return f.ravel()


def nodal_volumes(mesh: Mesh) -> NDArray[np.float64]:
    """Lumped nodal volumes ``V_a = int N_a dV`` (row sums of the consistent mass at rho = 1).

    Parameters
    ----------
    mesh : Mesh

    Returns
    -------
    ndarray, shape (N,)
        m^3 per node (0 on a node no cell uses); they add up to the mesh's volume.
    """
    v = np.zeros(mesh.n_points)
    for kind, conn in mesh.cells.items():
        elem = ELEMENTS[kind]
        _, detj = gradients(mesh.points[conn], elem)
        share = np.einsum("eq,q,qa->ea", detj, elem.weights, elem.shape(elem.points))
        v += np.bincount(conn.ravel(), share.ravel(), minlength=mesh.n_points)
    return v


def resultant_load(
    points: ArrayLike,
    weights: ArrayLike,
    force: ArrayLike,
    moment: ArrayLike,
    center: ArrayLike,
) -> NDArray[np.float64]:
    """Nodal forces with a given resultant force and moment, spread like a body force.

    With ``W = sum w_i``, the weighted centroid ``c_w = sum w_i x_i / W``, ``r_i = x_i -
    c_w`` and the weights' inertia tensor ``J = sum w_i (|r_i|^2 I - r_i r_i^T)``::

        f_i = w_i F / W + w_i omega x r_i,    J omega = M - (c_w - c) x F.

    The first term is a uniform body force: its resultant is ``F`` and, the moments taken
    about ``c_w``, it has none (``sum w_i r_i = 0``). The second is a rigid rotation's
    field: no resultant (``sum w_i r_i = 0`` again), moment ``J omega`` about any point.
    The moment about ``center`` of the whole is ``J omega + (c_w - c) x F = M``.

    Parameters
    ----------
    points : array_like, shape (n, 3)
        Node positions (m).
    weights : array_like, shape (n,)
        Non-negative nodal weights: lumped masses or volumes (:func:`nodal_volumes`).
    force : array_like, shape (3,)
        The resultant force ``F`` (N).
    moment : array_like, shape (3,)
        The resultant moment ``M`` (N m) about ``center``.
    center : array_like, shape (3,)
        The point ``c`` the moment is taken about (m).

    Returns
    -------
    ndarray, shape (n, 3)
        Nodal forces (N); invariant to the order of the nodes.

    Raises
    ------
    LoadError
        Bad shapes or non-finite values, a negative weight or a zero total weight, or a
        moment to carry (``M - (c_w - c) x F`` not zero) on weighted nodes that all lie on
        a line (``J`` singular: no moment along the line).
    """
    x = np.asarray(points, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 3 or w.shape != (len(x),):
        raise LoadError(
            f"resultant_load takes points (n, 3) and weights (n,), got {x.shape} and {w.shape}"
        )
    if not (np.isfinite(x).all() and np.isfinite(w).all()):
        raise LoadError("resultant_load: points and weights must be finite")
    if (w < 0).any():
        raise LoadError(f"resultant_load: weights must not be negative (min {w.min():g})")
    f, m, c = _vector(force, "force"), _vector(moment, "moment"), _vector(center, "center")
    total = float(w.sum())
    if not total > 0:
        raise LoadError("resultant_load: the weights add up to zero: nothing to carry the load")
    cw = w @ x / total
    r = x - cw
    out = np.outer(w, f / total)
    need = m - np.cross(cw - c, f)
    if not need.any():
        return out
    j = np.einsum("i,ij,ij->", w, r, r) * np.eye(3) - np.einsum("i,ij,ik->jk", w, r, r)
    eig = np.linalg.eigvalsh(j)
    if not eig[0] > 1e-12 * eig[-1]:
        raise LoadError(
            "resultant_load: the weighted nodes lie on a line (singular inertia): they carry "
            f"no moment along it, moment {need.tolist()} asked"
        )
    omega = np.linalg.solve(j, need)
    return out + w[:, None] * np.cross(omega, r)


def faces_of(faces: BoundaryFaces | Mapping[str, ArrayLike]) -> dict[str, NDArray[np.int64]]:
    """Faces by kind (``"triangle"``, ``"quad"``), checked for shape; empty kinds left out."""
    if isinstance(faces, BoundaryFaces):
        return {k: f for k, f in faces.faces.items() if len(f)}
    out = {}
    for kind, arr in faces.items():
        a = np.asarray(arr, dtype=np.int64)
        want = {"triangle": 3, "quad": 4}.get(kind)
        if want is None:
            raise LoadError(f"face kind {kind!r} is not supported (triangle or quad)")
        if a.size == 0:
            continue
        if a.ndim != 2 or a.shape[1] != want:
            raise LoadError(f"{kind} faces must have shape (F, {want}), got {a.shape}")
        out[kind] = a
    return out


def pressure_load(
    mesh: Mesh,
    faces: BoundaryFaces | Mapping[str, ArrayLike],
    pressure: float | Mapping[str, ArrayLike],
) -> NDArray[np.float64]:
    """Nodal forces of a pressure on faces: ``f_a = -int p N_a n dA``.

    The pressure pushes against each face's right-hand normal ``n`` (its nodes
    counter-clockwise seen from the side the pressure acts from): a positive pressure on
    outward-oriented boundary faces pushes into the body. Reference (undeformed) normals.

    Parameters
    ----------
    mesh : Mesh
    faces : BoundaryFaces or mapping
        ``"triangle"`` ``(F, 3)`` and/or ``"quad"`` ``(F, 4)`` node indices, e.g. a subset
        of :attr:`Mesh.boundary`.
    pressure : float or mapping
        Pascals; one value, or an array per face kind.
    """
    fcs = faces_of(faces)
    f = np.zeros((mesh.n_points, 3))
    for kind, conn in fcs.items():
        if conn.min() < 0 or conn.max() >= mesh.n_points:
            raise LoadError(f"{kind} faces refer to nodes outside 0..{mesh.n_points - 1}")
        p = pressure[kind] if isinstance(pressure, Mapping) else pressure
        p = np.broadcast_to(np.asarray(p, dtype=np.float64), (len(conn),))
        if not np.isfinite(p).all():
            raise LoadError("pressure must be finite")
        nq, dn, w = face_quadrature(conn.shape[1])
        x = mesh.points[conn]  # (F, k, 3)
        t1 = np.einsum("fki,qk->fqi", x, dn[:, :, 0])
        t2 = np.einsum("fki,qk->fqi", x, dn[:, :, 1])
        nda = np.cross(t1, t2)  # (F, q, 3): n dA per unit reference area
        fa = -np.einsum("f,fqi,q,qa->fai", p, nda, w, nq)
        for c in range(3):
            f[:, c] += np.bincount(conn.ravel(), fa[..., c].ravel(), minlength=mesh.n_points)
    return f.ravel()


def point_load(n_points: int, nodes: ArrayLike, forces: ArrayLike) -> NDArray[np.float64]:
    """Concentrated nodal forces (repeated nodes add up).

    Parameters
    ----------
    n_points : int
    nodes : array_like of int, shape (m,)
    forces : array_like, shape (m, 3) or (3,)
        Newtons; one vector for all nodes or one per node.
    """
    idx = np.asarray(nodes, dtype=np.int64).ravel()
    if idx.size and (idx.min() < 0 or idx.max() >= n_points):
        bad = idx[(idx < 0) | (idx >= n_points)][0]
        raise LoadError(f"point load on node {bad}, outside 0..{n_points - 1}")
    fv = np.asarray(forces, dtype=np.float64)
    try:
        fv = np.broadcast_to(fv, (idx.size, 3))
    except ValueError as exc:
        raise LoadError(
            f"point forces must have shape ({idx.size}, 3) or (3,), got {fv.shape}"
        ) from exc
    if not np.isfinite(fv).all():
        raise LoadError("point forces must be finite")
    f = np.zeros((n_points, 3))
    np.add.at(f, idx, fv)
    return f.ravel()


def voigt_to_tensor(s: ArrayLike) -> NDArray[np.float64]:
    """Voigt ``(..., 6)`` in order xx, yy, zz, yz, xz, xy to symmetric ``(..., 3, 3)``."""
    v = np.asarray(s, dtype=np.float64)
    t = np.empty((*v.shape[:-1], 3, 3))
    t[..., 0, 0], t[..., 1, 1], t[..., 2, 2] = v[..., 0], v[..., 1], v[..., 2]
    t[..., 1, 2] = t[..., 2, 1] = v[..., 3]
    t[..., 0, 2] = t[..., 2, 0] = v[..., 4]
    t[..., 0, 1] = t[..., 1, 0] = v[..., 5]
    return t


def initial_stress_load(
    mesh: Mesh, stress: Mapping[str, ArrayLike] | ArrayLike
) -> NDArray[np.float64]:
    """Nodal forces of an initial stress (the ``RI`` term): ``f = -int B^T sigma0 dV``.

    With these loads the total stress is ``sigma0 + D eps(u)``.

    Parameters
    ----------
    mesh : Mesh
    stress : mapping or array_like
        Per cell type, ``(M, 6)`` Voigt (xx, yy, zz, yz, xz, xy) or ``(M, 3, 3)`` stress
        in each cell (Pa); or one ``(6,)`` / ``(3, 3)`` stress for every cell.
    """
    f = np.zeros((mesh.n_points, 3))
    for kind, conn in mesh.cells.items():
        s = stress.get(kind) if isinstance(stress, Mapping) else stress
        if s is None:
            continue
        s = np.asarray(s, dtype=np.float64)
        if s.shape[-1:] == (6,) and s.ndim in (1, 2):
            s = voigt_to_tensor(s)
        if s.shape == (3, 3):
            s = np.broadcast_to(s, (len(conn), 3, 3))
        if s.shape != (len(conn), 3, 3):
            raise LoadError(
                f"initial stress for {kind} must be (M, 6), (M, 3, 3), (6,) or (3, 3) with "
                f"M = {len(conn)}, got {s.shape}"
            )
        if not np.isfinite(s).all():
            raise LoadError(f"initial stress for {kind} must be finite")
        grad, detj = gradients(mesh.points[conn], ELEMENTS[kind])
        fe = -np.einsum("eqaj,eij,eq,q->eai", grad, s, detj, ELEMENTS[kind].weights)
        for c in range(3):
            f[:, c] += np.bincount(conn.ravel(), fe[..., c].ravel(), minlength=mesh.n_points)
    return f.ravel()
