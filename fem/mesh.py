"""The validated volume mesh."""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .elements import ELEMENTS
from .errors import MeshError
from .mapping import det3, jacobians

__all__ = ["BoundaryFaces", "Mesh", "bounding_box", "tet_volumes6"]

#: A Jacobian determinant below this fraction of the element's size cubed is degenerate.
DEGENERATE_TOL = 1e-10
#: Connectivities whose boundary faces are kept (:attr:`Mesh.boundary`).
_BOUNDARY_CACHE = 8
_BOUNDARIES: OrderedDict[tuple, BoundaryFaces] = OrderedDict()


def tet_volumes6(points: NDArray[np.float64], tets: NDArray[np.int64]) -> NDArray[np.float64]:
    """Six times each tetrahedron's signed volume, positive for VTK's orientation."""
    x = points[tets]
    return np.einsum("ij,ij->i", np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), x[:, 3] - x[:, 0])


def bounding_box(points: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Lower and upper corners ``(3,)`` of the box around ``points`` ``(n, 3)``.

    ``points.min(axis=0)`` reduces across rows three values wide, which numpy does about
    fifteen times slower than along a contiguous row: the coordinates are transposed to
    rows first. Contact measures the boxes of
    its moved surfaces at every update.
    """
    x = np.asarray(points, dtype=np.float64)
    if x.ndim != 2 or x.shape[0] == 0:
        raise ValueError(f"points must have shape (n, 3) with n >= 1, got {x.shape}")
    t = np.ascontiguousarray(x.T)
    return t.min(axis=1), t.max(axis=1)


@dataclass(frozen=True)
class BoundaryFaces:
    """Boundary faces of a mesh, outward oriented, with the cells that own them.

    Attributes
    ----------
    faces : dict of str to ndarray
        ``"triangle"`` -> ``(F3, 3)`` and ``"quad"`` -> ``(F4, 4)`` node indices, each face
        counter-clockwise seen from outside the body.
    owners : dict of str to ndarray
        The same keys -> ``(F,)`` global index of the owning cell (cells numbered block
        after block in the order of :attr:`Mesh.cells`).
    """

    faces: dict[str, NDArray[np.int64]]
    owners: dict[str, NDArray[np.int64]]

    @property
    def nodes(self) -> NDArray[np.int64]:
        """Sorted indices of the nodes on the boundary."""
        parts = [f.ravel() for f in self.faces.values()]
        return np.unique(np.concatenate(parts)) if parts else np.zeros(0, dtype=np.int64)

    @property
    def n_faces(self) -> int:
        """Total number of boundary faces."""
        return sum(len(f) for f in self.faces.values())

    def subset(self, masks: Mapping[str, NDArray[np.bool_]]) -> BoundaryFaces:
        """The faces selected by a boolean mask per face kind (missing kinds dropped)."""
        faces = {k: self.faces[k][np.asarray(m, bool)] for k, m in masks.items()}
        owners = {k: self.owners[k][np.asarray(m, bool)] for k, m in masks.items()}
        return BoundaryFaces(faces, owners)


class Mesh:
    """A volume mesh of linear elements, validated on construction.

    Parameters
    ----------
    points : array_like, shape (N, 3)
        Node coordinates (metres).
    cells : mapping of str to array_like
        Connectivity per meshio cell type name: ``"tetra"`` ``(M, 4)``, ``"hexahedron"``
        ``(M, 8)``, ``"wedge"`` ``(M, 6)``.
    regions : mapping of str to array_like, optional
        An integer per cell (same keys as ``cells``) selecting its material; 0 when omitted.

    Raises
    ------
    MeshError
        On bad shapes, non-finite coordinates, indices out of range, unknown cell types,
        or an inverted or degenerate element (named by type, index and volume).

    Examples
    --------
    >>> import numpy as np
    >>> m = Mesh(np.eye(4, 3, k=-1), {"tetra": [[0, 1, 2, 3]]})
    >>> float(m.volumes["tetra"][0])
    0.16666666666666666
    """

    def __init__(
        self,
        points: ArrayLike,
        cells: Mapping[str, ArrayLike],
        regions: Mapping[str, ArrayLike] | None = None,
    ) -> None:
        pts = np.asarray(points, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise MeshError(f"points must have shape (N, 3), got {pts.shape}")
        bad = ~np.isfinite(pts).all(axis=1)
        if bad.any():
            idx = np.flatnonzero(bad)
            raise MeshError(
                f"{idx.size} point(s) have non-finite coordinates, first: point {idx[0]}"
            )
        if not isinstance(cells, Mapping) or len(cells) == 0:
            raise MeshError("cells must be a non-empty mapping of cell type to connectivity")
        self.points: NDArray[np.float64] = pts
        self.cells: dict[str, NDArray[np.int64]] = {}
        for kind, conn in cells.items():
            if kind not in ELEMENTS:
                raise MeshError(
                    f"unsupported cell type {kind!r}; supported: {', '.join(sorted(ELEMENTS))}"
                )
            arr = np.asarray(conn)
            k = ELEMENTS[kind].n_nodes
            if arr.size == 0:
                continue
            if arr.ndim != 2 or arr.shape[1] != k:
                raise MeshError(f"{kind} cells must have shape (M, {k}), got {arr.shape}")
            if not np.issubdtype(arr.dtype, np.integer):
                raise MeshError(f"{kind} connectivity must be integers, got dtype {arr.dtype}")
            arr = arr.astype(np.int64)
            out = (arr < 0) | (arr >= len(pts))
            if out.any():
                e = int(np.flatnonzero(out.any(axis=1))[0])
                raise MeshError(
                    f"{kind} element {e} refers to node(s) {arr[e][out[e]].tolist()} "
                    f"outside 0..{len(pts) - 1}"
                )
            for e_dup in _repeated_nodes(arr)[:1]:
                raise MeshError(f"{kind} element {e_dup} repeats a node: {arr[e_dup].tolist()}")
            self.cells[kind] = arr
        if not self.cells:
            raise MeshError("the mesh has no cells")
        self.regions: dict[str, NDArray[np.int64]] = {}
        regions = regions or {}
        for kind in regions:
            if kind not in self.cells:
                raise MeshError(f"regions given for cell type {kind!r} that the mesh does not have")
        for kind, conn in self.cells.items():
            if kind in regions:
                reg = np.asarray(regions[kind])
                if reg.shape != (len(conn),) or not np.issubdtype(reg.dtype, np.integer):
                    raise MeshError(
                        f"regions[{kind!r}] must be {len(conn)} integers, got shape {reg.shape} "
                        f"dtype {reg.dtype}"
                    )
                self.regions[kind] = reg.astype(np.int64)
            else:
                self.regions[kind] = np.zeros(len(conn), dtype=np.int64)
        self._check_jacobians()

    # --- validation ------------------------------------------------------------------

    def _check_jacobians(self) -> None:
        for kind, conn in self.cells.items():
            elem = ELEMENTS[kind]
            for start in range(0, len(conn), 200_000):
                block = conn[start : start + 200_000]
                x = self.points[block]
                detj = det3(jacobians(x, elem))
                size = np.ptp(x, axis=1).max(axis=1)
                bad = detj.min(axis=1) <= DEGENERATE_TOL * size**3
                if bad.any():
                    local = np.flatnonzero(bad)
                    e = int(local[0])
                    vol = float(detj[e] @ elem.weights)
                    what = "inverted" if detj[e].min() < 0 else "degenerate"
                    raise MeshError(
                        f"{kind} element {start + e} is {what}: volume {vol:.6g}, smallest "
                        f"Jacobian determinant {detj[e].min():.6g} at a Gauss point "
                        f"({local.size} bad element(s) in this block, nodes "
                        f"{block[e].tolist()})"
                    )

    # --- basic facts -----------------------------------------------------------------

    @property
    def n_points(self) -> int:
        """Number of nodes."""
        return len(self.points)

    @property
    def n_dofs(self) -> int:
        """Number of degrees of freedom, ``3 * n_points`` (node-major)."""
        return 3 * len(self.points)

    @property
    def n_cells(self) -> int:
        """Total number of cells over all types."""
        return sum(len(c) for c in self.cells.values())

    @cached_property
    def cell_offsets(self) -> dict[str, int]:
        """Global index of the first cell of each block (blocks in :attr:`cells` order)."""
        out, n = {}, 0
        for kind, conn in self.cells.items():
            out[kind] = n
            n += len(conn)
        return out

    @cached_property
    def volumes(self) -> dict[str, NDArray[np.float64]]:
        """Volume of every cell, per type."""
        out = {}
        for kind, conn in self.cells.items():
            elem = ELEMENTS[kind]
            out[kind] = det3(jacobians(self.points[conn], elem)) @ elem.weights
        return out

    @property
    def volume(self) -> float:
        """Total volume."""
        return float(sum(v.sum() for v in self.volumes.values()))

    @cached_property
    def used_points(self) -> NDArray[np.bool_]:
        """Mask of the nodes that belong to at least one cell."""
        used = np.zeros(self.n_points, dtype=bool)
        for conn in self.cells.values():
            used[conn.ravel()] = True
        return used

    @cached_property
    def region_ids(self) -> NDArray[np.int64]:
        """Sorted distinct region ids."""
        return np.unique(np.concatenate(list(self.regions.values())))

    def remove_unused_points(self) -> Mesh:
        """A copy without the nodes that belong to no cell (renumbered)."""
        used = self.used_points
        if used.all():
            return self
        new = np.full(self.n_points, -1, dtype=np.int64)
        new[used] = np.arange(int(used.sum()))
        return Mesh(self.points[used], {k: new[c] for k, c in self.cells.items()}, self.regions)

    @cached_property
    def boundary(self) -> BoundaryFaces:
        """Faces that belong to exactly one cell, outward oriented, with their owners.

        They depend on the connectivity alone: the last few connectivities' faces are
        kept (:data:`_BOUNDARIES`), so that a mesh moved to a new place (a posed hand,
        every frame) does not search them again.
        """
        key = (
            self.n_points,
            *(
                (kind, conn.shape, hashlib.blake2b(conn.tobytes(), digest_size=16).digest())
                for kind, conn in self.cells.items()
            ),
        )
        hit = _BOUNDARIES.get(key)
        if hit is not None:
            _BOUNDARIES.move_to_end(key)
            return hit
        out = self._find_boundary()
        _BOUNDARIES[key] = out
        while len(_BOUNDARIES) > _BOUNDARY_CACHE:
            _BOUNDARIES.popitem(last=False)
        return out

    def _find_boundary(self) -> BoundaryFaces:
        faces: dict[str, list[NDArray[np.int64]]] = {"triangle": [], "quad": []}
        owners: dict[str, list[NDArray[np.int64]]] = {"triangle": [], "quad": []}
        for kind, conn in self.cells.items():
            off = self.cell_offsets[kind]
            ids = np.arange(len(conn), dtype=np.int64) + off
            for local in ELEMENTS[kind].faces:
                key = "triangle" if len(local) == 3 else "quad"
                faces[key].append(conn[:, list(local)])
                owners[key].append(ids)
        out_f, out_o = {}, {}
        for key in ("triangle", "quad"):
            if not faces[key]:
                continue
            f = np.concatenate(faces[key])
            o = np.concatenate(owners[key])
            counts = _row_multiplicity(np.sort(f, axis=1))
            if (counts > 2).any():
                i = int(np.flatnonzero(counts > 2)[0])
                raise MeshError(
                    f"non-manifold mesh: {key} face {sorted(f[i].tolist())} is shared by "
                    f"{counts[i]} cells"
                )
            once = counts == 1
            out_f[key] = f[once]
            out_o[key] = o[once]
            out_f[key].setflags(write=False)  # shared by every mesh of this connectivity
            out_o[key].setflags(write=False)
        return BoundaryFaces(out_f, out_o)

    def face_centroids(self, faces: Mapping[str, NDArray[np.int64]]) -> dict[str, NDArray]:
        """Centroid of each face, per face kind."""
        return {k: self.points[f].mean(axis=1) for k, f in faces.items()}

    def __repr__(self) -> str:
        blocks = ", ".join(f"{k}: {len(c)}" for k, c in self.cells.items())
        return f"Mesh({self.n_points} points; {blocks})"


def _repeated_nodes(conn: NDArray[np.int64]) -> NDArray[np.int64]:
    s = np.sort(conn, axis=1)
    return np.flatnonzero((np.diff(s, axis=1) == 0).any(axis=1))


def _row_multiplicity(rows: NDArray[np.int64]) -> NDArray[np.int64]:
    """How many times each row occurs in ``rows``.

    Vectorised: the rows packed in one integer each where their entries fit, else sorted
    by lexsort.
    """
    if len(rows) == 0:
        return np.zeros(0, dtype=np.int64)
    k = rows.shape[1]
    top = int(rows.max()) + 1
    if rows.min() >= 0 and top**k < 2**63:
        code = np.zeros(len(rows), dtype=np.int64)
        for j in range(k):
            code = code * top + rows[:, j]
        _, inverse, counts = np.unique(code, return_inverse=True, return_counts=True)
        return counts[inverse]
    order = np.lexsort(rows.T[::-1])
    srt = rows[order]
    new = np.ones(len(rows), dtype=bool)
    new[1:] = (srt[1:] != srt[:-1]).any(axis=1)
    group = np.cumsum(new) - 1
    counts = np.bincount(group)
    out = np.empty(len(rows), dtype=np.int64)
    out[order] = counts[group]
    return out
