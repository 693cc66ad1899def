"""Conversion between :class:`~fem.mesh.Mesh` and ``pyvista.UnstructuredGrid``.

pyvista is imported lazily, on the first conversion. VTK's linear wedge winds like our
WEDGE6 (checked with VTK 9.7.2: a wedge with its bottom triangle counter-clockwise seen
from the top has positive volume in ``compute_cell_sizes`` and ``cell_quality``; see
:mod:`fem.io`), so connectivity passes through unchanged for every cell type.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from .errors import MeshError
from .io import _as_regions, _build, _split_cell_data
from .mesh import Mesh

if TYPE_CHECKING:
    import pyvista

__all__ = ["VTK_CELL_TYPES", "from_pyvista", "to_pyvista"]

#: VTK cell type id of each supported cell type.
VTK_CELL_TYPES = {"tetra": 10, "hexahedron": 12, "wedge": 13}
_N_NODES = {"tetra": 4, "hexahedron": 8, "wedge": 6}


def to_pyvista(
    mesh: Mesh,
    point_data: Mapping[str, ArrayLike] | None = None,
    cell_data: Mapping[str, Any] | None = None,
) -> pyvista.UnstructuredGrid:
    """The mesh as a pyvista grid, with a ``"region"`` cell array.

    Parameters
    ----------
    mesh : Mesh
        The mesh; its regions become the cell array ``"region"``.
    point_data : mapping of str to array_like, optional
        Arrays with one row per point.
    cell_data : mapping of str to (array_like or mapping of str to array_like), optional
        Per cell type (a dict like ``mesh.cells``) or one array over all cells in block
        order (the grid's cells follow the blocks of ``mesh.cells``). ``"region"`` is
        reserved.

    Returns
    -------
    pyvista.UnstructuredGrid
    """
    import pyvista as pv

    parts, types = [], []
    for kind, conn in mesh.cells.items():
        parts.append(np.hstack([np.full((len(conn), 1), conn.shape[1]), conn]).ravel())
        types.append(np.full(len(conn), VTK_CELL_TYPES[kind], dtype=np.uint8))
    grid = pv.UnstructuredGrid(np.concatenate(parts), np.concatenate(types), mesh.points)
    for name, arr in (point_data or {}).items():
        a = np.asarray(arr)
        if a.ndim == 0 or len(a) != mesh.n_points:
            raise MeshError(
                f"point data {name!r} must have {mesh.n_points} rows, got shape {a.shape}"
            )
        grid.point_data[name] = a
    for name, values in (cell_data or {}).items():
        if name == "region":
            raise MeshError("cell data name 'region' is reserved for the mesh regions")
        per = _split_cell_data(mesh, values, f"cell data {name!r}")
        grid.cell_data[name] = np.concatenate([per[k] for k in mesh.cells])
    grid.cell_data["region"] = np.concatenate([mesh.regions[k] for k in mesh.cells])
    return grid


def from_pyvista(grid: pyvista.DataSet) -> Mesh:
    """A :class:`Mesh` of the volume cells of a pyvista dataset.

    Tetrahedra, hexahedra and wedges are kept (other cells ignored), unused points are
    dropped, and a ``"region"`` cell array, when present, gives the regions.

    Raises
    ------
    MeshError
        When the grid has no volume cells (naming the cell types it has) or they are
        malformed.
    """
    import pyvista as pv

    if not isinstance(grid, pv.UnstructuredGrid):
        if not hasattr(grid, "cast_to_unstructured_grid"):
            raise MeshError(f"expected a pyvista dataset, got {type(grid).__name__}")
        grid = grid.cast_to_unstructured_grid()
    celltypes = np.asarray(grid.celltypes)
    # ``offset`` is deprecated in favour of ``cell_offsets`` in recent pyvista
    offsets = np.asarray(grid.cell_offsets if hasattr(type(grid), "cell_offsets") else grid.offset)
    conn = np.asarray(grid.cell_connectivity)
    region = np.asarray(grid.cell_data["region"]) if "region" in grid.cell_data else None
    cells, regions = {}, {}
    for kind, vtk_id in VTK_CELL_TYPES.items():
        sel = np.flatnonzero(celltypes == vtk_id)
        if sel.size:
            idx = offsets[sel][:, None] + np.arange(_N_NODES[kind])
            cells[kind] = conn[idx].astype(np.int64)
            if region is not None:
                regions[kind] = region[sel]
    if not cells:
        names = sorted({pv.CellType(int(t)).name for t in np.unique(celltypes)})
        raise MeshError(
            "the pyvista grid has no volume cells (tetra, hexahedron, wedge); cell types "
            f"found: {', '.join(names) or 'none'}"
        )
    regs = _as_regions(regions, "pyvista cell array 'region'") if region is not None else None
    return _build(grid.points, cells, regs, "pyvista grid")[0]
