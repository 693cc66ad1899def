"""The contact iteration: convergence histories and iteration counts of both algorithms.

Two scenes, both with two deformable bodies:

``"hand cup"``
    The hand at rest pressed by a free ball that a rising cup of four rigid planes holds
    (:func:`benchmarks.scenes.hand_cup`): flesh ``E = 100 kPa``, the ball ``ratio``
    times stiffer, the cup raised by ``press`` (5 mm unless said otherwise); node to
    surface pairs both ways between ball and hand.
``"sphere-block"``
    Hertz's sphere (R = 1 m, quarter model) pressed 0.01 m into an elastic block
    (:func:`contact.cases.hertz_bodies.hertz_scene`), the sphere ``ratio`` times stiffer than
    the block, graded hex meshes of ``fine_size`` cells at the contact.

Algorithms (:func:`contact.solver.iteration.solve_frame`): ``"contact-space"`` (contact-set
updates, each solved exactly with both bodies' compliance) and the Dirichlet-Neumann loop of
Gourret, Magnenat-Thalmann and Thalmann (1989) with each relaxation of its Neumann side
(none, a fixed factor 0.5, Aitken's). The seed loop's Dirichlet body is the ball (the
sphere): in the hand cup it must be, since the cup's planes touch only the ball. On the
Hertz scene the seed loop runs with the sphere's nodes against the block only (one way), as
with pairs both ways it diverges on its first iteration (rows met node to node prescribe the
sphere twice: one variant shows it); one more variant makes the softer body the Dirichlet
one.

Studies:

1. *histories and the stiffness ratio*: every variant at ``E_ball / E_other`` 0.01 to 100
   on both scenes; the largest change of a nodal displacement per iteration (CSV
   ``iteration_history.csv``, plot ``iteration.png``) and the iterations, stop reason,
   back-solves, time, force and penetration of each frame (``iteration.csv``);
2. *mesh refinement*: contact space on three meshes of each scene at ratios 0.01, 1 and
   100 (goal: iterations within +-30 % over the three);
3. *press depth*: contact space and the seed loop (Aitken) on the hand cup at several
   depths.

Goals (from the issue): contact iterations over three refinements within +-30 %, and at
most 10 contact-set updates over E ratios 0.01 to 100. Run with ``python -m benchmarks
iteration`` (or ``python -m benchmarks.iteration``), ``--quick`` for a smoke test.
"""

from __future__ import annotations

import argparse
import gc
import hashlib
import math
import subprocess
import time
from pathlib import Path

import contact

from ._common import load_average, machine_info, results_dir, write_csv
from .iteration_cases import (
    CONTACT_SPACE,
    CUP_LEVELS,
    GOAL_REFINEMENT,
    GOAL_UPDATES,
    HERTZ_SIZES,
    PRESSES,
    RATIOS,
    SCENES,
    Case,
    Variant,
    _cases,
    solve_case,
    variants,
)
from .iteration_plots import _plot_counts, _plot_histories
from .iteration_report import _goals, _write_report

__all__ = [
    "CUP_LEVELS",
    "GOAL_REFINEMENT",
    "GOAL_UPDATES",
    "HERTZ_SIZES",
    "PRESSES",
    "RATIOS",
    "SCENES",
    "Case",
    "Variant",
    "run",
    "solve_case",
    "variants",
]


def run(quick: bool = False, out: str | Path | None = None) -> list[dict]:
    """Run the contact-iteration study and write ``iteration*.{csv,md,png}``.

    Parameters
    ----------
    quick : bool
        Small meshes and the fewest cases: seconds.
    out : path, optional
        Results folder; ``benchmarks/results`` (``.../quick`` for quick runs) by default.

    Returns
    -------
    list of dict
        One row per frame solved (study, scene, ratio, mesh, press and variant).
    """
    folder = results_dir(out, quick)
    info = machine_info()
    info["code"] = _code_version()
    t_start = time.perf_counter()
    rows: list[dict] = []
    history: list[dict] = []
    for case, vs in _cases(quick):
        reference = None
        for v in vs:
            row, hist = solve_case(case, v, quick)
            if v.label == CONTACT_SPACE.label:
                reference = row
            if reference is not None and reference["force_z"]:
                if not row["stop_reason"].startswith("diverged"):
                    # the resultant on the hand (block), not the sum of the rows' forces:
                    # where both meshes touch, rows both ways share one physical force
                    row["force_vs_cs_pct"] = 100 * (row["force_z"] / reference["force_z"] - 1.0)
                scale = reference["max_displacement"]
                for h in hist:
                    h["max_change_rel"] = h["max_change"] / scale if scale > 0 else math.nan
            rows.append(row)
            history += hist
            print(
                f"[iteration] {case.study}: {case.scene} E ratio {case.ratio:g}, {case.mesh}, "
                f"press {case.press:g}: {v.label}: {row['cell']} in {row['contact_s']:.2f} s",
                flush=True,
            )
            gc.collect()
    info["load average at end"] = load_average()
    info["run time"] = f"{time.perf_counter() - t_start:.0f} s"
    write_csv(folder / "iteration.csv", rows, CSV_KEYS)
    write_csv(folder / "iteration_history.csv", history, HISTORY_KEYS)
    goals = _goals(rows, quick)
    _write_report(folder, info, rows, goals, quick)
    _plot_histories(folder / "iteration.png", history, quick)
    _plot_counts(folder / "iteration_counts.png", rows, quick)
    return rows


def _code_version() -> str:
    """The git commit, whether contact/, fem/ or meshes/ differ from it, and digests."""
    root = Path(contact.__file__).resolve().parent
    digest = hashlib.sha1(b"".join(f.read_bytes() for f in sorted(root.rglob("*.py"))))
    hand = sorted((root.parent / "meshes" / "hand").glob("flesh_*.vtu"))
    meshes = hashlib.sha1(b"".join(f.read_bytes() for f in hand)).hexdigest()[:12]
    try:
        head = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"],
            cwd=root,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--", "contact", "fem", "meshes"],
            cwd=root.parent,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        head, dirty = "unknown", ""
    state = " with uncommitted changes in contact/, fem/ or meshes/" if dirty else ""
    return (
        f"commit {head}{state}; contact sources sha1 {digest.hexdigest()[:12]}; hand flesh "
        f"meshes sha1 {meshes}"
    )


CSV_KEYS = [
    "study",
    "scene",
    "ratio",
    "mesh",
    "level",
    "press",
    "dofs",
    "variant",
    "algorithm",
    "relaxation",
    "pairs",
    "dirichlet",
    "iterations",
    "converged",
    "stop_reason",
    "contacts",
    "back_solves",
    "back_solves_by_body",
    "partial_solves",
    "setup_s",
    "frame_s",
    "factor_s",
    "contact_s",
    "rows_s",
    "geometry_s",
    "bodies_s",
    "normal_force",
    "force_vs_cs_pct",
    "force_z",
    "max_support_force",
    "penetration_ratio",
    "max_penetration",
    "max_displacement",
    "final_change",
    "clearance",
    "load",
]
HISTORY_KEYS = [
    "study",
    "scene",
    "ratio",
    "mesh",
    "press",
    "variant",
    "iteration",
    "max_change",
    "max_change_rel",
    "max_penetration",
    "n_contacts",
    "added",
    "released",
    "normal_force",
    "relaxation",
]


def main(argv: list[str] | None = None) -> None:
    """``python -m benchmarks.iteration [--quick] [--out DIR]``."""
    ap = argparse.ArgumentParser(prog="python -m benchmarks.iteration", description=__doc__)
    ap.add_argument("--quick", action="store_true", help="small meshes, fewest cases")
    ap.add_argument("--out", help="results folder")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    run(quick=args.quick, out=args.out)
    print(f"[iteration] done in {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
