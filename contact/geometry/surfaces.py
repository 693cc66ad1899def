"""Checks and measures of closed triangle surfaces (skin and bones).

:func:`check_closed_surface` makes sure a surface can bound a volume mesh: closed, manifold
and consistently oriented (:func:`fem.check_surface`), outward (positive enclosed volume),
in one connected piece and, optionally, free of self-intersections.

Self-intersections are found by an exact, vectorised triangle-triangle test: candidate pairs
of triangles whose bounding spheres overlap (a KD-tree of centroids), pairs that share a
node left out, then every edge of each triangle is intersected with the other triangle
(Moller-Trumbore). Coplanar overlaps are not detected; they do not arise on a smoothed
iso-surface or a swept bone.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fem import MeshError, check_surface

if TYPE_CHECKING:
    import pyvista

__all__ = [
    "check_closed_surface",
    "count_pieces",
    "enclosed_volume",
    "poly_from_arrays",
    "self_intersections",
    "surface_arrays",
]

_CHUNK = 200_000


def surface_arrays(poly: pyvista.PolyData) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Points and triangles of an all-triangle ``PolyData``."""
    if poly.n_cells and not poly.is_all_triangles:
        poly = poly.triangulate()
    tri = np.asarray(poly.regular_faces, dtype=np.int64) if poly.n_cells else np.zeros((0, 3))
    return np.asarray(poly.points, dtype=np.float64), tri.astype(np.int64)


def poly_from_arrays(points: ArrayLike, triangles: ArrayLike) -> pyvista.PolyData:
    """A triangle ``PolyData`` from arrays."""
    import pyvista as pv

    return pv.PolyData.from_regular_faces(
        np.asarray(points, np.float64), np.asarray(triangles, np.int64)
    )


def enclosed_volume(points: ArrayLike, triangles: ArrayLike) -> float:
    """Signed volume enclosed by a closed surface: positive when its triangles face out."""
    x = np.asarray(points, np.float64)[np.asarray(triangles)]
    return float(np.einsum("ij,ij->i", x[:, 0], np.cross(x[:, 1], x[:, 2])).sum() / 6.0)


def count_pieces(n_points: int, triangles: ArrayLike) -> int:
    """Number of edge-connected pieces of a triangle surface (unused points ignored)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    tri = np.asarray(triangles, np.int64)
    if len(tri) == 0:
        return 0
    e = tri[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    g = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n_points, n_points))
    _, labels = connected_components(g, directed=False)
    return len(np.unique(labels[np.unique(tri)]))


def _segment_hits(p0: NDArray, p1: NDArray, tri: NDArray, eps: float) -> NDArray[np.bool_]:
    """Whether segments ``p0-p1`` (k, 3) cross triangles ``tri`` (k, 3, 3), vectorised."""
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    d = p1 - p0
    pv_ = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, pv_)
    ok = np.abs(det) > eps * np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1) * (
        np.linalg.norm(d, axis=1)
    )
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = p0 - tri[:, 0]
    u = np.einsum("ij,ij->i", s, pv_) * inv
    q = np.cross(s, e1)
    v = np.einsum("ij,ij->i", d, q) * inv
    t = np.einsum("ij,ij->i", e2, q) * inv
    return ok & (u >= -eps) & (v >= -eps) & (u + v <= 1 + eps) & (t >= -eps) & (t <= 1 + eps)


def self_intersections(points: ArrayLike, triangles: ArrayLike) -> NDArray[np.int64]:
    """Pairs of triangles that intersect and share no node.

    Parameters
    ----------
    points : array_like, shape (N, 3)
    triangles : array_like of int, shape (M, 3)

    Returns
    -------
    ndarray, shape (K, 2)
        Triangle index pairs ``i < j``; empty for a surface free of self-intersections.
    """
    from scipy.spatial import cKDTree

    pts = np.asarray(points, np.float64)
    tri = np.asarray(triangles, np.int64)
    x = pts[tri]
    c = x.mean(axis=1)
    rad = np.linalg.norm(x - c[:, None], axis=2).max(axis=1)
    pairs = cKDTree(c).query_pairs(2.0 * rad.max(), output_type="ndarray")
    found = []
    for s in range(0, len(pairs), _CHUNK):
        p = pairs[s : s + _CHUNK]
        a, b = p[:, 0], p[:, 1]
        near = np.linalg.norm(c[a] - c[b], axis=1) <= rad[a] + rad[b]
        shared = (tri[a][:, :, None] == tri[b][:, None, :]).any(axis=(1, 2))
        p = p[near & ~shared]
        a, b = p[:, 0], p[:, 1]
        hit = np.zeros(len(p), dtype=bool)
        for i, j in ((0, 1), (1, 2), (2, 0)):
            hit |= _segment_hits(x[a, i], x[a, j], x[b], 1e-12)
            hit |= _segment_hits(x[b, i], x[b, j], x[a], 1e-12)
        found.append(p[hit])
    return np.concatenate(found) if found else np.zeros((0, 2), dtype=np.int64)


def check_closed_surface(
    poly: pyvista.PolyData, name: str, *, check_intersections: bool = True
) -> None:
    """Check a surface bounds a volume: closed, manifold, oriented out, one piece.

    Parameters
    ----------
    poly : pyvista.PolyData
        Triangles.
    name : str
        What the surface is, to start the messages.
    check_intersections : bool
        Also test for self-intersections (:func:`self_intersections`).

    Raises
    ------
    fem.MeshError
        One line naming the surface and the problem: open or non-manifold edges (listed by
        :func:`fem.check_surface`), inward orientation, several pieces, or the first
        intersecting triangle pair.
    """
    pts, tri = surface_arrays(poly)
    check_surface(pts, tri, source=name)
    vol = enclosed_volume(pts, tri)
    if not vol > 0:
        raise MeshError(f"{name}: the triangles face inward (enclosed volume {vol:.3g})")
    if check_intersections:
        bad = self_intersections(pts, tri)
        if len(bad):
            i, j = bad[0]
            raise MeshError(
                f"{name}: {len(bad)} pair(s) of triangles intersect, first: triangles {i} and "
                f"{j} near {np.round(pts[tri[i]].mean(axis=0), 4).tolist()}"
            )
    pieces = count_pieces(len(pts), tri)
    if pieces != 1:
        raise MeshError(f"{name}: the surface is in {pieces} separate pieces, expected one")
