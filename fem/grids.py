"""Structured grids of bricks and conversions: boxes, tensor grids, merging, bricks to tets.

:func:`box_mesh` and :func:`grid_mesh` lay bricks (or wedges, or Kuhn tetrahedra) on a
tensor grid; :func:`hex_to_tet` turns any brick mesh into a conforming tetrahedral one;
:func:`merge_points` joins coincident nodes of blocks meshed apart. The node numbering of a
grid (:func:`grid_index`, :func:`grid_hexes`) is shared with the cubed-sphere generators of
:mod:`fem.generators`.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from .elements import ELEMENTS
from .errors import MeshError
from .mapping import det3, jacobians
from .mesh import Mesh, tet_volumes6

__all__ = [
    "box_mesh",
    "grid_hexes",
    "grid_index",
    "grid_mesh",
    "hex_to_tet",
    "merge_points",
]


def grid_index(nx: int, ny: int, nz: int) -> NDArray[np.int64]:
    """Node numbers ``idx[k, j, i]`` of an ``nx x ny x nz`` cell grid, x fastest."""
    return np.arange((nx + 1) * (ny + 1) * (nz + 1)).reshape(nz + 1, ny + 1, nx + 1)


def grid_hexes(idx: NDArray[np.int64]) -> NDArray[np.int64]:
    """Hexahedra of a structured node index array ``idx[k, j, i]`` (VTK order)."""
    a = idx
    return np.stack(
        [
            a[:-1, :-1, :-1],
            a[:-1, :-1, 1:],
            a[:-1, 1:, 1:],
            a[:-1, 1:, :-1],
            a[1:, :-1, :-1],
            a[1:, :-1, 1:],
            a[1:, 1:, 1:],
            a[1:, 1:, :-1],
        ],
        axis=-1,
    ).reshape(-1, 8)


_KUHN = np.array(
    [[0, 1, 2, 6], [0, 2, 3, 6], [0, 3, 7, 6], [0, 7, 4, 6], [0, 4, 5, 6], [0, 5, 1, 6]]
)


def box_mesh(
    lengths: ArrayLike = (1.0, 1.0, 1.0),
    divisions: ArrayLike = (4, 4, 4),
    origin: ArrayLike = (0.0, 0.0, 0.0),
    element: str = "hexahedron",
) -> Mesh:
    """A structured box ``[origin, origin + lengths]``.

    Parameters
    ----------
    lengths : array_like, shape (3,)
        Edge lengths (m), positive.
    divisions : array_like of int, shape (3,)
        Cells along x, y and z.
    origin : array_like, shape (3,)
    element : {"hexahedron", "wedge", "tetra"}
        Bricks; each brick split into two wedges (along the xy diagonal); or into six
        tetrahedra (Kuhn split, conforming).
    """
    ln = np.asarray(lengths, dtype=float)
    nd = np.asarray(divisions)
    if ln.shape != (3,) or (ln <= 0).any():
        raise MeshError(f"box lengths must be 3 positive numbers, got {ln.tolist()}")
    if nd.shape != (3,) or not np.issubdtype(nd.dtype, np.integer) or (nd < 1).any():
        raise MeshError(f"box divisions must be 3 positive integers, got {nd.tolist()}")
    o = np.asarray(origin, dtype=float)
    xs = [np.linspace(o[d], o[d] + ln[d], int(nd[d]) + 1) for d in range(3)]
    if element == "hexahedron":
        return grid_mesh(*xs)
    pts, hexes = _grid(*xs)
    if element == "wedge":
        w = np.concatenate([hexes[:, [0, 1, 2, 4, 5, 6]], hexes[:, [0, 2, 3, 4, 6, 7]]])
        return Mesh(pts, {"wedge": w})
    if element == "tetra":
        return Mesh(pts, {"tetra": _orient_tets(pts, hexes[:, _KUHN].reshape(-1, 4))})
    raise MeshError(f"element must be hexahedron, wedge or tetra, got {element!r}")


def _grid(
    xs: ArrayLike, ys: ArrayLike, zs: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Points and hexahedra (VTK order) of the tensor grid of three coordinate lists."""
    xs, ys, zs = (np.asarray(v, dtype=float) for v in (xs, ys, zs))
    z, y, x = np.meshgrid(zs, ys, xs, indexing="ij")
    pts = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    return pts, grid_hexes(grid_index(len(xs) - 1, len(ys) - 1, len(zs) - 1))


def grid_mesh(xs: ArrayLike, ys: ArrayLike, zs: ArrayLike) -> Mesh:
    """Bricks on the tensor grid of three increasing coordinate lists (e.g. graded ones).

    Parameters
    ----------
    xs, ys, zs : array_like
        Node coordinates along x, y and z (m), strictly increasing, two or more each.
    """
    for name, v in (("xs", xs), ("ys", ys), ("zs", zs)):
        a = np.asarray(v, dtype=float)
        if a.ndim != 1 or a.size < 2 or not (np.diff(a) > 0).all():
            raise MeshError(f"grid {name} must be 2 or more increasing numbers, got {a.tolist()}")
    pts, hexes = _grid(xs, ys, zs)
    return Mesh(pts, {"hexahedron": hexes})


def _orient_tets(pts: NDArray, tets: NDArray[np.int64]) -> NDArray[np.int64]:
    tets = tets.copy()
    neg = tet_volumes6(pts, tets) < 0
    tets[neg, 1], tets[neg, 2] = tets[neg, 2].copy(), tets[neg, 1].copy()
    return tets


def merge_points(
    points: NDArray[np.float64], cells: dict[str, NDArray[np.int64]], tol: float
) -> tuple[NDArray[np.float64], dict[str, NDArray[np.int64]]]:
    """Merge points closer than ``tol`` and renumber cells (first occurrence kept)."""
    pairs = cKDTree(points).query_pairs(tol, output_type="ndarray")
    n = len(points)
    graph = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    # each group of coincident points is represented by its first member
    first = np.full(label.max() + 1, n, dtype=np.int64)
    np.minimum.at(first, label, np.arange(n))
    rep = first[label]
    uniq, new = np.unique(rep, return_inverse=True)
    return points[uniq], {k: new[c] for k, c in cells.items()}


def hex_to_tet(mesh: Mesh) -> Mesh:
    """Split every hexahedron into 24 tetrahedra through face and cell centres.

    Conforming for any brick mesh (face centres are shared by neighbours); other cell
    types are kept as they are; regions are inherited.
    """
    if "hexahedron" not in mesh.cells:
        return mesh
    hexes = mesh.cells["hexahedron"]
    m = len(hexes)
    faces = np.stack([hexes[:, list(f)] for f in ELEMENTS["hexahedron"].faces], axis=1)
    keys = np.sort(faces.reshape(-1, 4), axis=1)
    uniq, inv = np.unique(keys, axis=0, return_inverse=True)
    inv = inv.ravel()
    n0 = mesh.n_points
    face_ctr = mesh.points[uniq].mean(axis=1)
    cell_ctr = mesh.points[hexes].mean(axis=1)
    pts = np.concatenate([mesh.points, face_ctr, cell_ctr])
    fid = (n0 + inv).reshape(m, 6)
    cid = n0 + len(uniq) + np.arange(m)
    tets = []
    for f in range(6):
        for i in range(4):
            tets.append(
                np.stack([faces[:, f, (i + 1) % 4], faces[:, f, i], fid[:, f], cid], axis=1)
            )
    tet = np.stack(tets, axis=1).reshape(-1, 4)
    x = pts[tet]
    vol = det3(jacobians(x, ELEMENTS["tetra"]))[:, 0]
    if (vol <= 0).any():
        tet = _orient_tets(pts, tet)
    cells = {k: c for k, c in mesh.cells.items() if k != "hexahedron"}
    regions = {k: r for k, r in mesh.regions.items() if k != "hexahedron"}
    cells["tetra"] = np.concatenate([cells["tetra"], tet]) if "tetra" in cells else tet
    reg = np.repeat(mesh.regions["hexahedron"], 24)
    regions["tetra"] = np.concatenate([regions["tetra"], reg]) if "tetra" in regions else reg
    return Mesh(pts, cells, regions)
