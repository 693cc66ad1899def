"""Compiled closest-point search on a triangle surface: a bounding-volume hierarchy.

The contact iteration asks for the closest points of a few hundred slave nodes on a
master surface several times a frame, every time at new coordinates. A tree built again
for every set of coordinates (libigl's AABB tree) costs more than the search itself. Here
the hierarchy's shape is built once per connectivity (:func:`build_tree`: median splits of
the facets' centroids along the widest axis, up to :data:`LEAF` facets a leaf) and only
its boxes are computed again at new coordinates (:func:`refit`, one pass from the leaves
up); a deformed surface keeps a valid hierarchy, its boxes only overlap more.
:func:`closest_faces` searches it nearest box first and returns each point's closest facet
with the barycentric weights of its closest point (Ericson's region test, as
:func:`contact.geometry.triangles.closest_on_triangles`: exactly zero weights for the nodes
off an edge or a vertex the point lies on).

:func:`facet_cross` gives the facets' doubled-area vectors at new coordinates (normals and
areas of a moved surface) in one pass: numpy's gathers of the corners cost ten times more.

The first call compiles (a few seconds); the machine code is cached next to this module
(numba's ``cache=True``).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = ["LEAF", "TIE", "build_tree", "closest_faces", "facet_cross", "refit"]

#: Most facets in a leaf of the hierarchy.
LEAF = 4
#: Distances within this many rounding units of the coordinates are a tie: of the facets
#: around an edge or a vertex, the one whose weights are exactly zero off that edge or
#: vertex wins (then the lowest index), so that the closest point's feature, and with it
#: its pseudo-normal, does not depend on the order of the search.
TIE = 16.0


@njit(cache=True)
def build_tree(
    points: NDArray[np.float64], triangles: NDArray[np.int64], leaf: int
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """Shape of a bounding-volume hierarchy over the triangles at ``points``.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
    triangles : ndarray of int64, shape (m, 3), m >= 1
    leaf : int
        Most triangles in a leaf (>= 1).

    Returns
    -------
    order : ndarray of int64, shape (m,)
        The triangles, leaf by leaf.
    child : ndarray of int64, shape (k,)
        First child of each node (its second is ``child + 1``), -1 for a leaf; a child's
        index is larger than its parent's.
    start, count : ndarray of int64, shape (k,)
        A node's triangles are ``order[start:start + count]``.
    """
    m = triangles.shape[0]
    cen = np.empty((m, 3))
    for t in range(m):
        for d in range(3):
            cen[t, d] = (
                points[triangles[t, 0], d] + points[triangles[t, 1], d] + points[triangles[t, 2], d]
            ) / 3.0
    order = np.arange(m)
    size = 2 * m
    child = np.full(size, -1, dtype=np.int64)
    start = np.zeros(size, dtype=np.int64)
    count = np.zeros(size, dtype=np.int64)
    count[0] = m
    n_nodes = 1
    todo = np.empty(size, dtype=np.int64)
    todo[0] = 0
    top = 1
    while top > 0:
        top -= 1
        node = todo[top]
        a = start[node]
        b = a + count[node]
        if b - a <= leaf:
            continue
        lo = np.full(3, np.inf)
        hi = np.full(3, -np.inf)
        for j in range(a, b):
            for d in range(3):
                c = cen[order[j], d]
                lo[d] = min(lo[d], c)
                hi[d] = max(hi[d], c)
        axis = int(np.argmax(hi - lo))
        if hi[axis] <= lo[axis]:  # every centroid at one place: a leaf, however full
            continue
        seg = order[a:b].copy()
        order[a:b] = seg[np.argsort(cen[seg, axis], kind="mergesort")]
        mid = (a + b) // 2
        first = n_nodes
        n_nodes += 2
        child[node] = first
        start[first] = a
        count[first] = mid - a
        start[first + 1] = mid
        count[first + 1] = b - mid
        todo[top] = first
        todo[top + 1] = first + 1
        top += 2
    return order, child[:n_nodes].copy(), start[:n_nodes].copy(), count[:n_nodes].copy()


@njit(cache=True)
def refit(
    points: NDArray[np.float64],
    triangles: NDArray[np.int64],
    order: NDArray[np.int64],
    child: NDArray[np.int64],
    start: NDArray[np.int64],
    count: NDArray[np.int64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Boxes ``lo, hi`` ``(k, 3)`` of the hierarchy's nodes at ``points`` (leaves up)."""
    k = child.shape[0]
    lo = np.empty((k, 3))
    hi = np.empty((k, 3))
    for node in range(k - 1, -1, -1):
        c = child[node]
        if c >= 0:
            for d in range(3):
                lo[node, d] = min(lo[c, d], lo[c + 1, d])
                hi[node, d] = max(hi[c, d], hi[c + 1, d])
            continue
        for d in range(3):
            lo[node, d] = np.inf
            hi[node, d] = -np.inf
        for j in range(start[node], start[node] + count[node]):
            t = order[j]
            for i in range(3):
                for d in range(3):
                    x = points[triangles[t, i], d]
                    lo[node, d] = min(lo[node, d], x)
                    hi[node, d] = max(hi[node, d], x)
    return lo, hi


@njit(cache=True, inline="always")
def _box_d2(
    q: NDArray[np.float64], lo: NDArray[np.float64], hi: NDArray[np.float64], node: int
) -> float:
    s = 0.0
    for d in range(3):
        if q[d] < lo[node, d]:
            e = lo[node, d] - q[d]
            s += e * e
        elif q[d] > hi[node, d]:
            e = q[d] - hi[node, d]
            s += e * e
    return s


@njit(cache=True, inline="always")
def _ratio(num: float, den: float) -> float:
    return num / den if den != 0.0 else 0.0


@njit(cache=True, inline="always")
def _weights(
    q: NDArray[np.float64],
    points: NDArray[np.float64],
    tri: NDArray[np.int64],
    w: NDArray[np.float64],
) -> float:
    """Weights ``w`` (3,) of the closest point of ``q`` on a triangle; its squared distance.

    Ericson's region test in his order (vertex A, B, edge AB, vertex C, edges AC, BC, the
    interior); the first region that holds the point wins.
    """
    ia, ib, ic = tri[0], tri[1], tri[2]
    d1 = d2 = d3 = d4 = d5 = d6 = 0.0
    for d in range(3):
        ab = points[ib, d] - points[ia, d]
        ac = points[ic, d] - points[ia, d]
        ap = q[d] - points[ia, d]
        bp = q[d] - points[ib, d]
        cp = q[d] - points[ic, d]
        d1 += ab * ap
        d2 += ac * ap
        d3 += ab * bp
        d4 += ac * bp
        d5 += ab * cp
        d6 += ac * cp
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    if d1 <= 0.0 and d2 <= 0.0:
        w[0], w[1], w[2] = 1.0, 0.0, 0.0
    elif d3 >= 0.0 and d4 <= d3:
        w[0], w[1], w[2] = 0.0, 1.0, 0.0
    elif vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        f = _ratio(d1, d1 - d3)
        w[0], w[1], w[2] = 1.0 - f, f, 0.0
    elif d6 >= 0.0 and d5 <= d6:
        w[0], w[1], w[2] = 0.0, 0.0, 1.0
    elif vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        f = _ratio(d2, d2 - d6)
        w[0], w[1], w[2] = 1.0 - f, 0.0, f
    elif va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0:
        f = _ratio(d4 - d3, (d4 - d3) + (d5 - d6))
        w[0], w[1], w[2] = 0.0, 1.0 - f, f
    else:
        s = va + vb + vc
        v = _ratio(vb, s)
        t = _ratio(vc, s)
        w[0], w[1], w[2] = 1.0 - v - t, v, t
    s2 = 0.0
    for d in range(3):
        e = q[d] - (w[0] * points[ia, d] + w[1] * points[ib, d] + w[2] * points[ic, d])
        s2 += e * e
    return s2


@njit(cache=True)
def closest_faces(
    points: NDArray[np.float64],
    triangles: NDArray[np.int64],
    order: NDArray[np.int64],
    child: NDArray[np.int64],
    start: NDArray[np.int64],
    count: NDArray[np.int64],
    lo: NDArray[np.float64],
    hi: NDArray[np.float64],
    q: NDArray[np.float64],
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """Closest triangle of each query point, nearest box first.

    Parameters
    ----------
    points, triangles
        The surface.
    order, child, start, count
        Its hierarchy (:func:`build_tree`).
    lo, hi
        The hierarchy's boxes at ``points`` (:func:`refit`).
    q : ndarray, shape (p, 3)
        Query points.

    Returns
    -------
    face : ndarray of int64, shape (p,)
        The closest triangle; of several at the same distance (to :data:`TIE` rounding
        units), the one with the most zero weights, then the lowest index.
    bary : ndarray, shape (p, 3)
        Weights of its nodes at the closest point.
    d2 : ndarray, shape (p,)
        Squared distance.
    """
    p = q.shape[0]
    face = np.empty(p, dtype=np.int64)
    bary = np.empty((p, 3))
    d2 = np.empty(p)
    # a node's children are pushed together: the stack never holds more than one
    # pending sibling per level
    depth = 2 * (int(np.log2(child.shape[0] + 1)) + 64)
    # rounding of a distance: that of the coordinates it is computed from
    size = 0.0
    for d in range(3):
        size = max(size, abs(lo[0, d]), abs(hi[0, d]))
    for k in range(p):
        for d in range(3):
            size = max(size, abs(q[k, d]))
    tie = TIE * np.finfo(np.float64).eps * size
    stack = np.empty(depth, dtype=np.int64)
    sdist = np.empty(depth)
    w = np.empty(3)
    for i in range(p):
        x = q[i]
        best = np.inf
        reach = np.inf  # a tie may still be found up to this squared distance
        better = np.inf  # below this squared distance, a facet beats the best outright
        bf = -1
        b0 = b1 = b2 = 0.0
        zeros = -1
        stack[0] = 0
        sdist[0] = _box_d2(x, lo, hi, 0)
        top = 1
        while top > 0:
            top -= 1
            node = stack[top]
            if sdist[top] > reach:
                continue
            c = child[node]
            if c < 0:
                for j in range(start[node], start[node] + count[node]):
                    t = order[j]
                    s2 = _weights(x, points, triangles[t], w)
                    if s2 > reach:
                        continue
                    z = (w[0] == 0.0) + (w[1] == 0.0) + (w[2] == 0.0)
                    if s2 < better or z > zeros or (z == zeros and t < bf):
                        best, bf, zeros = s2, t, z
                        b0, b1, b2 = w[0], w[1], w[2]
                        dist = np.sqrt(best)
                        reach = (dist + tie) ** 2
                        better = max(dist - tie, 0.0) ** 2
                continue
            dl = _box_d2(x, lo, hi, c)
            dr = _box_d2(x, lo, hi, c + 1)
            near, far, dn, df = (c, c + 1, dl, dr) if dl <= dr else (c + 1, c, dr, dl)
            if df <= reach:
                stack[top] = far
                sdist[top] = df
                top += 1
            if dn <= reach:
                stack[top] = near
                sdist[top] = dn
                top += 1
        face[i] = bf
        bary[i, 0], bary[i, 1], bary[i, 2] = b0, b1, b2
        d2[i] = best
    return face, bary, d2


@njit(cache=True)
def facet_cross(
    points: NDArray[np.float64], triangles: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(b - a) x (c - a)`` of every triangle ``(m, 3)`` and its length ``(m,)``."""
    m = triangles.shape[0]
    cross = np.empty((m, 3))
    dbl = np.empty(m)
    for t in range(m):
        ia, ib, ic = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        ab0 = points[ib, 0] - points[ia, 0]
        ab1 = points[ib, 1] - points[ia, 1]
        ab2 = points[ib, 2] - points[ia, 2]
        ac0 = points[ic, 0] - points[ia, 0]
        ac1 = points[ic, 1] - points[ia, 1]
        ac2 = points[ic, 2] - points[ia, 2]
        c0 = ab1 * ac2 - ab2 * ac1
        c1 = ab2 * ac0 - ab0 * ac2
        c2 = ab0 * ac1 - ab1 * ac0
        cross[t, 0], cross[t, 1], cross[t, 2] = c0, c1, c2
        dbl[t] = np.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
    return cross, dbl
