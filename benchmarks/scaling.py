"""Scaling: time and peak memory of every phase of a static solve against DOFs, to ~1M DOFs.

Part one solves a clamped elastic unit cube (the ``z = 0`` face clamped, a uniform pressure
on the top face) of TET4 cells (six per brick) and, as a second series, of HEX8 cells, at
sizes geometric from about 10k DOFs up to about a million (:data:`FULL_MAX_DOFS`; the
``max_dofs`` argument or the environment variable ``BENCH_MAX_DOFS`` lowers the cap). Every
size runs the whole pipeline, each phase timed and its peak memory measured on its own
(:class:`benchmarks._common.PeakMemory`, the kernel's high-water mark):

``mesh``
    ``fem.box_mesh``, the boundary faces, the clamped DOFs and the pressure load.
``assembly``
    ``fem.assemble_stiffness``.
``factor``
    ``fem.StaticSolver(K, clamped)``: the partition of ``K`` into ``K11``, ``K12`` and the
    prescribed rows, and the factorisation of ``K11`` with the default backend (PARDISO).
``solve``
    One ``StaticSolver.solve``: displacements and reactions.
``stress``
    ``fem.cell_stress``, ``fem.von_mises`` and ``fem.nodal_average`` (what the results
    writer computes for every body).

``whole`` is their sum (time) and the highest resident memory of the process over all of
them. Every size runs in a fresh child process (``python -m benchmarks.scaling --child``),
so that its memory starts from a clean baseline and a crash loses that size only. A
phase's memory is its peak *increment*: the highest resident memory during the phase less
that at its start (what the phase needs on top of what earlier phases hold).
Before a size is run, a power law through the last sizes of its series predicts the
increment of the whole; a size that would not fit in the memory available is skipped and
the report says so. Slopes are least-squares fits on log-log axes over the sizes of at least
:data:`FIT_FROM` DOFs (all sizes where fewer than two are that large).

Part two runs the README's example end to end in a subprocess, ``python -m contact.grasp
examples/grasp.toml --out TMP`` (with ``--no-pictures``, and as the README has it, with
pictures), timing its wall clock and the child's peak resident memory; a third run through
``benchmarks/_grasp_trace.py`` splits its time into stages (imports, loading and meshing,
posing, assembling and factoring, contact, writing). ``--quick`` runs cubes up to about 20k
DOFs and only the traced run of the example's first frame without pictures.

Run it with ``python -m benchmarks.scaling [--quick] [--out DIR] [--max-dofs N]``.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import fem

from ._common import load_average, machine_info, results_dir, write_csv
from .scaling_cubes import (
    ELEMENTS,
    ENV_MAX_DOFS,
    FIT_FROM,
    FULL_MAX_DOFS,
    PHASES,
    QUICK_MAX_DOFS,
    _child,
    _cube_series,
    _dofs,
    _fits,
    cube_divisions,
    fit_slope,
    max_dofs_cap,
    solve_cube,
)
from .scaling_example import STAGES, _examples, run_example
from .scaling_report import CSV_KEYS, EXAMPLE_GOAL, MEMORY_GOAL, _plot, _write_report

__all__ = [
    "ELEMENTS",
    "EXAMPLE_GOAL",
    "FIT_FROM",
    "FULL_MAX_DOFS",
    "MEMORY_GOAL",
    "PHASES",
    "QUICK_MAX_DOFS",
    "STAGES",
    "cube_divisions",
    "fit_slope",
    "main",
    "max_dofs_cap",
    "run",
    "run_example",
    "solve_cube",
]


# --- entry points -----------------------------------------------------------------------


def run(
    quick: bool = False,
    out: str | Path | None = None,
    max_dofs: int | None = None,
    *,
    example: bool = True,
) -> list[dict]:
    """Run the scaling study and write ``scaling.{csv,md,png}``.

    Parameters
    ----------
    quick : bool
        Cubes up to about 20k DOFs and only the traced example's first frame (seconds).
    out : path, optional
        Results folder; ``benchmarks/results`` (``.../quick`` for quick runs) by default.
    max_dofs : int, optional
        Largest DOFs of the cubes (within 3 %); ``$BENCH_MAX_DOFS`` if not given, else
        about a million (20k with ``quick``).
    example : bool
        Run the grasp example (part two).

    Returns
    -------
    list of dict
        The cube rows (``kind = "cube"``), the example runs (``"example"``) and the
        fitted slopes (``"fit"``).
    """
    folder = results_dir(out, quick)
    cap = max_dofs_cap(max_dofs, quick)
    ns = cube_divisions(cap, quick)

    def log(msg: str) -> None:
        print(f"[scaling] {msg}", flush=True)

    info = machine_info()
    info["linear solver"] = fem.available_backends()[0]
    info["DOF cap"] = f"{cap:,}" + (
        f" (${ENV_MAX_DOFS}={os.environ[ENV_MAX_DOFS]})"
        if max_dofs is None and os.environ.get(ENV_MAX_DOFS)
        else ""
    )
    info["cube sizes (DOFs)"] = ", ".join(f"{_dofs(n):,}" for n in ns)
    cubes: list[dict] = []
    for element in ELEMENTS:
        cubes += _cube_series(element, ns, quick, log)
    fits = _fits(cubes)
    examples = _examples(quick, log) if example else []
    info["load average at end"] = load_average()
    rows = cubes + examples + fits
    write_csv(folder / "scaling.csv", rows, CSV_KEYS)
    _write_report(folder, info, cubes, fits, examples, cap, quick)
    _plot(folder / "scaling.png", cubes, fits)
    for f in fits:
        if f["quantity"] in ("whole_s", "factor_s", "assembly_s", "whole_peak_mib"):
            log(f"{f['element']} {f['quantity']}: slope {f['slope']:.2f} ({f['fit_over']})")
    return rows


def main(argv: list[str] | None = None) -> None:
    """The command line: ``python -m benchmarks.scaling [--quick] [--out DIR] [--max-dofs N]``."""
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.scaling",
        description="Time and peak memory of every phase of a static solve against DOFs "
        "(clamped cubes of tets and hexes, up to about a million DOFs), and the README's "
        "grasp example end to end.",
    )
    ap.add_argument("--quick", action="store_true", help="cubes up to ~20k DOFs, one frame")
    ap.add_argument("--out", help="results folder (default benchmarks/results[/quick])")
    ap.add_argument(
        "--max-dofs",
        type=int,
        help=f"largest cube's DOFs (default ${ENV_MAX_DOFS}, else {FULL_MAX_DOFS:,})",
    )
    ap.add_argument("--no-example", action="store_true", help="skip the grasp example")
    ap.add_argument("--child", nargs=3, metavar=("ELEMENT", "N", "JSON"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        element, n, path = args.child
        _child(element, int(n), args.quick, path)
        return
    t0 = time.perf_counter()
    run(quick=args.quick, out=args.out, max_dofs=args.max_dofs, example=not args.no_example)
    print(f"[scaling] done in {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
