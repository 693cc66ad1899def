"""The candidates of the query benchmark: each library's build and query, and the note on them.

:class:`Candidate` and :data:`CANDIDATES` (``contact.geometry.surfacequery``, libigl, fcpw,
open3d, embreex, vtk), each skipped when its package is not installed, and
:data:`CANDIDATES_NOTE`, the facts about the packages that the timings do not show. The
study itself is :mod:`benchmarks.queries`.
"""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from contact.geometry.surfacequery import TriangleSurface

__all__ = ["CANDIDATES", "CANDIDATES_NOTE", "VTK_LOOP_LIMIT", "Candidate"]

#: The VTK locator loops in Python: not run above this many points.
VTK_LOOP_LIMIT = 20_000


# --- candidates -----------------------------------------------------------------------------


@dataclass(frozen=True)
class Candidate:
    """One library's way of answering a query.

    ``build(V, F)`` makes the search state from the surface; ``query(state, V, F, X)``
    returns ``(distance, closest point)`` for ``kind == "closest"`` or a boolean array for
    ``kind == "inside"``.
    """

    name: str
    kind: str
    package: str
    dist: str
    precision: str
    build: Callable[[np.ndarray, np.ndarray], Any]
    query: Callable[[Any, np.ndarray, np.ndarray, np.ndarray], Any]
    limit: int | None = None

    @property
    def available(self) -> bool:
        """Whether its package imports (Open3D needs system libraries besides its wheel)."""
        if importlib.util.find_spec(self.package) is None:
            return False
        try:
            importlib.import_module(self.package)
        except Exception:
            return False
        return True


def _ours_build(v: np.ndarray, f: np.ndarray) -> TriangleSurface:
    s = TriangleSurface(v, f, name="skin")
    s._topology.pop("tree", None)  # a new connectivity: the hierarchy built, not recalled
    s._boxes  # noqa: B018  (build now, to time it)
    return s


_REFIT: dict[bytes, TriangleSurface] = {}


def _ours_refit(v: np.ndarray, f: np.ndarray) -> TriangleSurface:
    key = f.tobytes()
    if key not in _REFIT:
        _REFIT[key] = TriangleSurface(v, f, name="skin")
        _REFIT[key]._tree  # noqa: B018
    s = _REFIT[key].moved(v)  # the skin at new coordinates: the boxes refitted only
    s._boxes  # noqa: B018
    return s


def _ours_closest(s: TriangleSurface, v: Any, f: Any, x: np.ndarray) -> tuple:
    c = s.closest(x)
    return c.distance, c.point


def _ours_wn_build(v: np.ndarray, f: np.ndarray) -> TriangleSurface:
    s = TriangleSurface(v, f, name="skin")
    s._winding  # noqa: B018
    return s


def _ours_pn(s: TriangleSurface, v: Any, f: Any, x: np.ndarray) -> np.ndarray:
    return s.signed_distance(x, sign="pseudonormal") < 0


def _igl_aabb_build(v: np.ndarray, f: np.ndarray) -> Any:
    import igl

    t = igl.AABB()
    t.init(v, f)
    return t


def _igl_aabb_query(t: Any, v: np.ndarray, f: np.ndarray, x: np.ndarray) -> tuple:
    d2, _, c = t.squared_distance(v, f, x)
    return np.sqrt(d2), c


def _igl_fwn_build(v: np.ndarray, f: np.ndarray) -> Any:
    import igl

    t = igl.FastWindingNumberBVH()
    t.init(v, f)
    return t


def _igl_sd_query(_: Any, v: np.ndarray, f: np.ndarray, x: np.ndarray) -> np.ndarray:
    import igl

    s = igl.signed_distance(x, v, f, igl.SIGNED_DISTANCE_TYPE_PSEUDONORMAL)[0]
    return s < 0


def _fcpw_build(v: np.ndarray, f: np.ndarray) -> Any:
    import fcpw

    scene = fcpw.scene_3D()
    scene.set_object_count(1)
    scene.set_object_vertices(np.asfortranarray(v, dtype=np.float32), 0)
    scene.set_object_triangles(np.asfortranarray(f, dtype=np.int32), 0)
    scene.build(fcpw.aggregate_type.bvh_surface_area, True)
    return scene


def _fcpw_closest(scene: Any, v: Any, f: Any, x: np.ndarray) -> tuple:
    import fcpw

    hits = fcpw.interaction_3D_list()
    q = np.asfortranarray(x, dtype=np.float32)
    scene.find_closest_points(q, np.full(len(x), np.inf, np.float32), hits)
    p = np.array([h.p for h in hits], dtype=np.float64)  # one Python object per point
    return np.linalg.norm(x - p, axis=1), p


def _fcpw_inside(scene: Any, v: Any, f: Any, x: np.ndarray) -> np.ndarray:
    """``contains`` through fcpw's list types: its numpy overload (1.2.0) leaves the result
    array untouched, so the points go through a Python list."""
    import fcpw

    pts = fcpw.float_3D_list()
    pts.extend(list(x.astype(np.float32)))
    out = fcpw.uint32_list()
    scene.contains(pts, out)
    return np.asarray(list(out)) > 0


def _o3d_build(v: np.ndarray, f: np.ndarray) -> Any:
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(v.astype(np.float32)), o3d.core.Tensor(f.astype(np.uint32)))
    scene.compute_closest_points(o3d.core.Tensor(v[:1].astype(np.float32)))  # builds the BVH
    return scene


def _o3d_closest(scene: Any, v: Any, f: Any, x: np.ndarray) -> tuple:
    import open3d as o3d

    r = scene.compute_closest_points(o3d.core.Tensor(x.astype(np.float32)))
    p = r["points"].numpy().astype(np.float64)
    return np.linalg.norm(x - p, axis=1), p


def _o3d_inside(nsamples: int) -> Callable:
    def query(scene: Any, v: Any, f: Any, x: np.ndarray) -> np.ndarray:
        import open3d as o3d

        occ = scene.compute_occupancy(o3d.core.Tensor(x.astype(np.float32)), nsamples=nsamples)
        return occ.numpy() > 0.5

    return query


def _embree_build(v: np.ndarray, f: np.ndarray) -> Any:
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene, v.astype(np.float32), f.astype(np.int32))
    scene.run(v[:1].astype(np.float32), np.array([[0, 0, 1]], np.float32))  # commits
    return scene


def _embree_inside(scene: Any, v: np.ndarray, f: Any, x: np.ndarray) -> np.ndarray:
    """Ray parity along one fixed, skewed direction, re-casting just past every hit."""
    d = np.array([0.5773, 0.5774, 0.5775], np.float32)
    eps = 1e-6 * float(np.ptp(v, axis=0).max())
    origin = x.astype(np.float32)
    live = np.arange(len(x))
    count = np.zeros(len(x), np.int64)
    for _ in range(64):
        if live.size == 0:
            break
        dirs = np.broadcast_to(d, (live.size, 3)).copy()
        r = scene.run(origin[live], dirs, output=1)
        hit = r["geomID"] != -1
        count[live[hit]] += 1
        live = live[hit]
        origin[live] += (r["tfar"][hit, None] + eps) * d
    return count % 2 == 1


def _vtk_poly(v: np.ndarray, f: np.ndarray) -> Any:
    import pyvista as pv

    return pv.PolyData.from_regular_faces(v, f)


def _vtk_locator_build(v: np.ndarray, f: np.ndarray) -> Any:
    from vtkmodules.vtkCommonDataModel import vtkStaticCellLocator

    loc = vtkStaticCellLocator()
    loc.SetDataSet(_vtk_poly(v, f))
    loc.BuildLocator()
    return loc


def _vtk_locator_closest(loc: Any, v: Any, f: Any, x: np.ndarray) -> tuple:
    from vtkmodules.vtkCommonCore import reference
    from vtkmodules.vtkCommonDataModel import vtkGenericCell

    cell = vtkGenericCell()
    cid, sub, d2 = reference(0), reference(0), reference(0.0)
    p = np.empty_like(x)
    cp = [0.0, 0.0, 0.0]
    for i, q in enumerate(x.tolist()):
        loc.FindClosestPoint(q, cp, cell, cid, sub, d2)
        p[i] = cp
    return np.linalg.norm(x - p, axis=1), p


def _vtk_inside(method: str) -> Callable:
    """pyvista's ``select_interior_points``: ``signed_distance`` (vtkImplicitPolyDataDistance)
    or ``cell_locator`` (vtkSelectEnclosedPoints, ray casting)."""

    def query(poly: Any, v: Any, f: Any, x: np.ndarray) -> np.ndarray:
        import pyvista as pv

        sel = pv.PolyData(x).select_interior_points(poly, method=method, check_surface=False)
        return np.asarray(sel.point_data["selected_points"]) > 0

    return query


CANDIDATES: tuple[Candidate, ...] = (
    Candidate(
        "contact.geometry.surfacequery", "closest", "numba", "numba", "float64",
        _ours_build, _ours_closest,
    ),
    Candidate(
        "contact.geometry.surfacequery, moved (refit)", "closest", "numba", "numba", "float64",
        _ours_refit, _ours_closest,
    ),
    Candidate(
        "libigl AABB", "closest", "igl", "libigl", "float64", _igl_aabb_build, _igl_aabb_query
    ),
    Candidate(
        "fcpw", "closest", "fcpw", "fcpw", "float32", _fcpw_build, _fcpw_closest
    ),
    Candidate(
        "open3d", "closest", "open3d", "open3d-cpu", "float32", _o3d_build, _o3d_closest
    ),
    Candidate(
        "vtk StaticCellLocator (Python loop)", "closest", "vtkmodules", "vtk", "float64",
        _vtk_locator_build, _vtk_locator_closest, VTK_LOOP_LIMIT,
    ),
    Candidate(
        "contact.geometry.surfacequery (winding)", "inside", "igl", "libigl", "float64",
        _ours_wn_build, lambda s, v, f, x: s.inside(x),
    ),
    Candidate(
        "contact.geometry.surfacequery (pseudonormal)", "inside", "numba", "numba", "float64",
        _ours_build, _ours_pn,
    ),
    Candidate(
        "libigl FastWindingNumberBVH", "inside", "igl", "libigl", "float64",
        _igl_fwn_build, lambda t, v, f, x: t.winding_number(x) > 0.5,
    ),
    Candidate(
        "libigl signed_distance (pseudonormal)", "inside", "igl", "libigl", "float64",
        lambda v, f: None, _igl_sd_query,
    ),
    Candidate("fcpw contains", "inside", "fcpw", "fcpw", "float32", _fcpw_build, _fcpw_inside),
    Candidate(
        "open3d occupancy (1 ray)", "inside", "open3d", "open3d-cpu", "float32",
        _o3d_build, _o3d_inside(1),
    ),
    Candidate(
        "open3d occupancy (3 rays)", "inside", "open3d", "open3d-cpu", "float32",
        _o3d_build, _o3d_inside(3),
    ),
    Candidate(
        "embreex ray parity", "inside", "embreex", "embreex", "float32",
        _embree_build, _embree_inside,
    ),
    Candidate(
        "vtk ImplicitPolyDataDistance", "inside", "vtkmodules", "vtk", "float64",
        _vtk_poly, _vtk_inside("signed_distance"),
    ),
    Candidate(
        "vtk SelectEnclosedPoints", "inside", "vtkmodules", "vtk", "float64",
        _vtk_poly, _vtk_inside("cell_locator"),
    ),
)  # fmt: skip


#: Facts about the packages that the timings do not show (checked when they were chosen).
CANDIDATES_NOTE = """\
| package | licence | wheel (cp311) | installed | precision | closest facet | inside |
|---|---|---:|---:|---|---|---|
| libigl 2.6.3 | MPL-2.0 (the wheel also ships `igl.copyleft`, GPL/AGPL, never \
imported) | 14 MB | 16 MB | float64 | AABB tree: facet + point | exact and fast winding \
number, pseudo-normal sign |
| fcpw 1.2.0 | MIT | 26 MB | 65 MB | float32 | BVH: facet + point + uv, one Python object \
per point | `contains` (rays); its numpy overload leaves the result empty |
| open3d-cpu 0.20.0 | MIT | 105 MB | 312 MB, plus dash, flask, plotly... (144 MB) and the \
system's libusb to import | float32 | Embree BVH: facet + point + uv | ray parity |
| embreex 4.4.0 | BSD-2 (Embree: Apache-2.0) | 15 MB | 45 MB | float32 | none | ray \
parity, re-cast past every hit |
| vtk 9.7.2 (here already, through pyvista) | BSD-3 | - | - | float64 | one Python call \
per point | implicit distance (pseudo-normal), ray casting |

Chosen first: libigl. It is the only candidate with float64 closest points and a
vectorised facet index *and* a robust inside test (winding number) in one small wheel
with a permissive licence. float32 (fcpw, Open3D, embreex) puts the closest point ~1e-6 m
off on a 0.25 m hand, which is the size of the gaps the contact iteration resolves;
Open3D's faster rays come with a 400 MB install and a system library.

Since then the closest facet is searched by `contact.geometry.closestkernels` (numba, a dependency
already): the contact iteration asks a few hundred points at a time at new coordinates,
and libigl's tree had to be built again for each set (3 ms on the coarse skin, more than
the search). The hierarchy's shape is kept per connectivity and only its boxes are
refitted (the `moved (refit)` rows). libigl stays for the winding number.
`contact.geometry.surfacequery` computes the point on the facet exactly (weights and distance to
rounding; libigl's own distance, the square root of a squared distance, is only good to
~1e-12 relative near the surface).
"""
