"""An object's volume mesh from its file: a volume mesh used as it is, a surface filled.

:func:`mesh_object` reads the file with :func:`fem.read_mesh`. A volume mesh is used as it
is: the reader and :class:`fem.Mesh` already refuse inverted or degenerate cells (and turn
a file wound the other way throughout), and its boundary surface goes through the checks of
:func:`~contact.objects.surface.check_object_surface`. A file of surface cells (or one only
pyvista reads) is checked the same way and filled with tetrahedra by
:func:`fem.tetrahedralize` (fTetWild). Every error is one :class:`~contact.errors.ObjectError`
line that starts with ``<where> = '<path>': ``.
"""

from __future__ import annotations

import logging
import math
import os
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

import fem

from ..errors import ObjectError
from ..geometry import enclosed_volume
from ..geometry.triangles import surface_of_mesh
from ..scene import sizing
from .cache import FILL_TOLERANCE, cached
from .formats import SURFACE_FORMATS, read_surface_file
from .surface import check_object_surface

__all__ = ["mesh_object", "read_surface"]

log = logging.getLogger(__name__)


def _reword(exc: fem.MeshError, path: Path) -> str:
    """A reader's message without its own mention of the file (the prefix names it)."""
    text = str(exc)
    for said in (f"mesh file {path}: ", f"mesh file {path} ", f"{path}: "):
        text = text.replace(said, "")
    return text


@contextmanager
def _vtk_silenced() -> Iterator[None]:
    """VTK's own error and warning output kept off stderr (the reader's failure is told)."""
    import pyvista as pv
    import vtk

    shown = vtk.vtkObject.GetGlobalWarningDisplay()
    vtk.vtkObject.GlobalWarningDisplayOff()
    try:
        with pv.vtk_verbosity("off"):
            yield
    finally:
        vtk.vtkObject.SetGlobalWarningDisplay(shown)


def read_surface(
    path: str | os.PathLike, *, where: str = "object.mesh"
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The triangles of a surface file, unchecked: STL, OBJ or PLY read here, else by pyvista.

    STL, OBJ and PLY files are read and checked by :mod:`contact.objects.formats`; other
    formats go to pyvista (or meshio through it) with VTK's own output silenced. Polygons
    are split into triangles; lines and vertices are ignored; a volume file gives its
    outer surface.

    Raises
    ------
    ObjectError
        The file is missing or unreadable, or holds no polygons.
    """
    import pyvista as pv

    path = Path(path)
    prefix = f"{where} = '{path}': "
    if not path.is_file():
        raise ObjectError(prefix + ("not a file" if path.exists() else "no such file"))
    if path.suffix.lower() in SURFACE_FORMATS:
        return read_surface_file(path, prefix)
    with warnings.catch_warnings(record=True) as said, _vtk_silenced():
        warnings.simplefilter("always")  # a failing VTK reader only warns
        try:
            data: Any = pv.read(path)
        except Exception as exc:
            why = str(exc).strip().splitlines()[0][:200] if str(exc).strip() else ""
            raise ObjectError(f"{prefix}cannot be read: {type(exc).__name__}: {why}") from None
    if isinstance(data, pv.MultiBlock):
        data = data.combine()
    if not isinstance(data, pv.PolyData):
        with warnings.catch_warnings():  # pyvista's notice of a future default
            warnings.simplefilter("ignore")
            data = data.extract_surface()
    if data.faces.size == 0:
        if data.n_points == 0:  # VTK's reader failed, its own output silenced
            why = str(said[0].message).strip().splitlines()[0][:200] if said else ""
            why = why or "VTK's reader found nothing in it (an empty or damaged file)"
            raise ObjectError(f"{prefix}cannot be read: {why}")
        raise ObjectError(f"{prefix}holds no triangles or polygons")
    poly = data.triangulate()
    return np.asarray(poly.points, np.float64), np.asarray(poly.regular_faces, np.int64)


def _read_volume(path: Path, prefix: str) -> tuple[fem.Mesh | None, str | None]:
    """The file's volume mesh, or None and meshio's reason when it may be a surface."""
    try:
        return fem.read_mesh(path), None
    except fem.NoVolumeCellsError as exc:
        if exc.surface:
            return None, None
        found = ", ".join(exc.cell_types) or "none"
        raise ObjectError(
            f"{prefix}holds neither volume cells nor a triangle surface (cell types: {found})"
        ) from None
    except fem.MeshError as exc:
        text = _reword(exc, path)
        if "unknown format" in text:  # meshio's: pyvista may know it (VTP, ...)
            return None, text
        if text.startswith("cannot read (") and text.endswith(")"):
            text = f"cannot be read {text[len('cannot read (') : -1]}"
        raise ObjectError(f"{prefix}{text}") from None


def _check_fill(
    points: NDArray, tri: NDArray, mesh_size: float | None, prefix: str, envelope: float
) -> None:
    """Refuse a fill too big for the machine, from the surface's shape, before fTetWild runs.

    The body is estimated from the target edge (:func:`contact.scene.sizing.fill_size`); a
    surface of far more triangles than that edge needs is better simplified first: said
    with a warning, or in the refusal when fTetWild's memory for them is what does not fit.
    """
    x = points[tri]
    if mesh_size is None:
        mesh_size = float(np.linalg.norm(x - np.roll(x, 1, axis=1), axis=2).mean())
    area = 0.5 * float(np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), axis=1).sum())
    diagonal = float(np.linalg.norm(np.ptp(points, axis=0)))
    volume = abs(enclosed_volume(points, tri))
    size = sizing.fill_size(volume, area, diagonal, len(tri), mesh_size, envelope)
    n = len(tri)
    simplify = (
        f"simplify it to about {size.triangles:.3g} triangles first (a mesh_size of "
        f"{mesh_size:g} m keeps no more), e.g. pyvista.read(path).decimate("
        f"{1.0 - size.triangles / n:.3g}).save(new_path)"
    )
    avail = sizing.available_memory()
    if avail is not None and size.memory > avail:
        has = f"and the machine has {sizing.format_bytes(avail)} available"
        if size.fill_memory > sizing.body_memory(3.0 * size.nodes):
            raise ObjectError(
                f"{prefix}{n} triangles, too many to fill: fTetWild needs about "
                f"{sizing.format_bytes(size.memory)} of memory for them, {has}: {simplify}"
            )
        raise ObjectError(
            f"{prefix}too fine at mesh_size {mesh_size:g} m: about {size.nodes:.3g} nodes, "
            f"{sizing.format_bytes(size.memory)} of memory, {has}: give a larger mesh_size"
        )
    if n > sizing.LARGE_SURFACE and n > size.triangles:
        log.warning("%s%d triangles: fTetWild takes minutes on them; %s", prefix, n, simplify)
    if 3.0 * size.nodes > sizing.WARN_DOFS:
        log.warning(
            "%sabout %.3g nodes at mesh_size %g m: a big object", prefix, size.nodes, mesh_size
        )


def mesh_object(
    path: str | os.PathLike,
    mesh_size: float | None = None,
    *,
    where: str = "object.mesh",
    **tetwild_options: Any,
) -> fem.Mesh:
    """Read, check and if need be fill an object's mesh file.

    Parameters
    ----------
    path : str or path-like
        A volume mesh meshio reads (used as it is), or a closed triangle surface meshio or
        pyvista reads (STL, OBJ, PLY, VTP, ...), in metres.
    mesh_size : float or None
        Target tetrahedron edge length (m) for a surface; None: the surface's mean edge
        length. Ignored for a volume mesh. A surface's fill is kept between runs
        (:mod:`contact.objects.cache`): the same file and size give the same tetrahedra.
    where : str
        The scene key that gave the file (``object[1].mesh``), starting every message.
    **tetwild_options
        Passed on to :func:`fem.tetrahedralize` for a surface (``optimize=False`` or a
        looser ``epsilon`` make large surfaces much faster).

    Returns
    -------
    fem.Mesh
        Positively oriented cells (tetrahedra from a surface, region 0).

    Raises
    ------
    ObjectError
        One line ``<where> = '<path>': <what is wrong>``: a missing or unreadable file, a
        bad surface (:func:`~contact.objects.surface.check_object_surface`), a bad volume
        mesh (inverted or degenerate cells, non-manifold faces), or fTetWild's failure.

    Warns
    -----
    UserWarning
        A surface wound inward, flipped.
    """
    path = Path(path)
    prefix = f"{where} = '{path}': "
    if mesh_size is not None and not (math.isfinite(mesh_size) and mesh_size > 0):
        raise ObjectError(f"{where}_size = {mesh_size!r}: must be a positive length in metres")
    if not path.is_file():
        raise ObjectError(prefix + ("not a file" if path.exists() else "no such file"))
    surface_file = path.suffix.lower() in SURFACE_FORMATS  # no volume cells: not meshio's
    mesh, unread = (None, None) if surface_file else _read_volume(path, prefix)
    if mesh is not None:
        try:
            tri = surface_of_mesh(mesh)[1]
        except fem.MeshError as exc:
            raise ObjectError(f"{prefix}{exc}") from None
        check_object_surface(mesh.points, tri, path, where=where)
        log.info("%s = '%s': a volume mesh of %d cells, used as it is", where, path, mesh.n_cells)
        return mesh
    try:
        surface = read_surface(path, where=where)
    except ObjectError as exc:
        if unread is None or "automatically read" not in str(exc):  # pyvista's reader told
            raise
        raise ObjectError(f"{prefix}cannot be read: {unread}") from None  # neither knows it
    points, tri = check_object_surface(*surface, path, where=where)
    log.info(
        "%s = '%s': a surface of %d triangles, filled with tetrahedra (edge %s)",
        where,
        path,
        len(tri),
        "its mean edge length" if mesh_size is None else f"{mesh_size:g} m",
    )
    epsilon = float(tetwild_options.get("epsilon", sizing.ENVELOPE))
    _check_fill(points, tri, mesh_size, prefix, epsilon)

    def fill() -> fem.Mesh:
        try:
            return fem.tetrahedralize((points, tri), mesh_size, **tetwild_options)
        except fem.MeshError as exc:
            raise ObjectError(f"{prefix}cannot be filled with tetrahedra: {exc}") from None

    settings = f"size={mesh_size!r} options={sorted(tetwild_options.items())!r}"
    return cached(path, settings, fill, (points, tri), tolerance=max(FILL_TOLERANCE, 5 * epsilon))
