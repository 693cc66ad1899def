"""Checks of a user's object surface before it is filled with tetrahedra or used as it is.

:func:`check_object_surface` takes the triangles of an object's mesh file and refuses, each
with a one-line :class:`~contact.errors.ObjectError` that starts with
``<where> = '<path>': ``, in this order:

1. an open or non-manifold surface (edges used by one triangle, or by more than two);
2. degenerate triangles (a repeated node, or an area below :data:`DEGENERATE_AREA` of the
   mean area);
3. neighbouring triangles wound opposite ways;
4. self-intersections (exact predicates of libigl, coplanar overlaps included);
5. a size no hand grasps (largest extent outside :data:`MIN_EXTENT`..:data:`MAX_EXTENT`,
   most often a mesh written in millimetres).

A closed piece wound inward throughout (negative enclosed volume) that is not a cavity
inside another piece is a mistake that can be fixed: it is flipped, with a warning. An
inward piece inside an outward one is a cavity, and stays so (fTetWild leaves it empty).
Coincident points are merged first (an STL file repeats each corner in every triangle) and
unused points dropped.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from numpy.typing import ArrayLike, NDArray

import fem

from ..errors import ObjectError
from ..geometry import self_intersections

__all__ = [
    "DEGENERATE_AREA",
    "HAND_LENGTH",
    "MAX_EXTENT",
    "MIN_EXTENT",
    "check_object_surface",
]

#: A hand's length (m), wrist crease to middle fingertip: the scale an object is held at.
HAND_LENGTH = 0.19
#: Largest object extent (m): over five hands long, no grasp; a mesh in millimetres mostly.
MAX_EXTENT = 1.0
#: Smallest object extent (m): below the skin's element size, nothing a hand can hold.
MIN_EXTENT = 1e-3
#: A triangle whose area is below this fraction of the mean triangle area is degenerate.
DEGENERATE_AREA = 1e-10


def _xyz(p: ArrayLike) -> str:
    return "(" + ", ".join(f"{float(v):.6g}" for v in np.asarray(p)) + ")"


def _edge(points: NDArray, a: int, b: int) -> str:
    return f"the edge from {_xyz(points[a])} to {_xyz(points[b])}"


def _clean(
    points: ArrayLike, triangles: ArrayLike, prefix: str
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Shapes checked, coincident points merged, unused points dropped."""
    pts = np.asarray(points, dtype=np.float64)
    tri = np.asarray(triangles)
    if pts.ndim != 2 or pts.shape[1] != 3 or not np.isfinite(pts).all():
        raise ObjectError(f"{prefix}points must be finite, shape (N, 3), got {pts.shape}")
    if tri.ndim != 2 or tri.shape[1] != 3 or len(tri) == 0:
        raise ObjectError(f"{prefix}no triangles (shape (M, 3) expected, got {tri.shape})")
    if not np.issubdtype(tri.dtype, np.integer) or tri.min() < 0 or tri.max() >= len(pts):
        raise ObjectError(f"{prefix}triangles must be node indices in 0..{len(pts) - 1}")
    uniq, inverse = np.unique(pts, axis=0, return_inverse=True)
    tri = inverse.reshape(-1)[tri.astype(np.int64)]
    used, tri = np.unique(tri, return_inverse=True)
    return uniq[used], tri.reshape(-1, 3).astype(np.int64)


def _check_edges(points: NDArray, tri: NDArray, prefix: str) -> None:
    """Check 1: every edge of the triangles without a repeated node in exactly two."""
    good = tri[(tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 2] != tri[:, 0])]
    n = np.int64(len(points))
    e = np.sort(good[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    keys, counts = np.unique(e[:, 0] * n + e[:, 1], return_counts=True)
    open_, multi = keys[counts == 1], keys[counts > 2]
    if open_.size:
        k = int(open_[0])
        more = f" (and {multi.size} non-manifold)" if multi.size else ""
        raise ObjectError(
            f"{prefix}the surface is open: {open_.size} edge(s) used by one triangle only"
            f"{more}, e.g. {_edge(points, k // n, k % n)}; a solid object needs a closed "
            "surface"
        )
    if multi.size:
        k = int(multi[0])
        uses = int(counts[counts > 2][0])
        raise ObjectError(
            f"{prefix}the surface is not manifold: {multi.size} edge(s) shared by more than "
            f"two triangles, e.g. {_edge(points, k // n, k % n)} in {uses} triangles"
        )


def _check_degenerate(points: NDArray, tri: NDArray, prefix: str) -> None:
    """Check 2: no repeated node, no area below :data:`DEGENERATE_AREA` of the mean."""
    x = points[tri]
    area = 0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), axis=1)
    repeated = (tri[:, 0] == tri[:, 1]) | (tri[:, 1] == tri[:, 2]) | (tri[:, 2] == tri[:, 0])
    bad = np.flatnonzero(repeated | (area < DEGENERATE_AREA * area.mean()))
    if bad.size:
        i = int(bad[0])
        raise ObjectError(
            f"{prefix}{bad.size} degenerate triangle(s) (a repeated node, or an area below "
            f"{DEGENERATE_AREA:g} of the mean), first: triangle {i} with corners "
            f"{', '.join(_xyz(p) for p in x[i])}"
        )


def _check_winding(points: NDArray, tri: NDArray, prefix: str) -> None:
    """Check 3: each edge traversed once each way (neighbours wound alike)."""
    n = np.int64(len(points))
    d = tri[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    keys, counts = np.unique(d[:, 0] * n + d[:, 1], return_counts=True)
    twice = keys[counts > 1]
    if twice.size:
        k = int(twice[0])
        raise ObjectError(
            f"{prefix}the surface is inconsistently oriented: {twice.size} edge(s) traversed "
            f"twice the same way (neighbouring triangles wound opposite ways), e.g. "
            f"{_edge(points, k // n, k % n)}"
        )


def _pieces(n_points: int, tri: NDArray) -> NDArray[np.int64]:
    """Piece label of each triangle (pieces connected through nodes)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    e = tri[:, [0, 1, 1, 2]].reshape(-1, 2)
    g = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n_points, n_points))
    labels = connected_components(g, directed=False)[1]
    return labels[tri[:, 0]]


def _winding_number(x: NDArray, o: NDArray) -> float:
    """Winding number of triangles ``x`` (m, 3, 3) about point ``o``.

    The sum of the triangles' solid angles (Van Oosterom and Strackee 1983) over 4 pi.
    """
    a, b, c = (x[:, k] - o for k in range(3))
    la, lb, lc = (np.linalg.norm(v, axis=1) for v in (a, b, c))
    num = np.einsum("ij,ij->i", a, np.cross(b, c))
    den = (
        la * lb * lc
        + np.einsum("ij,ij->i", a, b) * lc
        + np.einsum("ij,ij->i", b, c) * la
        + np.einsum("ij,ij->i", c, a) * lb
    )
    return float(np.arctan2(num, den).sum() / (2.0 * math.pi))


def _orient_outward(points: NDArray, tri: NDArray, prefix: str) -> NDArray[np.int64]:
    """Check 3, second half: pieces wound inward flipped (with a warning), cavities kept."""
    label = np.unique(_pieces(len(points), tri), return_inverse=True)[1]
    x = points[tri]
    part = np.einsum("ij,ij->i", x[:, 0], np.cross(x[:, 1], x[:, 2])) / 6.0
    vol = np.bincount(label, weights=part)  # enclosed volume of each piece
    outward = tri[vol[label] > 0]
    flip = []
    for k in np.flatnonzero(vol <= 0):
        corner = points[tri[label == k][0, 0]]
        if not (len(outward) and _winding_number(points[outward], corner) > 0.5):
            flip.append(k)  # not a cavity inside an outward piece
    if not flip:
        return tri
    mask = np.isin(label, flip)
    tri = tri.copy()
    tri[mask] = tri[mask][:, ::-1]
    what = "the surface is" if len(vol) == 1 else f"{len(flip)} of its {len(vol)} pieces are"
    warnings.warn(
        f"{prefix}{what} wound inward (negative enclosed volume {vol[flip].sum():.4g} m^3): "
        "flipped to face outward",
        stacklevel=3,
    )
    return tri


def _intersecting_pairs(points: NDArray, tri: NDArray) -> NDArray[np.int64]:
    """Pairs of intersecting triangles, neighbours that merely share a node or edge left out."""
    try:
        from igl.predicates import find_self_intersections
    except ImportError:  # an older libigl: the vectorised test of contact.geometry
        return self_intersections(points, tri)
    found, pairs, _ = find_self_intersections(
        np.ascontiguousarray(points, np.float64), np.ascontiguousarray(tri, np.int64)
    )
    return np.asarray(pairs, np.int64).reshape(-1, 2) if found else np.zeros((0, 2), np.int64)


def _check_intersections(points: NDArray, tri: NDArray, prefix: str) -> None:
    """Check 4: no two triangles cross or overlap."""
    pairs = _intersecting_pairs(points, tri)
    if len(pairs):
        i, j = (int(v) for v in pairs[0])
        c = points[tri[[i, j]]].mean(axis=1)
        raise ObjectError(
            f"{prefix}the surface intersects itself: {len(pairs)} pair(s) of triangles "
            f"intersect, e.g. triangle {i} near {_xyz(c[0])} and triangle {j} near "
            f"{_xyz(c[1])}"
        )


def _check_size(points: NDArray, prefix: str) -> None:
    """Check 5: the largest extent within :data:`MIN_EXTENT`..:data:`MAX_EXTENT`."""
    size = float(np.ptp(points, axis=0).max())
    across = f"{prefix}the object is {size:.4g} m across"
    if size > MAX_EXTENT:
        if size * 1e-3 > MAX_EXTENT:
            hint = f"far larger than a hand ({HAND_LENGTH:g} m long); at most {MAX_EXTENT:g} m"
        elif size > 10.0 * MAX_EXTENT:
            hint = "in millimetres? the scene is in metres; scale it by 0.001"
        else:
            hint = "in centimetres? the scene is in metres; scale it by 0.01"
        raise ObjectError(f"{across}: {hint}")
    if size < MIN_EXTENT:
        hint = f"too small to grasp (at least {MIN_EXTENT:g} m; a hand is {HAND_LENGTH:g} m long)"
        if MIN_EXTENT <= size * 1e3 <= MAX_EXTENT:
            hint += "; in kilometres? the scene is in metres; scale it by 1000"
        raise ObjectError(f"{across}: {hint}")


def check_object_surface(
    points: ArrayLike, triangles: ArrayLike, path: object, *, where: str = "object.mesh"
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Check a user's triangle surface for an object; return it cleaned and outward.

    Parameters
    ----------
    points : array_like, shape (N, 3)
        Node coordinates (metres).
    triangles : array_like of int, shape (M, 3)
        Node indices of each triangle.
    path : path-like or str
        The mesh file, named in every message.
    where : str
        The scene key that gave the file (``object[1].mesh``), starting every message.

    Returns
    -------
    points : ndarray, shape (n, 3)
        Coincident points merged, unused points dropped.
    triangles : ndarray of int, shape (M, 3)
        The same triangles in the same order on those points, every closed piece facing
        out (cavities inside another piece facing in).

    Raises
    ------
    ObjectError
        One line ``<where> = '<path>': <what is wrong>``, for the first failed check of the
        module docstring's list.

    Warns
    -----
    UserWarning
        When pieces wound inward were flipped.
    """
    prefix = f"{where} = '{path}': "
    pts, tri = _clean(points, triangles, prefix)
    try:
        fem.check_surface(pts, tri)  # closed, manifold, no repeated node, wound alike
        topology = None
    except fem.MeshError as exc:
        topology = str(exc)
    if topology is not None:
        _check_edges(pts, tri, prefix)
    _check_degenerate(pts, tri, prefix)
    if topology is not None:
        _check_winding(pts, tri, prefix)
        raise ObjectError(f"{prefix}{topology}")  # anything the checks above do not word
    tri = _orient_outward(pts, tri, prefix)
    _check_intersections(pts, tri, prefix)
    _check_size(pts, prefix)
    return pts, tri
