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

import time
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
from .queries_candidates import CANDIDATES, CANDIDATES_NOTE, Candidate
from .queries_report import COLUMNS, CSV_KEYS, _ms, _plot

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
