"""Contact queries: closest point and inside tests on the hand's skin, library against library.

The repel step of the contact iteration asks, for the nodes of one body, which lie inside
the other's closed skin and where their closest points on it are. The skin moves every
iteration, so building the search structure counts as much as querying it: both are timed
apart. Candidates (each skipped when its package is not installed):

* ``contact.geometry.surfacequery`` -- what the contact code uses: its own bounding-volume
  hierarchy compiled with numba (:mod:`contact.geometry.closestkernels`) for the closest facet and
  the exact barycentric weights, pseudo-normals in numpy, libigl's fast winding number for
  inside (``pseudonormal``: the sign of the closest point's normal). Its build is timed
  twice: for a new connectivity (the hierarchy's shape and its boxes), and for the same
  skin at new coordinates (``moved``: the boxes refitted, what an iteration pays);
* ``libigl`` -- ``igl.AABB.squared_distance`` alone, ``igl.FastWindingNumberBVH`` and
  ``igl.signed_distance`` (pseudo-normal sign; builds its tree inside the call);
* ``fcpw`` -- ``scene_3D.find_closest_points`` and ``contains`` (float32);
* ``open3d`` -- ``RaycastingScene.compute_closest_points`` and ``compute_occupancy`` (ray
  parity, float32; the BVH is built on the first query, so a one-point query is part of
  the build);
* ``embreex`` -- inside by ray parity (Embree intersections, float32, re-cast past each
  hit); no closest-point query;
* ``vtk`` -- ``vtkStaticCellLocator.FindClosestPoint`` (one Python call per point: the
  only closest-facet query VTK exposes), and through pyvista's ``select_interior_points``
  ``vtkImplicitPolyDataDistance`` (pseudo-normal sign) and ``vtkSelectEnclosedPoints``
  (ray casting).

Query points are near the skin, as a ball's nodes pressed against it: random points of
random facets (area-weighted) moved along the facet normal by up to +-3 mm. Accuracy is
checked on the first :data:`N_REF` of them against a brute-force numpy reference (every
point against every facet, Ericson's closest point; Van Oosterom-Strackee solid angles for
the exact winding number), and inside/outside robustness on the skin's nodes moved by
+-1e-4 m and +-1e-6 m along their angle-weighted normals, where the answer is known.
"""

from __future__ import annotations

import importlib
import importlib.util
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from contact.geometry.surfacequery import TriangleSurface, closest_on_triangles

from ._common import (
    Column,
    _version,
    load_average,
    machine_info,
    markdown_table,
    measure,
    results_dir,
    write_csv,
    write_markdown,
)

__all__ = [
    "CANDIDATES",
    "SIZES",
    "Candidate",
    "brute_force_closest",
    "exact_winding_number",
    "near_surface_points",
    "run",
]

#: Query-point counts: full run and ``--quick``.
SIZES = {False: (2_000, 20_000, 100_000), True: (300,)}
#: Skin resolutions: full run and ``--quick``.
RESOLUTIONS = {False: ("coarse", "fine"), True: ("coarse",)}
#: Points checked against the brute-force reference: full run and ``--quick``.
N_REF = {False: 2_000, True: 100}
#: Offset of the query points from the skin (m): uniform in +-this.
SPREAD = 3e-3
#: Offsets along the node normals for the robustness check (m).
OFFSETS = (1e-4, 1e-6)
#: Seconds the repeats of one timing may take (full run, quick run).
BUDGET = {False: 3.0, True: 0.0}
#: The VTK locator loops in Python: not run above this many points.
VTK_LOOP_LIMIT = 20_000


# --- workload and references -------------------------------------------------------------


def near_surface_points(
    points: np.ndarray, triangles: np.ndarray, k: int, spread: float, seed: int = 0
) -> np.ndarray:
    """``k`` random points within ``spread`` of the surface (area-weighted facets)."""
    rng = np.random.default_rng(seed)
    x = points[triangles]
    cross = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    area = np.linalg.norm(cross, axis=1)
    f = rng.choice(len(triangles), size=k, p=area / area.sum())
    w = rng.dirichlet(np.ones(3), size=k)
    n = cross[f] / area[f, None]
    return np.einsum("ki,kij->kj", w, x[f]) + rng.uniform(-spread, spread, (k, 1)) * n


def brute_force_closest(
    points: np.ndarray, triangles: np.ndarray, x: np.ndarray, chunk: int = 2_000_000
) -> tuple[np.ndarray, np.ndarray]:
    """Distance and closest point of every ``x`` against every facet (numpy, chunked)."""
    tri = points[triangles]
    m = len(tri)
    per = max(1, chunk // m)
    dist = np.empty(len(x))
    cp = np.empty_like(x)
    for s in range(0, len(x), per):
        q = x[s : s + per]
        qq = np.repeat(q, m, axis=0)
        t = np.tile(tri, (len(q), 1, 1))
        w = closest_on_triangles(qq, t[:, 0], t[:, 1], t[:, 2])
        p = np.einsum("ki,kij->kj", w, t)
        d = np.linalg.norm(qq - p, axis=1).reshape(len(q), m)
        j = d.argmin(axis=1)
        dist[s : s + per] = d[np.arange(len(q)), j]
        cp[s : s + per] = p.reshape(len(q), m, 3)[np.arange(len(q)), j]
    return dist, cp


def exact_winding_number(
    points: np.ndarray, triangles: np.ndarray, x: np.ndarray, chunk: int = 2_000_000
) -> np.ndarray:
    """Generalised winding number by summing every facet's solid angle (numpy, chunked)."""
    tri = points[triangles]
    m = len(tri)
    per = max(1, chunk // m)
    out = np.empty(len(x))
    for s in range(0, len(x), per):
        q = x[s : s + per]
        a, b, c = (tri[None, :, i] - q[:, None] for i in range(3))
        la, lb, lc = (np.linalg.norm(v, axis=2) for v in (a, b, c))
        det = np.einsum("qmi,qmi->qm", a, np.cross(b, c))
        den = (
            la * lb * lc
            + np.einsum("qmi,qmi->qm", a, b) * lc
            + np.einsum("qmi,qmi->qm", b, c) * la
            + np.einsum("qmi,qmi->qm", c, a) * lb
        )
        out[s : s + per] = np.arctan2(det, den).sum(axis=1) / (2 * np.pi)
    return out


def vertex_normal_points(points: np.ndarray, triangles: np.ndarray, offset: float) -> tuple:
    """The surface's nodes moved by ``+-offset`` along their normals, and whether inside."""
    n = TriangleSurface(points, triangles).vertex_normals
    used = np.unique(triangles)
    x = np.concatenate([points[used] - offset * n[used], points[used] + offset * n[used]])
    truth = np.concatenate([np.ones(len(used), bool), np.zeros(len(used), bool)])
    return x, truth


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


# --- the benchmark ------------------------------------------------------------------------


def _skin(resolution: str) -> tuple[np.ndarray, np.ndarray]:
    from contact import load_hand
    from contact.geometry.surfaces import surface_arrays

    v, f = surface_arrays(load_hand(resolution).skin)
    return np.ascontiguousarray(v), np.ascontiguousarray(f)


def _accuracy(cand: Candidate, result: Any, ref: dict, n: int, scale: float) -> dict:
    """Errors of a candidate's answers on the first ``n`` points against the references."""
    if cand.kind == "closest":
        dist, point = result
        err_d = np.abs(dist[:n] - ref["dist"][:n])
        err_p = np.linalg.norm(point[:n] - ref["point"][:n], axis=1)
        far = err_p > 1e-9 * scale
        return {
            "max_dist_err": float(err_d.max()),
            "max_point_err": float(err_p.max()),
            "rel_dist_err": float((err_d / np.maximum(ref["dist"][:n], 1e-300)).max()),
            "points_off": int(far.sum()),
        }
    wrong = np.asarray(result[:n]) != ref["inside"][:n]
    return {"inside_wrong": int(wrong.sum())}


def _bench_mesh(resolution: str, quick: bool) -> tuple[list[dict], list[dict]]:
    v, f = _skin(resolution)
    scale = float(np.linalg.norm(np.ptp(v, axis=0)))
    sizes = SIZES[quick]
    x_all = near_surface_points(v, f, max(sizes), SPREAD, seed=1)
    n_ref = min(N_REF[quick], len(x_all))
    t0 = time.perf_counter()
    rd, rp = brute_force_closest(v, f, x_all[:n_ref])
    wn = exact_winding_number(v, f, x_all[:n_ref])
    ref = {"dist": rd, "point": rp, "inside": wn > 0.5}
    t_ref = time.perf_counter() - t0
    print(
        f"[queries] {resolution}: {len(v):,} nodes, {len(f):,} facets; brute-force reference "
        f"on {n_ref} points in {t_ref:.1f} s (winding numbers within "
        f"{np.abs(np.abs(wn - 0.5) - 0.5).max():.1e} of 0 or 1)",
        flush=True,
    )
    rows: list[dict] = []
    robust: list[dict] = []
    probes = {off: vertex_normal_points(v, f, off) for off in OFFSETS}
    for cand in CANDIDATES:
        if not cand.available:
            rows.append(
                {"skin": resolution, "facets": len(f), "library": cand.name, "query": cand.kind,
                 "dist": cand.dist, "note": f"not installed ({cand.package})"}
            )  # fmt: skip
            continue
        b = measure(lambda c=cand: c.build(v, f), 5, BUDGET[quick])
        state = b.result
        for k in sizes:
            row: dict[str, Any] = {
                "skin": resolution, "facets": len(f), "library": cand.name, "query": cand.kind,
                "dist": cand.dist, "version": _version(cand.dist), "precision": cand.precision,
                "points": k, "build_s": b.best,
            }  # fmt: skip
            if cand.limit is not None and k > cand.limit:
                row["note"] = f"not run above {cand.limit:,} points (Python loop)"
                rows.append(row)
                continue
            x = np.ascontiguousarray(x_all[:k])
            q = measure(lambda c=cand, s=state, x=x: c.query(s, v, f, x), 5, BUDGET[quick])
            row.update(
                query_s=q.best,
                us_per_point=q.best / k * 1e6,
                total_s=b.best + q.best,
                runs=q.n,
            )
            row.update(_accuracy(cand, q.result, ref, min(n_ref, k), scale))
            rows.append(row)
            print(
                f"[queries] {resolution:6s} {cand.name:38s} k={k:>7,} build "
                f"{b.best * 1e3:8.2f} ms  query {q.best * 1e3:9.2f} ms",
                flush=True,
            )
            del q
        if cand.kind == "inside":
            out = {"skin": resolution, "library": cand.name, "precision": cand.precision}
            for off, (xp, truth) in probes.items():
                got = np.asarray(cand.query(state, v, f, xp))
                out[f"wrong_{off:g}"] = int((got != truth).sum())
                out["probes"] = len(truth)
            robust.append(out)
        del state, b
    return rows, robust


COLUMNS = (
    Column("skin", "skin"),
    Column("facets", "facets", ","),
    Column("library", "library"),
    Column("precision", "precision"),
    Column("points", "points", ","),
    Column("build_s", "build (ms)", ".2f"),
    Column("query_s", "query (ms)", ".2f"),
    Column("us_per_point", "query µs/point", ".2f"),
    Column("max_point_err", "max point err (m)", ".1e"),
    Column("rel_dist_err", "max rel. dist err", ".1e"),
    Column("points_off", "points off (>1e-9 diag)", "d"),
    Column("inside_wrong", "inside wrong", "d"),
    Column("note", "note"),
)

CSV_KEYS = (
    "skin", "facets", "library", "query", "dist", "version", "precision", "points", "build_s",
    "query_s", "us_per_point", "total_s", "runs", "max_dist_err", "max_point_err",
    "rel_dist_err", "points_off", "inside_wrong", "note",
)  # fmt: skip


def _ms(rows: list[dict]) -> list[dict]:
    out = []
    for r in rows:
        r2 = dict(r)
        for key in ("build_s", "query_s"):
            if r2.get(key) is not None:
                r2[key] = 1e3 * r2[key]
        out.append(r2)
    return out


def _plot(path: Path, rows: list[dict], skin: str) -> None:
    """Build + query time against the number of points, closest point and inside apart."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(13, 5.5))
    markers = "osD^vP*X<>h"
    for ax, kind in zip(axes, ("closest", "inside")):
        cands = [c for c in CANDIDATES if c.kind == kind]
        for i, cand in enumerate(cands):
            rk = [
                r
                for r in rows
                if r["library"] == cand.name and r["skin"] == skin and r.get("query_s")
            ]
            if rk:
                ax.loglog(
                    [r["points"] for r in rk],
                    [r["total_s"] for r in rk],
                    marker=markers[i % len(markers)],
                    color=plt.cm.tab10(i % 10),
                    linestyle="-" if cand.precision == "float64" else "--",
                    label=f"{cand.name} ({cand.precision})",
                )
        ax.set_xlabel("query points")
        ax.set_ylabel("build + query (s)")
        ax.set_title(f"{'Closest point' if kind == 'closest' else 'Inside'}, {skin} skin")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run(quick: bool = False, out: str | Path | None = None) -> list[dict]:
    """Run the query benchmark and write ``queries.{csv,md,png}``.

    Parameters
    ----------
    quick : bool
        The coarse skin and 300 points only: a few seconds.
    out : path, optional
        Results folder; ``benchmarks/results`` (``.../quick`` for quick runs) by default.

    Returns
    -------
    list of dict
        One row per skin, library, query and size.
    """
    folder = results_dir(out, quick)
    info = machine_info()
    for c in CANDIDATES:
        info.setdefault(c.dist, _version(c.dist))
    rows: list[dict] = []
    robust: list[dict] = []
    for res in RESOLUTIONS[quick]:
        r, rb = _bench_mesh(res, quick)
        rows += r
        robust += rb
    info["load average at end"] = load_average()
    write_csv(folder / "queries.csv", rows, CSV_KEYS)
    sections = []
    for kind, title in (("closest", "Closest point"), ("inside", "Inside test")):
        rk = [r for r in rows if r["query"] == kind]
        cols = [c for c in COLUMNS if kind == "closest" or c.key != "max_point_err"]
        cols = [
            c
            for c in cols
            if not (kind == "inside" and c.key in ("rel_dist_err", "points_off"))
            and not (kind == "closest" and c.key == "inside_wrong")
        ]
        sections.append(
            (
                title + (" (quick: tiny sizes, not representative)" if quick else ""),
                markdown_table(_ms(rk), cols),
            )
        )
    rcols = [Column("skin", "skin"), Column("library", "library"), Column("probes", "probes", ",")]
    rcols += [Column(f"wrong_{o:g}", f"wrong at ±{o:g} m", "d") for o in OFFSETS]
    sections.append(
        (
            "Inside robustness: skin nodes moved along their normals",
            markdown_table(robust, rcols)
            + "\n\nEvery node of the skin moved inward and outward along its angle-weighted "
            "normal; the answer is known. Ray-parity methods fail where a ray grazes an "
            "edge or a vertex.",
        )
    )
    sections.append(("The candidates", CANDIDATES_NOTE))
    sections.append(
        (
            "How it was measured",
            "Build: the search structure from the coordinates (the skin moves every contact "
            "iteration, so it is rebuilt each time). Query: the best of up to 5 calls within "
            f"{BUDGET[quick]:g} s. Points: random points of random facets (area-weighted) "
            f"moved along the facet normal by up to ±{SPREAD * 1e3:g} mm. Errors on the first "
            f"{N_REF[quick]:,} points against a brute-force numpy reference (every facet; "
            "exact winding number by solid angles). Timings on a shared 2-core machine: "
            "see the load averages.",
        )
    )
    write_markdown(folder / "queries.md", "Contact queries on the hand skin", info, sections)
    _plot(folder / "queries.png", rows, RESOLUTIONS[quick][-1])
    return rows
