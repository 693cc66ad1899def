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
compares both with node rows against Hertz). Faces meeting at more than
:data:`contact.solver.smoothing.CREASE` keep their own normals there: a block's edge stays
sharp, its flat faces stay flat (the contact patch test is passed exactly: a uniform
pressure gives each node its consistent load ``p A_i``).

Faces are integrated with :func:`fem.elements.face_quadrature` of degree 5 (7 points on a
triangle, 3 x 3 on a quad): exact for ``N_i N_j`` and ``N_i`` times the smoothed
surface's quadratic bulge.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from fem.elements import face_quadrature

from ..geometry.plane import Plane
from .kept import Kept, digest
from .smoothing import corner_normals, face_cross, smoothed

__all__ = ["PlaneRows", "plane_rows"]


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
    key = digest(np.asarray(points, np.float64), faces, np.asarray(plane.normal, np.float64))
    kept = _KEPT.get(key, lambda: _integrals(points, faces, plane.normal))
    nodes, d, area, moment = kept
    gap0 = moment @ plane.normal / area - float((plane.point + plane.motion) @ plane.normal)
    return PlaneRows(nodes, d, area, gap0)


#: The integrals of the surfaces and normals last asked for.
_KEPT: Kept[tuple[NDArray, sp.csr_matrix, NDArray, NDArray]] = Kept(16)


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
        facing = face_cross(points[f]) @ normal < 0.0
        if not facing.any():
            continue
        f, cn = f[facing], corner[kind][facing]
        x = points[f]
        n, dn, w = face_quadrature(f.shape[1], degree=5)
        xa, xb = np.einsum("qk,fkd->fqd", dn[..., 0], x), np.einsum("qk,fkd->fqd", dn[..., 1], x)
        jw = np.linalg.norm(np.cross(xa, xb), axis=-1) * w[None]  # (F, q)
        smooth = smoothed(x, cn, n)  # (F, q, 3)
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
