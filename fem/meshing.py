"""Tetrahedral meshing of closed triangle surfaces with pytetwild (fTetWild).

With pytetwild 0.4.2, fTetWild keeps what the surface's winding number marks as
inside. A closed outer surface plus a closed inner surface whose triangles face INWARD (the
reverse of the outer one) gives a hollow body: the inner region is a hole. Had the inner
surface the same orientation as the outer one the result would be solid throughout. Open
surfaces and wrongly oriented patches are meshed too, silently, so :func:`check_surface`
rejects them first. Its tetrahedra come out all negatively oriented (without its
``vtk_ordering``) and differ from run to run; they are re-oriented here one by one.
"""

from __future__ import annotations

import os
import tempfile
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import MeshError
from .io import _build
from .mesh import DEGENERATE_TOL, Mesh, tet_volumes6

if TYPE_CHECKING:
    import pyvista

__all__ = ["check_surface", "sphere_surface", "tetrahedralize"]

_MAX_LISTED = 10


def _pairs(edges: NDArray[np.int64], extra: list[str] | None = None) -> str:
    shown = [f"({a}, {b})" for a, b in edges[:_MAX_LISTED].tolist()]
    if extra is not None:
        shown = [f"{s} {x}" for s, x in zip(shown, extra)]
    more = f", ... ({len(edges) - _MAX_LISTED} more)" if len(edges) > _MAX_LISTED else ""
    return ", ".join(shown) + more


def check_surface(points: ArrayLike, triangles: ArrayLike, *, source: str | None = None) -> None:
    """Check that a triangle surface is closed, manifold and consistently oriented.

    Parameters
    ----------
    points : array_like, shape (N, 3)
        Node coordinates.
    triangles : array_like of int, shape (M, 3)
        Node indices of each triangle.
    source : str, optional
        Where the surface came from (a file name), put at the start of messages.

    Raises
    ------
    MeshError
        Listing (up to ten) culprits as node pairs with their count: open edges (used by
        one triangle), non-manifold edges (used by more than two), and edges traversed
        twice in the same direction (neighbours wound opposite ways); also bad shapes,
        indices out of range and triangles that repeat a node.
    """
    where = f"{source}: " if source else ""
    pts = np.asarray(points, dtype=np.float64)
    tri = np.asarray(triangles)
    if pts.ndim != 2 or pts.shape[1] != 3 or not np.isfinite(pts).all():
        raise MeshError(f"{where}surface points must be finite, shape (N, 3), got {pts.shape}")
    if tri.ndim != 2 or tri.shape[1] != 3 or len(tri) == 0:
        raise MeshError(f"{where}surface triangles must have shape (M, 3), got {tri.shape}")
    if not np.issubdtype(tri.dtype, np.integer):
        raise MeshError(f"{where}surface triangles must be integers, got dtype {tri.dtype}")
    tri = tri.astype(np.int64)
    out = np.flatnonzero(((tri < 0) | (tri >= len(pts))).any(axis=1))
    if out.size:
        raise MeshError(
            f"{where}{out.size} triangle(s) refer to nodes outside 0..{len(pts) - 1}, first: "
            f"triangle {out[0]} {tri[out[0]].tolist()}"
        )
    s = np.sort(tri, axis=1)
    rep = np.flatnonzero((s[:, 1:] == s[:, :-1]).any(axis=1))
    if rep.size:
        raise MeshError(
            f"{where}{rep.size} degenerate triangle(s) repeat a node, first: triangle "
            f"{rep[0]} {tri[rep[0]].tolist()}"
        )
    n = np.int64(len(pts))
    directed = tri[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    lo, hi = directed.min(axis=1), directed.max(axis=1)
    keys, counts = np.unique(lo * n + hi, return_counts=True)
    problems = []
    open_ = keys[counts == 1]
    if open_.size:
        e = np.stack([open_ // n, open_ % n], axis=1)
        problems.append(f"not closed: {len(e)} open edge(s) used by one triangle only: {_pairs(e)}")
    multi = counts > 2
    if multi.any():
        e = np.stack([keys[multi] // n, keys[multi] % n], axis=1)
        used = [f"in {c} triangles" for c in counts[multi][:_MAX_LISTED].tolist()]
        problems.append(
            f"non-manifold: {len(e)} edge(s) shared by more than two triangles: {_pairs(e, used)}"
        )
    _, first, dcounts = np.unique(
        directed[:, 0] * n + directed[:, 1], return_index=True, return_counts=True
    )
    in_two = counts[np.searchsorted(keys, (lo * n + hi)[first])] == 2
    twice = first[(dcounts > 1) & in_two]
    if twice.size:
        e = directed[twice]
        problems.append(
            f"inconsistently oriented: {len(e)} edge(s) traversed twice in the same "
            f"direction (neighbouring triangles wound opposite ways): {_pairs(e)}"
        )
    if problems:
        raise MeshError(f"{where}bad surface, " + "; ".join(problems))


def sphere_surface(
    radius: float, center: ArrayLike = (0.0, 0.0, 0.0), refinement: int = 3
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """A closed, outward oriented icosphere.

    Parameters
    ----------
    radius : float
        Radius of the vertices (the facets lie slightly inside).
    center : array_like, shape (3,)
        Centre.
    refinement : int
        Subdivisions of the icosahedron: ``20 * 4**refinement`` triangles. At 3 (1280
        triangles) the enclosed volume is 0.9 % short of the sphere's, at 2 it is 3.4 %.

    Returns
    -------
    points : ndarray, shape (N, 3)
    triangles : ndarray, shape (M, 3)
        Counter-clockwise seen from outside.
    """
    import pyvista as pv

    if not radius > 0:
        raise MeshError(f"sphere radius must be positive, got {radius!r}")
    if int(refinement) != refinement or refinement < 0:
        raise MeshError(f"refinement must be an integer >= 0, got {refinement!r}")
    c = np.asarray(center, dtype=np.float64)
    ico = pv.Icosphere(radius=float(radius), center=c.tolist(), nsub=int(refinement))
    pts = np.asarray(ico.points, dtype=np.float64)
    tri = np.asarray(ico.regular_faces, dtype=np.int64)
    x = pts[tri] - c
    if np.einsum("ij,ij->i", x[:, 0], np.cross(x[:, 1], x[:, 2])).sum() < 0:
        tri = tri[:, ::-1].copy()
    return pts, tri


def _load_surface(surface: Any) -> tuple[NDArray, NDArray, str | None]:
    if isinstance(surface, tuple):
        if len(surface) != 2:
            raise MeshError(f"a surface tuple must be (points, triangles), got {len(surface)}")
        return np.asarray(surface[0]), np.asarray(surface[1]), None
    import pyvista as pv

    source = None
    if isinstance(surface, (str, os.PathLike)):
        path = Path(surface)
        source = f"surface file {path}"
        if not path.is_file():
            raise MeshError(f"{source} does not exist")
        try:
            surface = pv.read(path)
        except Exception as exc:
            raise MeshError(f"cannot read {source}: {type(exc).__name__}: {exc}") from None
        if not isinstance(surface, pv.PolyData) and hasattr(surface, "extract_surface"):
            with warnings.catch_warnings():  # pyvista's notice of a future default
                warnings.simplefilter("ignore")
                surface = surface.extract_surface()
    if not isinstance(surface, pv.PolyData):
        raise MeshError(
            f"{source or 'surface'}: expected a path, a pyvista.PolyData or (points, "
            f"triangles), got {type(surface).__name__}"
        )
    poly = surface.triangulate().clean()  # also merges coincident points (e.g. from STL)
    if poly.faces.size == 0:
        raise MeshError(f"{source or 'surface'}: the surface has no polygons")
    return np.asarray(poly.points), np.asarray(poly.regular_faces), source


def _sizing_arrays(field: Any) -> dict[str, NDArray]:
    if field is None:
        return {}
    if isinstance(field, tuple) and len(field) == 3:
        pts, tets, values = field
    elif hasattr(field, "cells_dict") and hasattr(field, "point_data"):
        tets = field.cells_dict.get(10)
        values = field.point_data.active_scalars
        if tets is None or len(field.cells_dict) != 1 or values is None:
            raise MeshError(
                "sizing_field must be an all-tetrahedral pyvista grid whose active point "
                "scalars are the target edge lengths"
            )
        pts = field.points
    else:
        raise MeshError(
            "sizing_field must be a pyvista.UnstructuredGrid or (points, tets, values), got "
            f"{type(field).__name__}"
        )
    return {
        "bg_vertices": np.asarray(pts, np.float64),
        "bg_tets": np.asarray(tets, np.int32),
        "bg_values": np.asarray(values, np.float64),
    }


def tetrahedralize(
    surface: str | os.PathLike | pyvista.PolyData | tuple[ArrayLike, ArrayLike],
    edge_length: float | None,
    *,
    sizing_field: pyvista.UnstructuredGrid | tuple | None = None,
    optimize: bool = True,
    **tetwild_options: Any,
) -> Mesh:
    """Fill a closed triangle surface with positively oriented tetrahedra (pytetwild).

    Parameters
    ----------
    surface : path, pyvista.PolyData or tuple (points, triangles)
        A file pyvista reads (cleaned: coincident points merged), a surface (triangulated
        and cleaned) or arrays. Nested closed surfaces make holes where the inner one is
        oriented inward (see the module docstring).
    edge_length : float or None
        Target tetrahedron edge length (absolute, in the surface's units); None: the
        surface's own mean edge length.
    sizing_field : pyvista.UnstructuredGrid or tuple, optional
        A tetrahedral background mesh whose active point scalars are target edge lengths,
        or ``(points, tets, values)``; needs ``optimize=True``.
    optimize : bool
        Let fTetWild improve element quality (slower, better elements).
    **tetwild_options
        Passed on to ``pytetwild.tetrahedralize``: ``epsilon`` (envelope size relative to
        the bounding box, default 1e-3), ``stop_energy``, ``num_opt_iter``, ``coarsen``...
        A looser envelope and fewer optimisation passes make large surfaces much faster.

    Returns
    -------
    Mesh
        Tetrahedra only, region 0, no unused points. The output is not deterministic.

    Raises
    ------
    MeshError
        On a bad surface (see :func:`check_surface`), a failure of pytetwild or an empty
        result. A warning tells how many zero-volume slivers were dropped, if any.
    """
    import pytetwild

    if edge_length is not None and not edge_length > 0:
        raise MeshError(f"edge_length must be positive, got {edge_length!r}")
    points, tris, source = _load_surface(surface)
    check_surface(points, tris, source=source)
    if edge_length is None:
        x = np.asarray(points, dtype=np.float64)[np.asarray(tris)]
        edge_length = float(np.linalg.norm(x - np.roll(x, 1, axis=1), axis=2).mean())
    what = source or "the surface"
    sizing = _sizing_arrays(sizing_field)
    # fTetWild writes "__tracked_surface.stl" into the working directory: run it in a
    # scratch directory so that it never litters the user's folder.
    cwd = os.getcwd()
    try:
        with tempfile.TemporaryDirectory(prefix="tetwild-") as scratch:
            os.chdir(scratch)
            try:
                p, t = pytetwild.tetrahedralize(
                    np.ascontiguousarray(points, np.float64),
                    np.ascontiguousarray(tris, np.int32),
                    edge_length_abs=float(edge_length),
                    optimize=optimize,
                    **sizing,
                    **tetwild_options,
                )
            finally:
                os.chdir(cwd)
    except MeshError:
        raise
    except Exception as exc:
        raise MeshError(f"pytetwild failed on {what}: {type(exc).__name__}: {exc}") from None
    p = np.asarray(p, dtype=np.float64)
    t = np.asarray(t, dtype=np.int64).reshape(-1, 4) if t is not None else np.zeros((0, 4))
    if len(t) == 0:
        raise MeshError(f"pytetwild returned no tetrahedra for {what}")
    x = p[t]
    vol6 = tet_volumes6(p, t)
    neg = vol6 < 0
    t[neg] = t[neg][:, [0, 2, 1, 3]]
    sliver = np.abs(vol6) <= DEGENERATE_TOL * np.ptp(x, axis=1).max(axis=1) ** 3
    if sliver.any():
        warnings.warn(
            f"dropped {int(sliver.sum())} zero-volume sliver tetrahedra of {len(t)} "
            f"from the pytetwild mesh of {what}",
            stacklevel=2,
        )
        t = t[~sliver]
        if len(t) == 0:
            raise MeshError(f"pytetwild returned only zero-volume tetrahedra for {what}")
    return _build(p, {"tetra": t}, None, f"pytetwild mesh of {what}")[0]
