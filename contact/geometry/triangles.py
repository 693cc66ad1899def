"""Triangles without a surface: closest points, degenerate triangles, a mesh's boundary.

Stateless and vectorised over rows: the pieces that
:class:`~contact.geometry.surfacequery.TriangleSurface` builds on, and that callers use
without a surface.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

import fem

from ..errors import SurfaceError
from . import closestkernels as kernels

__all__ = [
    "DEGENERATE_TOL",
    "Closest",
    "closest_on_triangles",
    "degenerate_triangles",
    "flat_triangles",
    "surface_of_mesh",
    "unit",
]

#: A triangle whose doubled area is below this times its longest edge squared is degenerate.
DEGENERATE_TOL = 1e-12


@dataclass(frozen=True)
class Closest:
    """Closest points on a surface of ``k`` query points.

    Attributes
    ----------
    distance : ndarray, shape (k,)
        Unsigned distance from each query point to the surface.
    point : ndarray, shape (k, 3)
        The closest point, ``sum_i bary[:, i] * points[triangles[face, i]]``.
    face : ndarray of int64, shape (k,)
        The triangle it lies on (one of them where it lies on a shared edge or vertex).
    bary : ndarray, shape (k, 3)
        Barycentric weights of the triangle's three nodes: non-negative, summing to one;
        exactly zero for the nodes opposite an edge or vertex the point lies on.
    normal : ndarray, shape (k, 3)
        Unit outward normal: the facet's inside a facet, the angle-weighted pseudo-normal
        on an edge or at a vertex; ``(x - point) . normal < 0`` for ``x`` inside.
    feature : ndarray of int8, shape (k,)
        Where the point lies: 3 inside a facet, 2 on an edge, 1 at a vertex.
    """

    distance: NDArray[np.float64]
    point: NDArray[np.float64]
    face: NDArray[np.int64]
    bary: NDArray[np.float64]
    normal: NDArray[np.float64]
    feature: NDArray[np.int8]

    def __len__(self) -> int:
        return len(self.distance)

    def side(self, x: ArrayLike) -> NDArray[np.float64]:
        """``(x - point) . normal`` of the query points ``x``: negative inside.

        Its sign is the pseudo-normal inside test (exact on a closed, manifold surface that
        does not overlap itself); its size is the distance only where the closest point
        lies inside a facet.
        """
        return np.einsum("ij,ij->i", np.asarray(x, np.float64) - self.point, self.normal)


def closest_on_triangles(
    x: NDArray[np.float64], a: NDArray[np.float64], b: NDArray[np.float64], c: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Barycentric weights of the closest point to ``x`` on triangle ``abc``, row by row.

    Ericson's region test (Real-Time Collision Detection, 5.1.5), vectorised: the weights
    of a point on an edge or at a vertex are exactly zero for the other nodes.

    Parameters
    ----------
    x, a, b, c : ndarray, shape (k, 3)
        Query points and the corners of the triangle each is projected on.

    Returns
    -------
    ndarray, shape (k, 3)
        Weights of ``a``, ``b``, ``c``: non-negative and summing to one.
    """
    ab, ac, ap = b - a, c - a, x - a
    bp, cp = x - b, x - c

    def dot(u: NDArray, v: NDArray) -> NDArray:
        return np.einsum("ij,ij->i", u, v)

    d1, d2 = dot(ab, ap), dot(ac, ap)
    d3, d4 = dot(ab, bp), dot(ac, bp)
    d5, d6 = dot(ab, cp), dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2

    def ratio(num: NDArray, den: NDArray) -> NDArray:
        ok = den != 0
        return np.where(ok, num / np.where(ok, den, 1.0), 0.0)

    w = np.empty((len(x), 3))
    s = va + vb + vc  # face interior unless a region below claims the point
    v, t = ratio(vb, s), ratio(vc, s)
    w[:, 0], w[:, 1], w[:, 2] = 1.0 - v - t, v, t

    def edge(mask: NDArray, i: int, j: int, num: NDArray, den: NDArray) -> None:
        if mask.any():
            f = ratio(num[mask], den[mask])
            w[mask] = 0.0
            w[mask, i], w[mask, j] = 1.0 - f, f

    def vertex(mask: NDArray, i: int) -> None:
        if mask.any():
            w[mask] = 0.0
            w[mask, i] = 1.0

    # Ericson tests A, B, AB, C, AC, BC in turn and the first match wins: assign in reverse
    edge((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), 1, 2, d4 - d3, (d4 - d3) + (d5 - d6))
    edge((vb <= 0) & (d2 >= 0) & (d6 <= 0), 0, 2, d2, d2 - d6)
    vertex((d6 >= 0) & (d5 <= d6), 2)
    edge((vc <= 0) & (d1 >= 0) & (d3 <= 0), 0, 1, d1, d1 - d3)
    vertex((d3 >= 0) & (d4 <= d3), 1)
    vertex((d1 <= 0) & (d2 <= 0), 0)
    return w


def degenerate_triangles(
    points: NDArray[np.float64], triangles: NDArray[np.int64], tol: float = DEGENERATE_TOL
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """Doubled-area vectors of triangles, their lengths, and which are degenerate.

    A triangle is degenerate where its doubled area is at most ``tol`` times its longest
    edge squared. The edges are measured only for the few triangles that could be: those
    whose doubled area is below ``tol`` times the square of the diagonal of the points'
    bounding box (no edge is longer).

    Returns
    -------
    cross : ndarray, shape (m, 3)
        ``(b - a) x (c - a)``.
    dbl : ndarray, shape (m,)
        Its length, twice the area.
    bad : ndarray of bool, shape (m,)
    """
    x = np.ascontiguousarray(points, dtype=np.float64)
    tri = np.ascontiguousarray(triangles, dtype=np.int64)
    if tri.ndim != 2 or tri.shape[1] != 3 or x.ndim != 2 or x.shape[1] != 3:
        raise SurfaceError(
            f"points (n, 3) and triangles (m, 3) expected, got {x.shape} and {tri.shape}"
        )
    if tri.size and (tri.min() < 0 or tri.max() >= len(x)):
        raise SurfaceError(f"triangles refer to nodes outside 0..{len(x) - 1}")
    cross, dbl = kernels.facet_cross(x, tri)
    return cross, dbl, flat_triangles(x, tri, dbl, tol)


def flat_triangles(
    points: NDArray[np.float64], triangles: NDArray[np.int64], dbl: NDArray[np.float64], tol: float
) -> NDArray[np.bool_]:
    """Which triangles (doubled areas ``dbl``) are degenerate (see :func:`degenerate_triangles`)."""
    if not len(triangles):
        return np.zeros(0, dtype=bool)
    # the box of every point holds every triangle's box: a bound on their edges
    lo, hi = fem.bounding_box(points)
    diag2 = float(np.sum((hi - lo) ** 2))
    bad = dbl <= tol * diag2
    suspect = np.flatnonzero(bad)
    if suspect.size:
        y = points[triangles[suspect]]
        edge2 = np.max([((y[:, i] - y[:, (i + 1) % 3]) ** 2).sum(axis=1) for i in range(3)], 0)
        bad[suspect] = dbl[suspect] <= tol * edge2
    return bad


def unit(v: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rows of ``v`` scaled to unit length (zero rows stay zero)."""
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


def surface_of_mesh(
    mesh: fem.Mesh, faces: fem.BoundaryFaces | Mapping[str, ArrayLike] | None = None
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Outward triangles of a volume mesh's boundary, numbered as the mesh's nodes.

    Parameters
    ----------
    mesh : fem.Mesh
    faces : fem.BoundaryFaces or mapping, optional
        The faces to use (``"triangle"`` ``(F3, 3)`` and/or ``"quad"`` ``(F4, 4)``,
        counter-clockwise seen from outside), e.g. a ball's outer surface; by default the
        whole boundary, ``mesh.boundary``.

    Returns
    -------
    nodes : ndarray of int64, shape (s,)
        Sorted volume nodes on these faces.
    triangles : ndarray of int64, shape (m, 3)
        Triangles in the volume mesh's node numbers (quads split along their 0-2
        diagonal into ``(0, 1, 2)`` and ``(0, 2, 3)``): ``TriangleSurface(mesh.points + u,
        triangles)`` is the deformed surface, and the weights of a closest point act on
        ``triangles[face]``. For a compact surface use ``mesh.points[nodes]`` with
        ``np.searchsorted(nodes, triangles)``.

    Raises
    ------
    SurfaceError
        A face kind other than triangle or quad, or node numbers outside the mesh.
    """
    if faces is None:
        faces = mesh.boundary
    groups = faces.faces if isinstance(faces, fem.BoundaryFaces) else faces
    parts = [np.zeros((0, 3), dtype=np.int64)]
    for kind, f in groups.items():
        f = np.asarray(f, dtype=np.int64)
        if f.size == 0:
            continue
        if f.ndim != 2 or f.shape[1] not in (3, 4):
            raise SurfaceError(f"mesh surface: {kind} faces must have 3 or 4 nodes, got {f.shape}")
        if f.shape[1] == 3:
            parts.append(f)
        else:
            parts.append(np.stack([f[:, [0, 1, 2]], f[:, [0, 2, 3]]], axis=1).reshape(-1, 3))
    tri = np.concatenate(parts)
    if tri.size and (tri.min() < 0 or tri.max() >= mesh.n_points):
        raise SurfaceError(f"mesh surface: faces refer to nodes outside 0..{mesh.n_points - 1}")
    return np.unique(tri), tri
