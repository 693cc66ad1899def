"""Closest points and inside tests against a closed triangle surface, vectorised over points.

The geometric queries of the contact iteration ("repel", issue 6): a slave node inside the
master's closed surface is moved to its closest point on it, remembering the facet and the
barycentric weights of that point.

:class:`TriangleSurface` wraps the queries, in double precision throughout. libigl
(`<https://libigl.github.io>`_, MPL-2.0; ``pip install libigl``, wheels of a few MB for
every platform) was chosen after measuring libigl, fcpw, Open3D, embreex and VTK
(``python -m benchmarks queries``; see ``benchmarks/results/queries.md``); the closest
facet is now searched by a compiled hierarchy of our own:

* closest point: a bounding-volume hierarchy compiled with numba
  (:mod:`contact.geometry.closestkernels`) finds the closest facet and the barycentric weights of
  its closest point (Ericson's region test), so that ``point == w @ facet_points`` to
  rounding and a point on an edge or a vertex has exactly zero weights for the other
  nodes. Its shape is built once per connectivity; a surface at new coordinates
  (:meth:`TriangleSurface.moved`, every iteration of a contact frame) refits its boxes
  only (libigl's AABB tree had to be built again for each: about 3 ms on the coarse skin,
  more than a search of a few hundred points);
* inside: the generalised winding number (``igl.FastWindingNumberBVH``, Barnes-Hut with
  exact near-field sums), ``> 1/2`` inside. It stays right in concave regions, for points
  a hair from the surface, and where a deformed surface overlaps itself;
* normal: the facet normal inside a facet, the angle-weighted pseudo-normal (Baerentzen and
  Aanaes 2005) at an edge or a vertex, so that ``(x - point) . normal < 0`` exactly when
  ``x`` is inside a closed, manifold surface that does not overlap itself. Of facets tied
  at an edge or a vertex, the search takes one whose weights are exactly zero off it.

The winding number's tree is built lazily on the first inside query and again for every
new set of coordinates (a few ms for the coarse skin's 2.7k facets, 30-80 ms for the fine
one's 18k). ``closest(x, faces=patch)`` searches a patch only, on a hierarchy of its own,
with the whole surface's normals. What depends on the triangles alone (closed or not, edge
neighbours, corners around the nodes, the hierarchy's shape) is kept for the last few
connectivities, so that a posed hand's skin, a new surface every frame, does not work it
out again.

:func:`surface_of_mesh` turns a volume mesh's boundary into outward triangles numbered as
the volume mesh's nodes, so that the weights of a closest point act on volume nodes.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

import fem

from ..errors import ContactError, SurfaceError
from . import closestkernels as kernels

__all__ = [
    "DEGENERATE_TOL",
    "WINDING_THRESHOLD",
    "Closest",
    "SurfaceError",
    "TriangleSurface",
    "closest_on_triangles",
    "degenerate_triangles",
    "surface_of_mesh",
]

#: A point is inside where the generalised winding number exceeds this.
WINDING_THRESHOLD = 0.5

#: A triangle whose doubled area is below this times its longest edge squared is degenerate.
DEGENERATE_TOL = 1e-12


#: Topology of recent surfaces by their connectivity: closed or not, edge neighbours, the
#: corners around each node. A posed hand's skin is a new surface every frame, on the same
#: triangles; what depends on the triangles alone is worked out once. The posing makes a
#: surface of every bone each frame too: the record keeps up to ``_TOPOLOGY_KEPT`` surfaces
#: and ``_TOPOLOGY_TRIANGLES`` triangles in all (about 100 bytes each), the least recently
#: used dropped first (at 8 surfaces, the hand's and ball's were dropped every frame).
_TOPOLOGY: OrderedDict[tuple[int, bytes], dict[str, Any]] = OrderedDict()
_TOPOLOGY_KEPT = 256
_TOPOLOGY_TRIANGLES = 500_000


def _topology(n_points: int, triangles: NDArray[np.int64]) -> dict[str, Any]:
    """The shared topology record of a connectivity (made empty if new)."""
    key = (n_points, triangles.tobytes())
    entry = _TOPOLOGY.pop(key, None)
    if entry is None:
        entry = {}
    _TOPOLOGY[key] = entry
    held = sum(len(k[1]) for k in _TOPOLOGY) // 24  # triangles (3 int64 each)
    while len(_TOPOLOGY) > 1 and (len(_TOPOLOGY) > _TOPOLOGY_KEPT or held > _TOPOLOGY_TRIANGLES):
        old, _ = _TOPOLOGY.popitem(last=False)
        held -= len(old[1]) // 24
    return entry


def _igl() -> Any:
    try:
        import igl
    except ImportError as exc:  # pragma: no cover - a declared dependency
        raise ContactError(
            "contact.geometry.surfacequery needs libigl (pip install libigl): " + str(exc)
        ) from None
    return igl


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
    return cross, dbl, _flat(x, tri, dbl, tol)


def _flat(
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


def _unit(v: NDArray[np.float64]) -> NDArray[np.float64]:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


class TriangleSurface:
    """A closed, outward-oriented triangle surface for closest-point and inside queries.

    Parameters
    ----------
    points : array_like, shape (n, 3)
        Node coordinates. Nodes that no triangle uses are allowed (e.g. all the nodes of
        a volume mesh, with :func:`surface_of_mesh`'s triangles) and ignored.
    triangles : array_like of int, shape (m, 3)
        Node indices, counter-clockwise seen from outside.
    name : str
        What the surface is, to start error messages.

    Raises
    ------
    SurfaceError
        Non-finite coordinates, bad shapes, indices out of range, or a degenerate triangle
        (repeated node, or doubled area below :data:`DEGENERATE_TOL` times its longest edge
        squared). Closedness is checked by :meth:`check_closed`, called by the inside
        queries.

    Notes
    -----
    Query methods take points ``(k, 3)`` and loop in compiled code (numba, libigl) and
    numpy only. The acceleration structures are built on the first query that needs them;
    a surface that moves is best passed on with :meth:`moved`, which keeps the checked
    connectivity and the closest-point hierarchy's shape.
    """

    def __init__(self, points: ArrayLike, triangles: ArrayLike, *, name: str = "surface") -> None:
        self.name = str(name)
        tri = np.asarray(triangles)
        if tri.ndim != 2 or tri.shape[1] != 3 or len(tri) == 0:
            raise SurfaceError(f"{self.name}: triangles must have shape (m, 3), got {tri.shape}")
        if not np.issubdtype(tri.dtype, np.integer):
            raise SurfaceError(f"{self.name}: triangles must be integers, got dtype {tri.dtype}")
        tri = np.ascontiguousarray(tri, dtype=np.int64)
        pts = self._check_points(points, None)
        bad = np.flatnonzero(((tri < 0) | (tri >= len(pts))).any(axis=1))
        if bad.size:
            raise SurfaceError(
                f"{self.name}: {bad.size} triangle(s) refer to nodes outside 0..{len(pts) - 1}, "
                f"first: triangle {bad[0]} {tri[bad[0]].tolist()}"
            )
        s = np.sort(tri, axis=1)
        rep = np.flatnonzero((s[:, 1:] == s[:, :-1]).any(axis=1))
        if rep.size:
            raise SurfaceError(
                f"{self.name}: {rep.size} triangle(s) repeat a node, first: triangle {rep[0]} "
                f"{tri[rep[0]].tolist()}"
            )
        tri.setflags(write=False)
        self.triangles: NDArray[np.int64] = tri
        self._set_points(pts)
        self._topology = _topology(len(pts), tri)
        # "ok" or the error message, once checked (only "ok" is shared: a message names
        # its surface)
        self._closed: str | None = self._topology.get("closed")

    # --- construction --------------------------------------------------------------

    def _check_points(self, points: ArrayLike, n: int | None) -> NDArray[np.float64]:
        pts = np.asarray(points, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise SurfaceError(f"{self.name}: points must have shape (n, 3), got {pts.shape}")
        if n is not None and len(pts) != n:
            raise SurfaceError(f"{self.name}: moved() needs {n} points, got {len(pts)}")
        if not np.isfinite(pts).all():
            i = np.flatnonzero(~np.isfinite(pts).all(axis=1))
            raise SurfaceError(
                f"{self.name}: {i.size} point(s) have non-finite coordinates, first: point {i[0]}"
            )
        pts = np.array(pts, dtype=np.float64, order="C")  # our own copy
        pts.setflags(write=False)
        return pts

    def _set_points(self, pts: NDArray[np.float64]) -> None:
        self.points: NDArray[np.float64] = pts
        # the connectivity is checked once (__init__): no index checks at every move
        cross, dbl = kernels.facet_cross(pts, self.triangles)
        bad = np.flatnonzero(_flat(pts, self.triangles, dbl, DEGENERATE_TOL))
        if bad.size:
            x = pts[self.triangles[bad]]
            raise SurfaceError(
                f"{self.name}: {bad.size} degenerate triangle(s) (zero area), first: triangle "
                f"{bad[0]} {self.triangles[bad[0]].tolist()} near "
                f"{np.round(x[0].mean(axis=0), 6).tolist()}"
            )
        self.face_normals: NDArray[np.float64] = cross / dbl[:, None]
        self.areas: NDArray[np.float64] = 0.5 * dbl

    def moved(self, points: ArrayLike) -> TriangleSurface:
        """The same connectivity with new coordinates (the topology is not checked again).

        Parameters
        ----------
        points : array_like, shape (n, 3)
            New coordinates of all ``n`` nodes.

        Returns
        -------
        TriangleSurface
            Its search structures are rebuilt on its first query.
        """
        new = object.__new__(TriangleSurface)
        new.name = self.name
        new.triangles = self.triangles
        new._set_points(self._check_points(points, len(self.points)))
        new._closed = self._closed
        new._topology = self._topology
        for topology in ("_twins", "_corners"):  # depend on the triangles only
            if topology in self.__dict__:
                new.__dict__[topology] = self.__dict__[topology]
        return new

    # --- facts -----------------------------------------------------------------------

    @property
    def n_points(self) -> int:
        """Number of nodes (used by a triangle or not)."""
        return len(self.points)

    @property
    def n_faces(self) -> int:
        """Number of triangles."""
        return len(self.triangles)

    @property
    def volume(self) -> float:
        """Signed enclosed volume (divergence theorem): positive when the triangles face out."""
        x = self.points[self.triangles]
        return float(np.einsum("ij,ij->i", x[:, 0], np.cross(x[:, 1], x[:, 2])).sum() / 6.0)

    @property
    def is_closed(self) -> bool:
        """Whether the surface is closed, manifold, consistently and outward oriented."""
        try:
            self.check_closed()
        except SurfaceError:
            return False
        return True

    def check_closed(self) -> None:
        """Check the surface bounds a volume: closed, manifold, oriented, facing out.

        Raises
        ------
        SurfaceError
            Naming the surface and the culprits (open, non-manifold or wrongly wound
            edges, or triangles that face inward).
        """
        if self._closed is None:
            try:
                fem.check_surface(self.points, self.triangles, source=self.name)
                self._closed = self._topology["closed"] = "ok"
            except fem.MeshError as exc:
                self._closed = f"{exc} (a closed surface is needed to tell inside from outside)"
        if self._closed != "ok":
            raise SurfaceError(self._closed)
        vol = self.volume
        if not vol > 0:
            raise SurfaceError(
                f"{self.name}: the triangles face inward (enclosed volume {vol:.6g}); "
                "reverse their node order"
            )

    def degenerate(self, tol: float = DEGENERATE_TOL) -> NDArray[np.bool_]:
        """Which triangles are degenerate at ``tol``, from the areas already known.

        As :func:`degenerate_triangles`, without computing the areas again.
        """
        return _flat(self.points, self.triangles, 2.0 * self.areas, tol)

    def face_nodes(self, face: ArrayLike) -> NDArray[np.int64]:
        """Node indices ``(k, 3)`` of the given faces: the nodes the weights act on."""
        return self.triangles[np.asarray(face, dtype=np.int64)]

    # --- search structures ---------------------------------------------------------

    @property
    def _tree(self) -> tuple[NDArray[np.int64], ...]:
        """The hierarchy's shape, per connectivity.

        See :func:`contact.geometry.closestkernels.build_tree`.

        Built at the coordinates of the first surface of its connectivity; later ones (a
        deformed or posed copy) refit its boxes only.
        """
        tree = self._topology.get("tree")
        if tree is None:
            tree = kernels.build_tree(self.points, self.triangles, kernels.LEAF)
            self._topology["tree"] = tree
        return tree

    @cached_property
    def _boxes(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The hierarchy's boxes at this surface's coordinates."""
        return kernels.refit(self.points, self.triangles, *self._tree)

    def _search(self, q: NDArray[np.float64]) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """Closest facet of each point ``(k, 3)`` and the weights of its closest point."""
        face, w, _ = kernels.closest_faces(
            self.points, self.triangles, *self._tree, *self._boxes, q
        )
        return face, w

    @cached_property
    def _winding(self) -> Any:
        tree = _igl().FastWindingNumberBVH()
        tree.init(self.points, self.triangles)
        return tree

    @cached_property
    def _twins(self) -> NDArray[np.int64]:
        """``twins[f, i]``: the triangle across the edge of ``f`` opposite its node ``i``."""
        if "twins" in self._topology:
            return self._topology["twins"]
        tri = self.triangles
        n = np.int64(self.n_points)
        a = tri[:, [1, 2, 0]].ravel()  # edge opposite node i runs from i+1 to i+2
        b = tri[:, [2, 0, 1]].ravel()
        key = a * n + b
        order = np.argsort(key, kind="stable")
        srt = key[order]
        rev = b * n + a
        pos = np.clip(np.searchsorted(srt, rev), 0, len(srt) - 1)
        found = srt[pos] == rev
        twin = np.where(found, order[pos] // 3, np.repeat(np.arange(len(tri)), 3))
        twin = twin.reshape(-1, 3)
        twin.setflags(write=False)
        self._topology["twins"] = twin
        return twin

    @cached_property
    def _corners(self) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """Corners ``3 f + i`` sorted by node, and where each node's run starts."""
        if "corners" in self._topology:
            return self._topology["corners"]
        flat = self.triangles.ravel()
        order = np.argsort(flat, kind="stable")
        start = np.searchsorted(flat[order], np.arange(self.n_points + 1))
        order.setflags(write=False)
        start.setflags(write=False)
        self._topology["corners"] = (order, start)
        return order, start

    def vertex_normals_at(self, nodes: ArrayLike) -> NDArray[np.float64]:
        """Angle-weighted pseudo-normals ``(k, 3)`` of some nodes only.

        As :attr:`vertex_normals`, from the corners around each node, not the whole surface.
        """
        nodes = np.asarray(nodes, dtype=np.int64)
        if "vertex_normals" in self.__dict__:
            return self.vertex_normals[nodes]
        order, start = self._corners
        counts = start[nodes + 1] - start[nodes]
        owner = np.repeat(np.arange(nodes.size), counts)
        first = np.repeat(start[nodes] - np.cumsum(counts) + counts, counts)
        corner = order[first + np.arange(counts.sum())]
        f, i = corner // 3, corner % 3
        x = self.points[self.triangles[f]]
        k = np.arange(f.size)
        u = _unit(x[k, (i + 1) % 3] - x[k, i])
        v = _unit(x[k, (i + 2) % 3] - x[k, i])
        angle = np.arctan2(np.linalg.norm(np.cross(u, v), axis=1), np.einsum("ij,ij->i", u, v))
        out = np.zeros((nodes.size, 3))
        np.add.at(out, owner, angle[:, None] * self.face_normals[f])
        return _unit(out)

    @cached_property
    def vertex_normals(self) -> NDArray[np.float64]:
        """Angle-weighted pseudo-normals of the nodes, ``(n, 3)`` (zero for unused nodes)."""
        return self.vertex_normals_at(np.arange(self.n_points))

    def _check_query(self, x: ArrayLike) -> NDArray[np.float64]:
        q = np.asarray(x, dtype=np.float64)
        if q.ndim == 1 and q.shape == (3,):
            q = q[None]
        if q.ndim != 2 or q.shape[1] != 3:
            raise SurfaceError(f"{self.name}: query points must have shape (k, 3), got {q.shape}")
        bad = ~np.isfinite(q).all(axis=1)
        if bad.any():
            i = np.flatnonzero(bad)
            raise SurfaceError(
                f"{self.name}: {i.size} query point(s) are not finite, first: point {i[0]} "
                f"{q[i[0]].tolist()}"
            )
        return np.ascontiguousarray(q)

    # --- queries ---------------------------------------------------------------------

    def closest(self, x: ArrayLike, faces: ArrayLike | None = None) -> Closest:
        """Closest points on the surface, with facet, weights and outward normal.

        Parameters
        ----------
        x : array_like, shape (k, 3)
            Query points.
        faces : array_like of int, optional
            Search these triangles only (a patch near the points: its own tree is built
            for this call). The result is the closest point on the patch; its normal is
            the whole surface's (pseudo-normals from every triangle around an edge or a
            vertex), so that :meth:`Closest.side` tells inside exactly wherever the
            patch holds the surface's closest point.

        Returns
        -------
        Closest
        """
        q = self._check_query(x)
        if len(q) == 0:
            e = np.zeros((0, 3))
            return Closest(np.zeros(0), e, np.zeros(0, np.int64), e, e, np.zeros(0, np.int8))
        if faces is None:
            face, w = self._search(q)
        else:
            sub = np.asarray(faces, dtype=np.int64)
            if sub.ndim != 1 or sub.size == 0 or sub.min() < 0 or sub.max() >= self.n_faces:
                raise SurfaceError(
                    f"{self.name}: faces must list triangles 0..{self.n_faces - 1}, at least one"
                )
            tri = np.ascontiguousarray(self.triangles[sub])
            tree = kernels.build_tree(self.points, tri, kernels.LEAF)
            face, w, _ = kernels.closest_faces(
                self.points, tri, *tree, *kernels.refit(self.points, tri, *tree), q
            )
            face = sub[face]
        corners = self.points[self.triangles[face]]
        point = np.einsum("ki,kij->kj", w, corners)
        distance = np.linalg.norm(q - point, axis=1)
        zero = w == 0.0
        feature = (3 - zero.sum(axis=1)).astype(np.int8)
        normal = self.face_normals[face].copy()
        on_edge = np.flatnonzero(feature == 2)
        if on_edge.size:
            opposite = np.argmax(zero[on_edge], axis=1)
            twin = self._twins[face[on_edge], opposite]
            normal[on_edge] = _unit(normal[on_edge] + self.face_normals[twin])
        at_vertex = np.flatnonzero(feature == 1)
        if at_vertex.size:
            node = self.triangles[face[at_vertex], np.argmax(w[at_vertex], axis=1)]
            normal[at_vertex] = self.vertex_normals_at(node)
        return Closest(distance, point, face, w, normal, feature)

    def winding_number(self, x: ArrayLike) -> NDArray[np.float64]:
        """Generalised winding number of the surface around each point ``(k,)``.

        About 1 inside a closed outward surface, 0 outside, 1/2 on it; 2 where a deformed
        surface overlaps itself twice. Barnes-Hut far field (libigl's fast winding number),
        exact sums near the point.
        """
        q = self._check_query(x)
        if len(q) == 0:
            return np.zeros(0)
        return np.asarray(self._winding.winding_number(q), dtype=np.float64)

    def inside(self, x: ArrayLike) -> NDArray[np.bool_]:
        """Whether each point ``(k, 3)`` lies inside: winding number above 1/2.

        Raises
        ------
        SurfaceError
            If the surface is not closed and outward (:meth:`check_closed`), or a query
            point is not finite.
        """
        self.check_closed()
        return self.winding_number(x) > WINDING_THRESHOLD

    def signed_distance(self, x: ArrayLike, *, sign: str = "winding") -> NDArray[np.float64]:
        """Distance to the surface ``(k,)``, negative inside.

        Parameters
        ----------
        x : array_like, shape (k, 3)
        sign : {"winding", "pseudonormal"}
            How inside is told: the winding number (robust, also where the surface
            overlaps itself), or the side of the closest point's pseudo-normal (no extra
            search, exact on a closed manifold surface free of overlaps).
        """
        if sign not in ("winding", "pseudonormal"):
            raise SurfaceError(
                f"{self.name}: sign must be 'winding' or 'pseudonormal', not {sign!r}"
            )
        c = self.closest(x)
        if sign == "winding":
            inside = self.inside(x)
        else:
            self.check_closed()
            inside = c.side(self._check_query(x)) < 0
        return np.where(inside, -c.distance, c.distance)

    def __repr__(self) -> str:
        return f"TriangleSurface({self.name!r}: {self.n_points} points, {self.n_faces} triangles)"


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
