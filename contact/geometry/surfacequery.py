"""Closest points and inside tests against a closed triangle surface, vectorised over points.

The geometric queries of the contact iteration's step 2 ("repel"): a slave node inside the
master's closed surface is moved to its closest point on it, remembering the facet and the
barycentric weights of that point. :class:`TriangleSurface` wraps the queries, in double
precision throughout (the libraries compared: ``benchmarks/results/queries.md``):

* closest point: a bounding-volume hierarchy compiled with numba
  (:mod:`contact.geometry.closestkernels`) finds the closest facet and the barycentric
  weights of its closest point (Ericson's region test), so that ``point == w @
  facet_points`` to rounding and a point on an edge or a vertex has exactly zero weights
  for the other nodes. Its shape is built once per connectivity; a surface at new
  coordinates (:meth:`TriangleSurface.moved`, every iteration of a contact frame) refits
  its boxes only;
* inside: the generalised winding number (libigl's ``FastWindingNumberBVH``, Barnes-Hut
  with exact near-field sums), ``> 1/2`` inside. It stays right in concave regions, for
  points a hair from the surface, and where a deformed surface overlaps itself;
* normal: the facet normal inside a facet, the angle-weighted pseudo-normal (Baerentzen and
  Aanaes 2005) at an edge or a vertex, so that ``(x - point) . normal < 0`` exactly when
  ``x`` is inside a closed, manifold surface that does not overlap itself. Of facets tied
  at an edge or a vertex, the search takes one whose weights are exactly zero off it.

The winding number's tree is built lazily on the first inside query and again for every
new set of coordinates. ``closest(x, faces=patch)`` searches a patch only, on a hierarchy
of its own, with the whole surface's normals. What depends on the triangles alone is kept
for the last few connectivities (:mod:`contact.geometry.topology`). The functions of
triangles alone, :func:`surface_of_mesh` among them, live in
:mod:`contact.geometry.triangles` and are re-exported here.
"""

from __future__ import annotations

from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

import fem

from ..errors import ContactError, SurfaceError
from . import closestkernels as kernels
from .topology import edge_twins, node_corners, pseudo_normals, topology_record
from .triangles import (
    DEGENERATE_TOL,
    Closest,
    closest_on_triangles,
    degenerate_triangles,
    flat_triangles,
    surface_of_mesh,
    unit,
)

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


def _igl() -> Any:
    try:
        import igl
    except ImportError as exc:  # pragma: no cover - a declared dependency
        raise ContactError(
            "contact.geometry.surfacequery needs libigl (pip install libigl): " + str(exc)
        ) from None
    return igl


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
        self._topology = topology_record(len(pts), tri)
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
        bad = np.flatnonzero(flat_triangles(pts, self.triangles, dbl, DEGENERATE_TOL))
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
        return flat_triangles(self.points, self.triangles, 2.0 * self.areas, tol)

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
        if "twins" not in self._topology:
            self._topology["twins"] = edge_twins(self.triangles, self.n_points)
        return self._topology["twins"]

    @cached_property
    def _corners(self) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """Corners ``3 f + i`` sorted by node, and where each node's run starts."""
        if "corners" not in self._topology:
            self._topology["corners"] = node_corners(self.triangles, self.n_points)
        return self._topology["corners"]

    def vertex_normals_at(self, nodes: ArrayLike) -> NDArray[np.float64]:
        """Angle-weighted pseudo-normals ``(k, 3)`` of some nodes only.

        As :attr:`vertex_normals`, from the corners around each node, not the whole surface.
        """
        nodes = np.asarray(nodes, dtype=np.int64)
        if "vertex_normals" in self.__dict__:
            return self.vertex_normals[nodes]
        return pseudo_normals(self.points, self.triangles, self.face_normals, self._corners, nodes)

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
            normal[on_edge] = unit(normal[on_edge] + self.face_normals[twin])
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
