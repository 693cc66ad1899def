"""How the contact phase's cost grows with the contact patch, on graded tetrahedral octants.

The scene of :mod:`benchmarks.hertz` on another mesher's mesh: the octant ``x, y >= 0,
z <= R`` of an elastic ball (R = 1 m, E = 1 Pa, nu = 0.3, centre ``(0, 0, R)``) filled with
tetrahedra by fTetWild under a sizing field (:func:`fem.graded_tets.graded_tet_octant`:
fine within 0.2 R of the pole, growing linearly to R / 5), zero normal displacement on the
three cut planes, the table ``z = 0`` advanced by ``d`` along z, through
:class:`~contact.solver.ElasticBody` (``bbar=False``) and
:func:`~contact.cases.solve_rigid_contact`. Three meshes, ``d/R`` in 0.005, 0.01, 0.02.

Per run: assembly (the body's construction), factorisation (``body.solver.factor_time``,
done lazily inside the contact solve once the zone is marked), the contact phase (the
contact solve's wall time less the factorisation), updates of the contact set, contact
rows (contact nodes at the end), back-solves and partial solves; against "factor + solve"
(one fresh factorisation and solve of the body, :func:`benchmarks.frame.plain_seconds`).
Accuracy against Hertz for the solver's own force (contact radius, peak pressure:
:func:`~contact.cases.hertz.measure_contact_patch`) and the force against Hertz's for the
approach ``d``. Then the log-log slope of the contact phase against the contact rows and
a cProfile of the largest run's contact solve. For the slope, layered octants too
(:data:`LAYERED`: fine in a surface layer only), whose patches reach about 6,000 rows on
a few 10k DOFs.

fTetWild takes minutes on the largest graded mesh, a quarter of an hour or more on the
finer layered ones (their envelope is tight), and differs from run to run: the meshes
are cached as VTU files in the temporary folder (:data:`MESHES`), keyed by their
parameters, and never committed. Run ``python -m benchmarks.patch [--quick]``.
"""

from __future__ import annotations

import argparse
import cProfile
import gc
import io
import math
import pstats
import tempfile
import time
from pathlib import Path

import numpy as np

import fem
from contact.cases import solve_rigid_contact
from contact.cases.hertz import hertz_sphere_on_plane, measure_contact_patch
from contact.geometry import Plane
from contact.solver import ElasticBody
from fem.graded_tets import graded_tet_octant

from ._common import (
    Column,
    load_average,
    machine_info,
    markdown_table,
    plot_loglog,
    results_dir,
    write_csv,
    write_markdown,
)
from .frame import plain_seconds

__all__ = ["DEPTHS", "FRAME_GOAL", "GOAL", "SIZES", "mesh_of", "run", "run_case"]

RADIUS, E, NU = 1.0, 1.0, 0.3
#: Radius of the uniformly fine zone about the pole: 1.3 a at the largest press.
FINE_RADIUS = 0.2
#: Table advances d / R.
DEPTHS: dict[bool, tuple[float, ...]] = {False: (0.005, 0.01, 0.02), True: (0.01,)}
#: Edge lengths at the pole (m): about 5k, 17k, 47k and 120k DOFs; ``--quick`` one coarse mesh.
SIZES: dict[bool, tuple[float, ...]] = {False: (0.02, 0.011, 0.0065, 0.0047), True: (0.04,)}
#: Layered octants for the growth study: fine only in a surface layer about the pole (the
#: size grows by ``LAYER_GROWTH - 1`` per unit of depth), so that a few 10k DOFs carry up
#: to about 6,000 contact rows at d/R ``LAYER_DEPTHS``. Not part of the goals: there the
#: patch is a large part of the mesh.
LAYERED: dict[bool, tuple[float, ...]] = {False: (0.006, 0.003, 0.0022), True: ()}
LAYER_FINE_RADIUS = 0.22
LAYER_GROWTH = 1.3
#: Edge length at the pole of the surface handed to fTetWild (it refines it).
LAYER_SURFACE = 0.012
LAYER_DEPTHS = (0.01, 0.02, 0.03)
#: The goal of the contact phase: at most this multiple of assembly + factorisation.
GOAL = 1.0
#: The goal of the whole frame: at most this multiple of one factorisation and solve.
FRAME_GOAL = 2.0

#: Presses quicker than this (s) are timed ``REPEAT`` times, the fastest kept.
QUICK_PRESS = 1.0
REPEAT = 3

#: Bands of contact rows over which the growth study fits a slope too.
SLOPE_BANDS = ((100, 1000), (1000, 5000), (100, 5000))

#: Cache of the generated meshes (VTU, megabytes each: kept out of the repository).
MESHES = Path(tempfile.gettempdir()) / "fem-benchmark-patch-meshes"

COLUMNS = (
    Column("mesh", "mesh"),
    Column("dofs", "DOFs", ","),
    Column("fine_size", "h pole (m)", ".4f"),
    Column("depth", "d/R", ".3f"),
    Column("cells_per_a", "cells per a", ".1f"),
    Column("updates", "updates", "d"),
    Column("rows", "contact rows", ","),
    Column("back_solves", "back-solves", ","),
    Column("partial_solves", "partial solves", ","),
    Column("assemble_s", "assemble (s)", ".2f"),
    Column("factor_s", "factor (s)", ".2f"),
    Column("contact_s", "contact (s)", ".2f"),
    Column("contact_over_factor", "contact / (assemble + factor)", ".2f"),
    Column("frame_s", "frame (s)", ".2f"),
    Column("plain_s", "factor + solve (s)", ".2f"),
    Column("frame_over_plain", "frame / (factor + solve)", ".2f"),
    Column("radius_err_pct", "radius err (%)", "+.2f"),
    Column("pressure_err_pct", "peak p err (%)", "+.2f"),
    Column("force_err_pct", "force vs Hertz(d) (%)", "+.2f"),
    Column("met", "contact <= factor"),
)


def mesh_of(
    fine_size: float, folder: Path = MESHES, layered: bool = False
) -> tuple[fem.Mesh, float]:
    """The graded (or ``layered``) octant for ``fine_size``, from the cache or made now.

    Returns
    -------
    mesh : fem.Mesh
    seconds : float
        fTetWild's time when made now, NaN when read from the cache.
    """
    folder.mkdir(parents=True, exist_ok=True)
    fr = LAYER_FINE_RADIUS if layered else FINE_RADIUS
    tag = f"_layer{LAYER_GROWTH:g}_s{LAYER_SURFACE:g}" if layered else ""
    path = folder / f"octant_R{RADIUS:g}_h{fine_size:g}_fr{fr:g}{tag}.vtu"
    if path.exists():
        return fem.read_mesh(path), math.nan
    t = time.perf_counter()
    if layered:  # an envelope well inside the fine size: the snap onto the sphere is small
        mesh = graded_tet_octant(
            RADIUS,
            fine_size,
            fr,
            depth_growth=LAYER_GROWTH,
            surface_size=max(fine_size, LAYER_SURFACE),
            center=(0.0, 0.0, RADIUS),
            epsilon=min(1e-3, float(f"{fine_size / 15:.2g}")),
        )
    else:
        mesh = graded_tet_octant(RADIUS, fine_size, fr, center=(0.0, 0.0, RADIUS))
    secs = time.perf_counter() - t
    fem.write_mesh(path, mesh)
    return mesh, secs


def _symmetry_dofs(mesh: fem.Mesh) -> np.ndarray:
    """Normal DOFs of the nodes on the cut planes x = 0, y = 0 and z = R."""
    d = mesh.points - np.array([0.0, 0.0, RADIUS])
    tol = 1e-9 * RADIUS
    return np.concatenate([3 * np.flatnonzero(np.abs(d[:, k]) <= tol) + k for k in range(3)])


def _press(
    mesh: fem.Mesh, depth: float, weighted: bool = False
) -> tuple[ElasticBody, list[Plane], dict, object]:
    """Build the body and solve the press (by ``weighted`` gaps); the times and the result."""
    gc.collect()
    t0 = time.perf_counter()
    body = ElasticBody(
        "ball", mesh, fem.LinearElastic(E, NU), prescribed=_symmetry_dofs(mesh), bbar=False
    )
    t1 = time.perf_counter()
    planes = [Plane([0, 0, 0], [0, 0, 1], motion=[0, 0, depth * RADIUS], name="table")]
    res = solve_rigid_contact(body, planes, weighted=weighted)
    t2 = time.perf_counter()
    return body, planes, {"assemble": t1 - t0, "solve": t2 - t1}, res


def run_case(
    mesh: fem.Mesh, fine_size: float, depth: float, layered: bool = False, weighted: bool = False
) -> dict:
    """One press of one mesh: a row of the study (see ``COLUMNS``), by ``weighted`` gaps.

    A press under :data:`QUICK_PRESS` seconds is timed :data:`REPEAT` times and its
    fastest run kept, as the plain factorisation and solve it is set against is.
    """
    body, planes, secs, res = _press(mesh, depth, weighted)
    if secs["assemble"] + secs["solve"] < QUICK_PRESS:
        for _ in range(REPEAT - 1):
            again = _press(mesh, depth, weighted)
            if again[2]["solve"] < secs["solve"]:
                body, planes, secs, res = again
    factor = body.solver.factor_time
    contact = secs["solve"] - factor
    plain = plain_seconds([body], repeat=REPEAT if secs["solve"] < QUICK_PRESS else 2)
    patch = measure_contact_patch(
        mesh, res, planes[0], center=np.zeros(3), fraction=0.25, edge_cells=2.0
    )
    hz = hertz_sphere_on_plane(patch.force, RADIUS, E, NU)
    e_star = E / (1 - NU**2)
    f_hertz = 4.0 / 3.0 * e_star * math.sqrt(RADIUS) * (depth * RADIUS) ** 1.5
    a_d = math.sqrt(RADIUS * depth * RADIUS)
    ratio = contact / (secs["assemble"] + factor)
    return {
        "mesh": "layered" if layered else "graded",
        "dofs": mesh.n_dofs,
        "fine_size": fine_size,
        "depth": depth,
        "cells_per_a": a_d / fine_size,
        "updates": res.iterations,
        "converged": res.converged,
        # node rows: the contact nodes; weighted: the closed rows (their forces spread
        # over each row's facets, onto more nodes)
        "rows": res.history[-1].n_contacts if weighted else len(res.contact_nodes),
        "gaps": "weighted" if weighted else "nodal",
        "back_solves": body.solver.n_back_solves,
        "partial_solves": body.solver.n_partial_solves,
        "marked": int(body.solver.marked.size),
        "assemble_s": secs["assemble"],
        "factor_s": factor,
        "contact_s": contact,
        "contact_over_factor": ratio,
        "frame_s": secs["solve"],
        "plain_s": plain,
        "frame_over_plain": secs["solve"] / plain,
        "radius_err_pct": 100 * (patch.contact_radius / hz.contact_radius - 1),
        "pressure_err_pct": 100 * (patch.peak_pressure / hz.peak_pressure - 1),
        "force_err_pct": 100 * (patch.force / f_hertz - 1),
        "met": "met" if ratio <= GOAL else "**missed**",
        "load": load_average(),
    }


def _slope(rows: list[dict]) -> tuple[float, int, int]:
    """Least-squares slope of log(contact s) against log(contact rows), and the row range."""
    r = np.array([x["rows"] for x in rows], dtype=float)
    t = np.array([x["contact_s"] for x in rows], dtype=float)
    ok = (r > 0) & (t > 0)
    if ok.sum() < 2:
        return math.nan, 0, 0
    k = np.polyfit(np.log(r[ok]), np.log(t[ok]), 1)[0]
    return float(k), int(r[ok].min()), int(r[ok].max())


def _profile(mesh: fem.Mesh, depth: float, top: int = 15, sort: str = "cumulative") -> str:
    """cProfile of one press's contact solve (body built outside): the top by ``sort``."""
    body = ElasticBody(
        "ball", mesh, fem.LinearElastic(E, NU), prescribed=_symmetry_dofs(mesh), bbar=False
    )
    planes = [Plane([0, 0, 0], [0, 0, 1], motion=[0, 0, depth * RADIUS], name="table")]
    prof = cProfile.Profile()
    prof.enable()
    res = solve_rigid_contact(body, planes)
    prof.disable()
    buf = io.StringIO()
    pstats.Stats(prof, stream=buf).strip_dirs().sort_stats(sort).print_stats(top)
    timings = ", ".join(f"{k} {v:.2f} s" for k, v in res.timings.items())
    return f"result timings: {timings}\n\n{buf.getvalue()}"


def run(quick: bool = False, out: str | Path | None = None) -> list[dict]:
    """Run the study and write ``patch.{csv,md,png}``.

    Parameters
    ----------
    quick : bool
        One coarse mesh, one press (seconds, after the mesh is cached).
    out : path, optional
        Results folder; ``benchmarks/results`` (``.../quick`` for quick runs) by default.

    Returns
    -------
    list of dict
        One row per mesh and press.
    """
    folder = results_dir(out, quick)
    info = machine_info()
    rows: list[dict] = []
    made: list[str] = []
    largest: fem.Mesh | None = None
    series = [(h, False, DEPTHS[quick]) for h in SIZES[quick]]
    series += [(h, True, LAYER_DEPTHS) for h in LAYERED[quick]]
    for h, layered, depths in series:
        mesh, secs = mesh_of(h, layered=layered)
        made.append(
            f"{'layered ' if layered else ''}h = {h:g}: {mesh.n_dofs:,} DOFs, "
            f"{len(mesh.cells['tetra']):,} tetrahedra, "
            + ("cached" if math.isnan(secs) else f"fTetWild {secs:.0f} s")
        )
        for d in depths:
            row = run_case(mesh, h, d, layered)
            rows.append(row)
            print(
                f"[patch] {row['dofs']:>8,} DOFs d/R {d}: {row['rows']} rows, "
                f"{row['updates']} updates, factor {row['factor_s']:.2f} s, contact "
                f"{row['contact_s']:.2f} s (x{row['contact_over_factor']:.2f}), radius "
                f"{row['radius_err_pct']:+.2f} %, p0 {row['pressure_err_pct']:+.2f} %, load "
                f"{row['load']}",
                flush=True,
            )
        if not layered:
            largest = mesh
    slope, r0, r1 = _slope(rows)
    graded = [r for r in rows if r["mesh"] == "graded"]
    prof = _profile(largest, max(DEPTHS[quick])) if largest is not None else ""
    # and the layered run with the most rows within the last band: the dense work
    big = [r for r in rows if r["mesh"] == "layered" and r["rows"] <= SLOPE_BANDS[-1][1]]
    big_prof = ""
    if big:
        top = max(big, key=lambda r: r["rows"])
        big_mesh = mesh_of(top["fine_size"], layered=True)[0]
        big_prof = _profile(big_mesh, top["depth"], sort="tottime")
    write_csv(folder / "patch.csv", rows, [c.key for c in COLUMNS] + ["converged", "load"])
    met = all(r["contact_over_factor"] <= GOAL for r in graded)
    notes = (
        "Octant of a ball (R = 1, E = 1, nu = 0.3) on fTetWild tetrahedra graded by a sizing "
        f"field (fine within {FINE_RADIUS} R of the pole), symmetry rollers on the three cut "
        "planes, a rigid table pressed along z, `bbar=False`. 'contact' = the contact solve's "
        "wall time less its factorisation; 'frame' = the whole contact solve (factorisation "
        "included); 'factor + solve' = one fresh factorisation and solve of the body. "
        "'contact rows' = contact nodes at the end (one normal row each). Errors against "
        "Hertz for the solver's own force; 'force vs Hertz(d)' against Hertz's force for "
        "the table advance. Layered meshes (for the growth): fine in a surface layer "
        f"within {LAYER_FINE_RADIUS} R of the pole, the size growing by "
        f"{LAYER_GROWTH - 1:g} per unit of depth. Meshes: " + "; ".join(made) + "."
    )
    verdict = (
        f"goal: contact/factor <= {GOAL:g} at every row: **{'met' if met else 'missed'}** "
        f"(largest {max(r['contact_over_factor'] for r in graded):.2f})."
    )
    over = [r for r in graded if r["frame_over_plain"] > FRAME_GOAL]
    verdict += (
        f"\n\ngoal: frame / (factor + solve) <= {FRAME_GOAL:g} at every row: "
        + ("**met**" if not over else f"**missed** on {len(over)} of {len(graded)}: ")
        + "; ".join(
            f"{r['dofs']:,} DOFs d/R {r['depth']:g}: {r['frame_over_plain']:.2f} "
            f"({r['frame_s']:.2f} s against {r['plain_s']:.2f} s, {r['back_solves']} "
            "back-solves)"
            for r in over
        )
        + f" (largest {max(r['frame_over_plain'] for r in graded):.2f})."
        + "\n\nThe goals are those of the graded meshes; the layered ones are for the growth."
    )
    bands = []
    for lo, hi in SLOPE_BANDS:
        k, b0, b1 = _slope([r for r in rows if lo <= r["rows"] <= hi])
        bands.append(f"{lo:,} to {hi:,} rows ({b0:,} to {b1:,}): **{k:.2f}**")
    growth = (
        "Log-log slope of the contact phase's time against the contact rows (least "
        f"squares), over all runs ({r0:,} to {r1:,} rows): **{slope:.2f}**; over "
        + "; ".join(bands)
        + ". Rows past the marks' capacity (fem.statics.MARK_LIMIT DOFs) cost a back-solve "
        "each."
    )
    sections = [
        ("Runs", notes + "\n\n" + markdown_table(rows, COLUMNS)),
        ("Goal", verdict),
        ("Growth with the contact rows", growth),
        ("Profile of the largest run's contact solve", "```\n" + prof + "\n```"),
    ]
    if big_prof:
        title = "Profile of the layered run with the most rows in the last band (by own time)"
        sections.append((title, "```\n" + big_prof + "\n```"))
    write_markdown(
        folder / "patch.md",
        "Contact phase against the contact patch: graded tetrahedral octants",
        info,
        sections,
    )
    plot_loglog(
        folder / "patch.png",
        {
            "contact phase": ([r["rows"] for r in rows], [r["contact_s"] for r in rows]),
            "assemble + factor": (
                [r["rows"] for r in rows],
                [r["assemble_s"] + r["factor_s"] for r in rows],
            ),
        },
        title="Contact phase against contact rows",
        xlabel="contact rows",
    )
    return rows


def main(argv: list[str] | None = None) -> None:
    """Command line: ``python -m benchmarks.patch [--quick] [--out DIR]``."""
    ap = argparse.ArgumentParser(prog="python -m benchmarks.patch", description=__doc__)
    ap.add_argument("--quick", action="store_true", help="one coarse mesh: seconds")
    ap.add_argument("--out", help="results folder")
    args = ap.parse_args(argv)
    run(quick=args.quick, out=args.out)


if __name__ == "__main__":
    main()
