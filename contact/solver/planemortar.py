"""Weighted (mortar) gaps of a body's surface against a plane, measured on its smoothed surface.

What is integrated
------------------
With the slave's shape functions as multipliers, slave node ``i`` gets one row whose gap
is the ``N_i``-weighted mean of the gap field over the faces around it that face the
plane (normal ``n``, through ``p``)::

    g_i = (1 / A_i) int N_i (n . (x~ - p)) dA       A_i = int N_i dA
    E_i = (1 / A_i) sum_j D_ij n^T                   D_ij = int N_i N_j dA

so that ``g_i + E_i u`` is the row's linearised gap and its multiplier a force whose
pressure field is ``sum_i N_i lambda_i / A_i``. The displacement enters through the faces'
own interpolation (``D``); the rest geometry ``x~`` is the surface smoothed through its
nodal normals (Phong tessellation, Boubekeur and Alexa 2008, with ``alpha = 1/2``: each
point moves half-way to the mean of its projections on the corners' tangent planes). A
coarse mesh's facets lie inside the curved surface they stand for, by ``h^2 / 8R`` at a
facet's middle, as much as a small press: on the flat facets a weighted gap would see
that sagitta and close late; on the smoothed surface, with ``alpha = 1/2`` exact to
second order on a sphere, the press is the curved body's (``benchmarks/results/plates.md``
compares both with node rows against Hertz). Faces meeting at more than :data:`CREASE`
keep their own normals there: a block's edge stays sharp, its flat faces stay flat (the
contact patch test is passed exactly: a uniform pressure gives each node its consistent
load ``p A_i``).

Faces are integrated with :func:`fem.elements.face_quadrature` of degree 5 (7 points on a
triangle, 3 x 3 on a quad): exact for ``N_i N_j`` and ``N_i`` times the smoothed
surface's quadratic bulge.
"""

from __future__ import annotations

import hashlib
import threading
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from fem.elements import face_quadrature

from ..geometry.plane import Plane

__all__ = ["CREASE", "PlaneRows", "corner_normals", "plane_rows"]

#: Faces whose normals differ by more than this (degrees) meet at a crease: no smoothing.
CREASE = 40.0
#: Phong tessellation's blend: 1/2 is exact to second order on a sphere.
ALPHA = 0.5

def _face_cross(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Normals of faces ``(F, k, 3)`` twice their areas long (quads by their diagonals)."""
    if x.shape[1] == 3:
        return np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    return np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 1])


def corner_normals(
    points: NDArray[np.float64], faces: dict[str, NDArray[np.int64]], crease: float = CREASE
) -> dict[str, NDArray[np.float64]]:
    """Each face corner's smoothed unit normal, ``(F, k, 3)`` per face kind.

    The mean of the normals of the faces around the corner's node that lie within
    ``crease`` degrees of the corner's own face, weighted by those faces' areas.
    """
    kinds = [k for k, f in faces.items() if len(f)]
    normals, areas, corner_face, corner_node = [], [], [], []
    base = 0
    for k in kinds:
        f = faces[k]
        c = _face_cross(points[f])
        a = np.linalg.norm(c, axis=1)
        normals.append(c / np.maximum(a, 1e-300)[:, None])
        areas.append(a)
        corner_face.append(np.repeat(np.arange(len(f)) + base, f.shape[1]))
        corner_node.append(f.ravel())
        base += len(f)
    if not kinds:
        return {}
    nf, af = np.concatenate(normals), np.concatenate(areas)
    cf, cn = np.concatenate(corner_face), np.concatenate(corner_node)
    # the faces around each node, as CSR over the nodes
    order = np.argsort(cn, kind="stable")
    starts = np.searchsorted(cn[order], np.arange(len(points) + 1))
    count = np.diff(starts)[cn]  # faces around each corner's node
    corner = np.repeat(np.arange(cn.size), count)
    offset = np.arange(corner.size) - np.repeat(np.cumsum(count) - count, count)
    other = cf[order[starts[cn[corner]] + offset]]
    near = np.einsum("ij,ij->i", nf[cf[corner]], nf[other]) >= np.cos(np.radians(crease))
    acc = np.zeros((cn.size, 3))
    np.add.at(acc, corner[near], af[other[near], None] * nf[other[near]])
    acc /= np.maximum(np.linalg.norm(acc, axis=1), 1e-300)[:, None]
    out, start = {}, 0
    for k in kinds:
        f = faces[k]
        out[k] = acc[start : start + f.size].reshape(*f.shape, 3)
        start += f.size
    return out


def _smoothed(x: NDArray, corner_n: NDArray, n: NDArray) -> NDArray[np.float64]:
    """Phong-smoothed points at shape-function values ``n`` (q, k) on faces ``x`` (F, k, 3)."""
    flat = np.einsum("qk,fkd->fqd", n, x)  # (F, q, 3)
    rel = flat[:, :, None, :] - x[:, None, :, :]  # (F, q, k, 3)
    off = np.einsum("fqkd,fkd->fqk", rel, corner_n)[..., None] * corner_n[:, None]  # (F,q,k,3)
    return flat - ALPHA * np.einsum("qk,fqkd->fqd", n, off)


@dataclass(frozen=True)
class PlaneRows:
    """The weighted rows of a surface against a plane: one per node of a face facing it.

    Attributes
    ----------
    nodes : ndarray of int64, shape (s,)
        The rows' slave nodes, sorted.
    d : scipy.sparse.csr_matrix, shape (s, n_points)
        ``D_ij`` (m^2) over the faces facing the plane.
    area : ndarray, shape (s,)
        ``A_i = sum_j D_ij`` (m^2).
    gap0 : ndarray, shape (s,)
        Each row's weighted mean gap of the smoothed rest surface (m).
    """

    nodes: NDArray[np.int64]
    d: sp.csr_matrix
    area: NDArray[np.float64]
    gap0: NDArray[np.float64]

    def __len__(self) -> int:
        return int(self.nodes.size)


def plane_rows(
    points: NDArray[np.float64], faces: dict[str, NDArray[np.int64]], plane: Plane
) -> PlaneRows:
    """The weighted rows of the surface ``faces`` of ``points`` against ``plane``.

    Only faces whose outward normal faces the plane (``n_face . n < 0``) are integrated:
    a block's side faces do not weigh its bottom edge's rows. The integrals depend on the
    plane's normal only (its place enters each gap linearly), so that they are kept for
    the surface and the normal: a body the frames do not move (a ball pressed by a
    moving plate) is integrated once.
    """
    key = hashlib.blake2b(np.ascontiguousarray(points, np.float64).tobytes(), digest_size=20)
    for kind in sorted(faces):
        key.update(kind.encode() + np.ascontiguousarray(faces[kind], np.int64).tobytes())
    key.update(np.ascontiguousarray(plane.normal, np.float64).tobytes())
    digest = key.digest()
    kept = _KEPT.get(digest)
    if kept is None:
        kept = _integrals(points, faces, plane.normal)
        with _LOCK:  # a sweep's threads may share the module
            while len(_KEPT) >= _KEEP:
                _KEPT.pop(next(iter(_KEPT)))
            _KEPT[digest] = kept
    nodes, d, area, moment = kept
    gap0 = moment @ plane.normal / area - float((plane.point + plane.motion) @ plane.normal)
    return PlaneRows(nodes, d, area, gap0)


#: The integrals of the surfaces and normals last asked for, by their bytes' hash.
_KEPT: dict[bytes, tuple[NDArray, sp.csr_matrix, NDArray, NDArray]] = {}
_KEEP = 16
_LOCK = threading.Lock()


def _integrals(
    points: NDArray[np.float64], faces: dict[str, NDArray[np.int64]], normal: NDArray
) -> tuple[NDArray[np.int64], sp.csr_matrix, NDArray[np.float64], NDArray[np.float64]]:
    """The rows' nodes, ``D``, ``A`` and each row's ``int N_i x~ dA`` ``(s, 3)``."""
    n_pts = len(points)
    corner = corner_normals(points, faces)
    rows, cols, vals, g_nodes, g_vals = [], [], [], [], []
    for kind, f in faces.items():
        if not len(f):
            continue
        facing = _face_cross(points[f]) @ normal < 0.0
        if not facing.any():
            continue
        f, cn = f[facing], corner[kind][facing]
        x = points[f]
        n, dn, w = face_quadrature(f.shape[1], degree=5)
        xa, xb = np.einsum("qk,fkd->fqd", dn[..., 0], x), np.einsum("qk,fkd->fqd", dn[..., 1], x)
        jw = np.linalg.norm(np.cross(xa, xb), axis=-1) * w[None]  # (F, q)
        smooth = _smoothed(x, cn, n)  # (F, q, 3)
        k = f.shape[1]
        m = np.einsum("fq,qi,qj->fij", jw, n, n)  # (F, k, k)
        rows.append(np.repeat(f, k, axis=1).ravel())
        cols.append(np.tile(f, k).ravel())
        vals.append(m.ravel())
        g_nodes.append(f.ravel())
        g_vals.append(np.einsum("fq,qi,fqd->fid", jw, n, smooth).reshape(-1, 3))
    if not rows:
        empty = np.zeros(0)
        return np.zeros(0, np.int64), sp.csr_matrix((0, n_pts)), empty, np.zeros((0, 3))
    r, c = np.concatenate(rows), np.concatenate(cols)
    nodes = np.unique(r)
    local = np.searchsorted(nodes, r)
    d = sp.csr_matrix((np.concatenate(vals), (local, c)), shape=(nodes.size, n_pts))
    d.sum_duplicates()
    area = np.asarray(d.sum(axis=1)).ravel()
    at = np.searchsorted(nodes, np.concatenate(g_nodes))
    moment = np.zeros((nodes.size, 3))
    np.add.at(moment, at, np.concatenate(g_vals))
    return nodes, d, area, moment
