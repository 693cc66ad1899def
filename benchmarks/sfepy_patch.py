"""Hertz against SfePy on graded tetrahedral octants: the same press, accuracy and time.

The scene of :mod:`benchmarks.patch`: the octant ``x, y >= 0, z <= R`` of an elastic ball
(R = 1 m, E = 1 Pa, nu = 0.3) filled with tetrahedra by fTetWild under a sizing field
(fine at the pole, 20+ cells across the contact radius on the finest mesh), zero normal
displacement on the three cut planes, the table ``z = 0`` advanced by ``d``. Ours is
patch's press (:class:`~contact.solver.ElasticBody` with ``bbar=False``,
:func:`~contact.cases.solve_rigid_contact`); SfePy's is the penalty contact of
:mod:`benchmarks.sfepy_hertz` (:func:`~benchmarks.sfepy_hertz_problem.solve_sfepy_press`:
``dw_lin_elastic`` + ``dw_contact_plane``, ``nls.newton``, ``ls.pypardiso``) on the very
same mesh (cell type ``3_4``) and the same prescribed DOFs. On linear tetrahedra both codes
have the same discrete model, so the contact treatment alone tells them apart.

Both are measured alike: :func:`~contact.cases.hertz.measure_contact_patch` on the nodal
reactions of the contact nodes (``fraction=0.25``, ``edge_cells=2.0``, as patch measures
ours), contact radius and peak pressure against Hertz for each code's own force. SfePy's
penalty ``k`` is swept (:data:`PENALTIES`, in units of E / R). A SfePy run has *the same
accuracy* as ours when both its errors are within ours plus
:data:`SAME_ACCURACY_PP` percentage points (in magnitude) and its Newton solve converged;
the verdict on each mesh is our time over SfePy's fastest such run (goal
:data:`GOAL_TIME_RATIO`), or, where none has it, over its most accurate run.

Times as in :mod:`benchmarks.sfepy_hertz`: ours is assembly + factorisation + contact
solve, best of :data:`REPEAT`; SfePy's is mesh arrays to problem + Newton, its fastest run
at the same accuracy best of two, the rest of the sweep once; the repeats come after the
sweep, so both codes sample the machine's load alike. On the largest mesh a Newton step
costs seconds and a stiff penalty takes tens of steps, so there the sweep starts at the
softest penalty that had the same accuracy on the mesh before and stiffens only until a
run has it; after the first, a run (or the repeat) predicted to take SfePy's time on that
mesh past :data:`LARGEST_BUDGET_S` is left out and said so.

The meshes come from patch's cache (:data:`benchmarks.patch.MESHES`; fTetWild takes
minutes on the largest). SfePy is an optional extra (``pip install .[benchmarks]``);
without it the study writes a note and returns no rows. The accuracy rule, the verdict
and the table's columns are in :mod:`benchmarks.sfepy_patch_report`.

Run it with ``python -m benchmarks.sfepy_patch [--quick] [--out DIR]``.
"""

from __future__ import annotations

import argparse
import gc
import math
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

import fem
from contact.cases.hertz import hertz_sphere_on_plane, measure_contact_patch
from contact.geometry import Plane
from contact.solver import ElasticBody

from ._common import (
    load_average,
    machine_info,
    markdown_table,
    plot_loglog,
    results_dir,
    write_csv,
    write_markdown,
)
from .patch import NU, RADIUS, E, _press, mesh_of
from .sfepy_hertz import load1, sfepy_times
from .sfepy_hertz_problem import (
    CONTACT_ORDER,
    sfepy_available,
    sfepy_version,
    solve_sfepy_press,
)
from .sfepy_hertz_report import sfepy_missing
from .sfepy_patch_report import (
    COLUMNS,
    CSV_KEYS,
    GOAL_TIME_RATIO,
    SAME_ACCURACY_PP,
    _fastest,
    same_accuracy,
    verdicts,
)

__all__ = [
    "DEPTHS",
    "GOAL_TIME_RATIO",
    "LARGEST_BUDGET_S",
    "NEWTON_LIMIT",
    "PENALTIES",
    "REPEAT",
    "SAME_ACCURACY_PP",
    "SIZES",
    "STEP_GROWTH",
    "run",
    "same_accuracy",
    "verdicts",
]

#: Edge lengths at the pole (m) of patch's cached octants: about 17k, 47k and 120k DOFs;
#: ``--quick`` the coarsest (about 2k DOFs).
SIZES: dict[bool, tuple[float, ...]] = {False: (0.011, 0.0065, 0.0047), True: (0.04,)}
#: Table advances d / R on each mesh (the smallest mesh also the deeper press).
DEPTHS: dict[float, tuple[float, ...]] = {
    0.04: (0.01,),
    0.011: (0.01, 0.02),
    0.0065: (0.01,),
    0.0047: (0.01,),
}
#: Penalty stiffnesses of SfePy's contact plane (Pa/m, in units of E / R = 1): the hex
#: study's and 3e3, for where 1e3's sinking in (``p / k``) costs more than the margin and
#: 1e4 takes several times the Newton steps.
PENALTIES: tuple[float, ...] = (1e3, 3e3, 1e4, 1e5)
#: Our solve is timed as the best of this many runs (one with ``--quick``).
REPEAT = 3
#: SfePy's seconds on the largest mesh (the sweep and its repeat) are kept under this.
LARGEST_BUDGET_S = 360.0
#: Newton's limit on SfePy's steps.
NEWTON_LIMIT = 50
#: Growth of SfePy's seconds per Newton step with the DOFs (a tangent assembly and a
#: PARDISO factorisation each): predicts the first run on the largest mesh.
STEP_GROWTH = 1.3


def _measured(
    mesh: fem.Mesh, contact_force: np.ndarray, plane: Plane, ours_force: float | None
) -> dict[str, Any]:
    """Patch, Hertz errors and force of one solution's nodal contact forces, as patch
    measures ours (:func:`measure_contact_patch` reads only ``contact_force``)."""
    forces = SimpleNamespace(contact_force=contact_force)
    patch = measure_contact_patch(
        mesh,
        forces,  # type: ignore[arg-type]
        plane,
        center=np.zeros(3),
        fraction=0.25,
        edge_cells=2.0,
    )
    hz = hertz_sphere_on_plane(patch.force, RADIUS, E, NU)
    return {
        "contacts": len(patch.nodes),
        "force": patch.force,
        "force_vs_ours_pct": 0.0 if ours_force is None else 100 * (patch.force / ours_force - 1),
        "radius_err_pct": 100 * (patch.contact_radius / hz.contact_radius - 1),
        "pressure_err_pct": 100 * (patch.peak_pressure / hz.peak_pressure - 1),
    }


def _ours(mesh: fem.Mesh, h: float, depth: float) -> tuple[ElasticBody, Plane, dict[str, Any]]:
    """Our press of one mesh, timed once: the body, the table and the row."""
    body, planes, secs, res = _press(mesh, depth)
    row = {
        "fine_size": h,
        "dofs": mesh.n_dofs,
        "depth": depth,
        "cells_per_a": math.sqrt(depth) * RADIUS / h,
        "code": "ours",
        "iterations": res.iterations,
        "converged": "yes" if res.converged else "no",
        "total_s": secs["assemble"] + secs["solve"],
        "assemble_s": secs["assemble"],
        "factor_s": body.solver.factor_time,
        "runs": 1,
        "load1": load1(),
        "load": load_average(),
        "ours_over_this": 1.0,
    }
    row.update(_measured(mesh, res.contact_force, planes[0], None))
    return body, planes[0], row


def _ours_again(mesh: fem.Mesh, row: dict[str, Any]) -> None:
    """One more timed press of ours; the row keeps the fastest."""
    body, _planes, secs, _res = _press(mesh, row["depth"])
    t = secs["assemble"] + secs["solve"]
    row["runs"] += 1
    if t < row["total_s"]:
        row.update(
            total_s=t,
            assemble_s=secs["assemble"],
            factor_s=body.solver.factor_time,
            load1=load1(),
            load=load_average(),
        )


def _theirs(
    mesh: fem.Mesh, body: ElasticBody, plane: Plane, ours: dict[str, Any], k: float
) -> dict[str, Any]:
    """SfePy's press of the same mesh and DOFs with the penalty ``k``, timed once."""
    res = solve_sfepy_press(mesh, body, plane, k, radius=RADIUS, max_iterations=NEWTON_LIMIT)
    row = {key: ours[key] for key in ("fine_size", "dofs", "depth", "cells_per_a")}
    row.update(
        code="SfePy",
        penalty=k,
        iterations=res.iterations,
        converged="yes" if res.converged else "no",
        equilibrium=res.equilibrium,
        runs=1,
    )
    row.update(_measured(mesh, res.contact_force, plane, ours["force"]))
    row["same_accuracy"] = "yes" if same_accuracy(row, ours) else "no"
    sfepy_times(row, res)
    row["load"] = load_average()
    return row


def _theirs_again(mesh: fem.Mesh, body: ElasticBody, plane: Plane, row: dict[str, Any]) -> None:
    """One more timed SfePy run; the row keeps the fastest."""
    res = solve_sfepy_press(
        mesh, body, plane, row["penalty"], radius=RADIUS, max_iterations=NEWTON_LIMIT
    )
    row["runs"] += 1
    if res.seconds["total"] < row["total_s"]:
        sfepy_times(row, res)
        row["load"] = load_average()


def _penalties(largest: bool, before: list[dict]) -> list[float]:
    """The penalties to run: all, or on the largest mesh from the softest that had the same
    accuracy on the mesh before on (a softer one's error, ``p / k`` of sinking in, does not
    shrink with the cells while ours does), soft to stiff."""
    if not largest:
        return list(PENALTIES)
    same = [r["penalty"] for r in before if r.get("same_accuracy") == "yes"]
    start = min(same) if same else PENALTIES[0]
    return [k for k in PENALTIES if k >= start]


def _per_step(rows: list[dict]) -> float:
    """SfePy's mean seconds per Newton step over ``rows`` (NaN without SfePy rows)."""
    theirs = [r for r in rows if r["code"] == "SfePy"]
    steps = sum(r["iterations"] for r in theirs)
    return sum(r["total_s"] for r in theirs) / steps if steps else math.nan


def _guess(k: float, dofs: int, rows: list[dict], before: list[dict]) -> float:
    """Predicted seconds of SfePy's run with penalty ``k``: its Newton steps on the mesh
    before (Newton's limit if it did not run there), times the seconds per step on this
    mesh (or on the one before, scaled by DOFs^STEP_GROWTH); 0 when nothing is known."""
    prev = [r for r in before if r.get("penalty") == k]
    steps = prev[0]["iterations"] if prev else NEWTON_LIMIT
    per_step = _per_step(rows)
    if math.isnan(per_step) and before:
        per_step = _per_step(before) * (dofs / before[0]["dofs"]) ** STEP_GROWTH
    return 0.0 if math.isnan(per_step) else per_step * steps


def _press_both(
    mesh: fem.Mesh, h: float, depth: float, largest: bool, before: list[dict], repeat: int
) -> tuple[list[dict], list[str]]:
    """Ours and SfePy's sweep on one mesh and press: the rows and notes on runs left out."""
    gc.collect()
    body, plane, ours = _ours(mesh, h, depth)
    rows, notes, spent = [ours], [], 0.0
    for k in _penalties(largest, before):
        if largest:
            if _fastest(rows, ours) is not None:
                break  # a stiffer penalty only takes more Newton steps
            guess = _guess(k, mesh.n_dofs, rows, before)
            if len(rows) > 1 and spent + guess > LARGEST_BUDGET_S:
                notes.append(
                    f"{mesh.n_dofs:,} DOFs: SfePy k = {k:.0e} (predicted {guess:.0f} s, "
                    f"{spent:.0f} s spent, budget {LARGEST_BUDGET_S:.0f} s)"
                )
                continue
        row = _theirs(mesh, body, plane, ours, k)
        spent += row["total_s"]
        rows.append(row)
        print(
            f"[sfepy_patch] {row['dofs']:>8,} DOFs d/R {depth:g} SfePy k={k:.0e}: radius "
            f"{row['radius_err_pct']:+.2f} %, peak p {row['pressure_err_pct']:+.2f} %, force "
            f"{row['force_vs_ours_pct']:+.3f} % vs ours, {row['iterations']} Newton "
            f"({row['converged']}), {row['total_s']:.2f} s",
            flush=True,
        )
    for _ in range(repeat - 1):
        _ours_again(mesh, ours)
    best = _fastest(rows, ours)
    if repeat > 1 and best is not None:
        if largest and spent + best["total_s"] > LARGEST_BUDGET_S:
            notes.append(f"{mesh.n_dofs:,} DOFs: SfePy's repeat of k = {best['penalty']:.0e}")
        else:
            _theirs_again(mesh, body, plane, best)
    for r in rows[1:]:
        r["ours_over_this"] = ours["total_s"] / r["total_s"]
    print(
        f"[sfepy_patch] {ours['dofs']:>8,} DOFs d/R {depth:g} ours: radius "
        f"{ours['radius_err_pct']:+.2f} %, peak p {ours['pressure_err_pct']:+.2f} %, "
        f"{ours['total_s']:.2f} s (best of {ours['runs']}), load {ours['load']}",
        flush=True,
    )
    return rows, notes


def _warm_up(mesh: fem.Mesh) -> None:
    """One untimed press of each code on a small mesh: first-call costs (imports, SfePy's
    caches, MKL's start) stay out of the timings."""
    body, planes, _secs, _res = _press(mesh, 0.01)
    solve_sfepy_press(mesh, body, planes[0], PENALTIES[0], radius=RADIUS)
    gc.collect()


def run(quick: bool = False, out: str | Path | None = None) -> list[dict]:
    """Press the graded tetrahedral octants with ours and SfePy's; write ``sfepy_patch.*``.

    Parameters
    ----------
    quick : bool
        The coarsest mesh, one press (seconds once the mesh is cached).
    out : path, optional
        Results folder; ``benchmarks/results`` (``.../quick`` for quick runs) by default.

    Returns
    -------
    list of dict
        One row per code, penalty, mesh and press; empty (and a note written) without SfePy.
    """
    folder = results_dir(out, quick)
    if not sfepy_available():
        print("[sfepy_patch] SfePy is not installed: skipped", flush=True)
        return sfepy_missing(
            folder, "sfepy_patch", "Hertz against SfePy on graded tetrahedral octants"
        )
    info = machine_info()
    info["sfepy"] = sfepy_version()
    info["sfepy solvers"] = "nls.newton (ls_on 2), ls.pypardiso (MKL PARDISO)"
    repeat = 1 if quick else REPEAT
    sizes = SIZES[quick]
    _warm_up(mesh_of(SIZES[True][0])[0])
    rows: list[dict] = []
    notes: list[str] = []
    made: list[str] = []
    before: list[dict] = []
    for h in sizes:
        mesh, secs = mesh_of(h)
        made.append(
            f"h = {h:g}: {mesh.n_dofs:,} DOFs, {len(mesh.cells['tetra']):,} tetrahedra"
            + ("" if math.isnan(secs) else f" (fTetWild {secs:.0f} s)")
        )
        largest = not quick and h == sizes[-1]
        for depth in DEPTHS.get(h, (0.01,)):
            got, left = _press_both(mesh, h, depth, largest, before, repeat)
            rows += got
            notes += left
            if depth == 0.01:
                before = got
        del mesh
        gc.collect()

    write_csv(folder / "sfepy_patch.csv", rows, CSV_KEYS)
    lines, met = verdicts(rows)
    status = {True: "met", False: "missed", None: "not judged"}[met]
    text = (
        "Octant of a ball (R = 1, E = 1, nu = 0.3) on fTetWild tetrahedra graded by a sizing "
        "field (benchmarks.patch's cached meshes: " + "; ".join(made) + "), symmetry "
        "rollers on the three cut planes, the table advanced by d. Ours: `ElasticBody` "
        "(`bbar=False`) + `solve_rigid_contact`, iterations = contact-set updates. SfePy: the "
        "same mesh (`3_4`) and prescribed DOFs, `dw_lin_elastic` + `dw_contact_plane` "
        f"(linear penalty `k d`, integral order {CONTACT_ORDER} on the faces), `nls.newton` "
        f"(`ls_on = 2`, eps_r 1e-10, at most {NEWTON_LIMIT} steps), `ls.pypardiso`; "
        "iterations = Newton steps. Errors against Hertz for each code's own force, measured alike "
        "(`measure_contact_patch` on the nodal reactions of the contact nodes, fraction "
        "0.25, edge_cells 2). 'same accuracy': converged, both errors within ours + "
        f"{SAME_ACCURACY_PP} points. Times: ours = assemble + factor + contact solve, best "
        f"of {repeat}; SfePy = mesh arrays to problem + Newton, its fastest run at the same "
        "accuracy best of 2, the rest once. The machine is shared: see the load column."
    )
    if notes:
        text += "\n\nLeft out (SfePy's time budget on the largest mesh): " + "; ".join(notes) + "."
    goal = (
        f"Ours in at most {GOAL_TIME_RATIO:g} of SfePy's time at the same accuracy, on each "
        f"mesh: **{status}**.\n\n" + "\n".join(lines)
    )
    write_markdown(
        folder / "sfepy_patch.md",
        "Hertz against SfePy on graded tetrahedral octants: accuracy and time",
        info,
        [("Runs", text + "\n\n" + markdown_table(rows, COLUMNS)), ("Goal", goal)],
    )
    ours = [r for r in rows if r["code"] == "ours" and r["depth"] == 0.01]
    series = {"ours": ([r["dofs"] for r in ours], [r["total_s"] for r in ours])}
    for k in PENALTIES:
        rs = [r for r in rows if r.get("penalty") == k and r["depth"] == 0.01]
        series[f"SfePy k={k:.0e}"] = ([r["dofs"] for r in rs], [r["total_s"] for r in rs])
    plot_loglog(folder / "sfepy_patch.png", series, title="Hertz on graded tetrahedra, d/R 0.01")
    return rows


def main(argv: list[str] | None = None) -> None:
    """Command line: ``python -m benchmarks.sfepy_patch [--quick] [--out DIR]``."""
    ap = argparse.ArgumentParser(prog="python -m benchmarks.sfepy_patch", description=__doc__)
    ap.add_argument("--quick", action="store_true", help="the coarsest mesh: seconds")
    ap.add_argument("--out", help="results folder")
    args = ap.parse_args(argv)
    run(quick=args.quick, out=args.out)


if __name__ == "__main__":
    main()
