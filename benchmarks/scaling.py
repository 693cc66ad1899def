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
import gc
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import psutil

import fem

from ._common import (
    GIB,
    MIB,
    Column,
    PeakMemory,
    load_average,
    machine_info,
    markdown_table,
    results_dir,
    write_csv,
    write_markdown,
)

__all__ = [
    "ELEMENTS",
    "EXAMPLE_GOAL",
    "FIT_FROM",
    "FULL_MAX_DOFS",
    "MEMORY_GOAL",
    "PHASES",
    "QUICK_MAX_DOFS",
    "cube_divisions",
    "fit_slope",
    "main",
    "max_dofs_cap",
    "run",
    "run_example",
    "solve_cube",
]

#: Element series: fem's cell type -> label.
ELEMENTS: dict[str, str] = {"tetra": "tet4", "hexahedron": "hex8"}

#: The phases of one solve, in order.
PHASES: tuple[str, ...] = ("mesh", "assembly", "factor", "solve", "stress")

#: Young's modulus (Pa), Poisson's ratio and top pressure (Pa) of the cubes.
E, NU, PRESSURE = 1.0e6, 0.3, 1.0e3

#: Smallest and largest DOFs of the full run, and of ``--quick``.
FULL_MIN_DOFS, FULL_MAX_DOFS = 10_000, 1_000_000
QUICK_MIN_DOFS, QUICK_MAX_DOFS = 2_000, 20_000

#: The largest cube may exceed the cap by this fraction (a cube's DOFs are ``3 (n + 1)^3``).
CAP_SLACK = 0.03

#: Environment variable that caps the DOFs when ``max_dofs`` is not given.
ENV_MAX_DOFS = "BENCH_MAX_DOFS"

#: Slopes are fitted over the sizes of at least this many DOFs.
FIT_FROM = 50_000

#: Goals: a million DOFs within this peak memory; the README example within this time.
MEMORY_GOAL = 24 * GIB
MILLION = 1_000_000
EXAMPLE_GOAL = 60.0

#: A size is skipped where its predicted peak increment times this margin exceeds the
#: memory available; the prediction grows at least as ``DOFs^(4/3)`` (a 3D factor's fill).
#: A size that runs out of memory all the same kills its own child process only.
MEMORY_MARGIN = 1.1
MIN_MEMORY_EXPONENT = 4.0 / 3.0

#: Memory increments below this (MiB) are allocator noise (pages reused): not fitted or drawn.
NOISE_MIB = 1.0

#: Pipeline runs per size (best time per phase kept) and the seconds they may take in all.
REPEAT = 3
BUDGET = {False: 10.0, True: 0.6}

#: The README's example, run from the repository root; longest it may run (s).
ROOT = Path(__file__).resolve().parents[1]
EXAMPLE_SCENE = "examples/grasp.toml"
EXAMPLE_TIMEOUT = 900.0

#: Longest one cube size may run in its child process (s).
CHILD_TIMEOUT = 4 * 3600.0
TRACE_SCRIPT = Path(__file__).resolve().parent / "_grasp_trace.py"

#: Stages of the traced example run (see ``benchmarks/_grasp_trace.py``).
STAGES: tuple[str, ...] = (
    "startup",
    "load_mesh",
    "posing",
    "assemble_factor",
    "contact",
    "writing",
    "other",
)


# --- sizes ------------------------------------------------------------------------------


def max_dofs_cap(max_dofs: int | None = None, quick: bool = False) -> int:
    """The DOF cap: ``max_dofs``, else ``$BENCH_MAX_DOFS``, else the default of the mode.

    ``--quick`` never goes above :data:`QUICK_MAX_DOFS`.
    """
    if max_dofs is None:
        env = os.environ.get(ENV_MAX_DOFS, "").strip().replace("_", "")
        max_dofs = int(float(env)) if env else None
    default = QUICK_MAX_DOFS if quick else FULL_MAX_DOFS
    cap = default if max_dofs is None else int(max_dofs)
    if quick:
        cap = min(cap, QUICK_MAX_DOFS)
    if cap < 81:
        raise ValueError(f"max_dofs must be at least 81 (a 2-cube), got {cap}")
    return cap


def _dofs(n: int) -> int:
    return 3 * (n + 1) ** 3


def cube_divisions(cap: int, quick: bool = False) -> list[int]:
    """Cube divisions ``n`` of the sizes: geometric (ratio about 2; 3 quick) up to ``cap`` DOFs.

    The largest has at most ``cap * (1 + CAP_SLACK)`` DOFs; the smallest is near
    :data:`FULL_MIN_DOFS` (:data:`QUICK_MIN_DOFS`), or the largest alone if that is below.
    """
    hi = 1
    while _dofs(hi + 1) <= cap * (1 + CAP_SLACK):
        hi += 1
    lo_target = QUICK_MIN_DOFS if quick else FULL_MIN_DOFS
    lo = max(1, round((lo_target / 3) ** (1 / 3)) - 1)
    if lo >= hi:
        return [hi]
    step = 3.0 if quick else 2.0
    count = max(2, round(np.log(_dofs(hi) / _dofs(lo)) / np.log(step)) + 1)
    targets = np.geomspace(_dofs(lo), _dofs(hi), count)
    ns = sorted({round((t / 3) ** (1 / 3)) - 1 for t in targets} | {lo, hi})
    return [n for n in ns if lo <= n <= hi]


# --- one cube ---------------------------------------------------------------------------


class _Phase:
    """Time and peak memory of one phase: ``record[name] = (s, rss_start, rss_peak, method)``."""

    def __init__(self, name: str, record: dict[str, tuple]) -> None:
        self.name = name
        self.record = record
        self._mem = PeakMemory()

    def __enter__(self) -> _Phase:
        self._mem.__enter__()
        self._t0 = time.perf_counter()
        return self

    def __exit__(self, *exc: object) -> None:
        elapsed = time.perf_counter() - self._t0
        self._mem.__exit__(*exc)
        self.record[self.name] = (elapsed, self._mem.start, self._mem.peak, self._mem.method)


def _pardiso_stats(solver: fem.StaticSolver) -> dict[str, float]:
    """Factor nonzeros and PARDISO's own peak memory report, where the backend tells."""
    s = getattr(getattr(solver, "_fact", None), "_s", None)
    iparm = getattr(s, "iparm", None)
    if iparm is None or len(iparm) < 18:
        return {}
    kib = max(int(iparm[14]), int(iparm[15]) + int(iparm[16]))
    return {"factor_nnz": int(iparm[17]), "pardiso_mem_mib": kib / 1024}


def solve_cube(n: int, element: str = "tetra") -> tuple[dict[str, Any], dict[str, tuple]]:
    """Solve the clamped ``n``-cube of ``element`` cells once, phase by phase.

    Parameters
    ----------
    n : int
        Divisions per edge.
    element : {"tetra", "hexahedron"}
        Cell type.

    Returns
    -------
    info : dict
        Cells, nodes, DOFs, nonzeros, factor nonzeros, the backend and checks: the
        reactions' balance of the load (relative) and the largest displacement.
    phases : dict
        Per phase of :data:`PHASES`: ``(seconds, rss_at_start, peak_rss, method)``.
    """
    rec: dict[str, tuple] = {}
    material = fem.LinearElastic(E, NU)
    with _Phase("mesh", rec):
        mesh = fem.box_mesh((1.0, 1.0, 1.0), (n, n, n), element=element)
        fixed = fem.node_dofs(np.flatnonzero(np.isclose(mesh.points[:, 2], 0.0)))
        faces = mesh.boundary.faces
        top = {k: c[np.isclose(mesh.points[c, 2], 1.0).all(axis=1)] for k, c in faces.items()}
        f = fem.pressure_load(mesh, top, PRESSURE)
    with _Phase("assembly", rec):
        k = fem.assemble_stiffness(mesh, material)
    with _Phase("factor", rec):
        solver = fem.StaticSolver(k, fixed)
    with _Phase("solve", rec):
        sol = solver.solve(f)
    with _Phase("stress", rec):
        sigma = fem.cell_stress(mesh, material, sol.u)
        vm = {kind: fem.von_mises(s) for kind, s in sigma.items()}
        nodal = fem.nodal_average(mesh, vm)
    load = f.reshape(-1, 3).sum(axis=0)
    reaction = sol.reactions.reshape(-1, 3).sum(axis=0)
    info: dict[str, Any] = {
        "cells": mesh.n_cells,
        "nodes": mesh.n_points,
        "dofs": mesh.n_dofs,
        "free_dofs": int(solver.free.size),
        "nnz_k": int(k.nnz),
        "nnz_k11": int(solver._k11.nnz) if hasattr(solver, "_k11") else None,
        "backend": solver.backend,
        "balance": float(np.linalg.norm(load + reaction) / np.linalg.norm(load)),
        "max_u": float(np.abs(sol.u).max()),
        "max_von_mises": float(nodal.max()),
        **_pardiso_stats(solver),
    }
    return info, rec


def _bench_size(n: int, element: str, quick: bool) -> dict[str, Any]:
    """One result row: best time per phase over repeats, memory of the first run."""
    info, first = solve_cube(n, element)
    runs = [first]
    while len(runs) < REPEAT:
        spent = sum(sum(p[0] for p in r.values()) for r in runs)
        if spent + min(sum(p[0] for p in r.values()) for r in runs) > BUDGET[quick]:
            break
        gc.collect()
        runs.append(solve_cube(n, element)[1])
    row: dict[str, Any] = {
        "kind": "cube",
        "element": ELEMENTS[element],
        "divisions": n,
        **info,
        "runs": len(runs),
    }
    start = first[PHASES[0]][1]
    for name in PHASES:
        row[f"{name}_s"] = min(r[name][0] for r in runs)
        _, rss0, peak, _ = first[name]
        row[f"{name}_inc_mib"] = max(peak - rss0, 0) / MIB
        row[f"{name}_peak_mib"] = peak / MIB
    row["whole_s"] = min(sum(r[name][0] for name in PHASES) for r in runs)
    peak = max(first[name][2] for name in PHASES)
    row["whole_peak_mib"] = peak / MIB
    row["whole_inc_mib"] = max(peak - start, 0) / MIB
    row["start_mib"] = start / MIB
    row["memory_method"] = first[PHASES[0]][3]
    return row


def _predict(
    history: list[tuple[int, float]], dofs: int, least: float, floor: float
) -> float | None:
    """A power law through the last three ``(dofs, value)`` at ``dofs``; None if unknown.

    The exponent is the least-squares one, at least ``least``; values below ``floor`` are
    left out.
    """
    pts = [(d, m) for d, m in history if m >= floor][-3:]
    if len(pts) < 2:
        return None
    slope = fit_slope([d for d, _ in pts], [m for _, m in pts])
    p = max(slope, least)
    d1, m1 = pts[-1]
    return m1 * (dofs / d1) ** p


def _warm_up(element: str) -> None:
    """Load the libraries and MKL once, so that the measured run does not carry that."""
    solve_cube(2, element)
    gc.collect()


def _child(element: str, n: int, quick: bool, path: str) -> None:
    """In a child process: warm up, measure one size, write its row as JSON to ``path``."""
    _warm_up(element)
    row = _bench_size(n, element, quick)
    Path(path).write_text(json.dumps(row))


def _measure_size(n: int, element: str, quick: bool) -> dict[str, Any]:
    """One size in a fresh process (clean memory baseline; a crash loses only this size)."""
    with tempfile.TemporaryDirectory(prefix="bench-scaling-") as tmp:
        path = Path(tmp) / "row.json"
        cmd = [sys.executable, "-m", "benchmarks.scaling", "--child", element, str(n), str(path)]
        if quick:
            cmd.append("--quick")
        wall, rss, status, text = _run_child(cmd, CHILD_TIMEOUT)
        if status == 0 and path.is_file():
            row = json.loads(path.read_text())
            row["child_peak_mib"] = rss / MIB
            row["child_wall_s"] = wall
            return row
    why = f"killed by signal {-status}" if status < 0 else f"exit status {status}"
    if status == -9:
        why += " (out of memory?)"
    tail = " | ".join(text.strip().splitlines()[-2:])
    return {
        "kind": "cube",
        "element": ELEMENTS[element],
        "divisions": n,
        "dofs": _dofs(n),
        "child_peak_mib": rss / MIB,
        "note": f"failed: {why} after {wall:.0f} s, peak RSS {rss / GIB:.1f} GiB; {tail}",
    }


def _cube_series(
    element: str, ns: Sequence[int], quick: bool, log: Callable[[str], None]
) -> list[dict]:
    """Every size of one element's series; sizes predicted not to fit are skipped."""
    rows: list[dict] = []
    history: list[tuple[int, float]] = []
    times: list[tuple[int, float]] = []
    skipped = False
    for n in ns:
        dofs = _dofs(n)
        need = _predict(history, dofs, MIN_MEMORY_EXPONENT, MIB)
        wait = _predict(times, dofs, 1.0, 1e-3)
        avail = psutil.virtual_memory().available
        if skipped or (need is not None and need * MEMORY_MARGIN > avail):
            note = (
                f"skipped: predicted peak increment {need / GIB:.1f} GiB (x {MEMORY_MARGIN} "
                f"margin) > {avail / GIB:.1f} GiB available"
                if need is not None and not skipped
                else "skipped: a smaller size did not run or was predicted not to fit"
            )
            rows.append(
                {
                    "kind": "cube",
                    "element": ELEMENTS[element],
                    "divisions": n,
                    "dofs": dofs,
                    "predicted_inc_mib": None if need is None else need / MIB,
                    "available_mib": avail / MIB,
                    "note": note,
                }
            )
            log(f"{ELEMENTS[element]} {dofs:>9,} DOFs: {note}")
            skipped = True
            continue
        if wait is not None and wait > 60:
            log(f"{ELEMENTS[element]} {dofs:>9,} DOFs: predicted {wait:.0f} s (whole) ...")
        t0 = time.perf_counter()
        row = _measure_size(n, element, quick)
        if need is not None:
            row["predicted_inc_mib"] = need / MIB
        if wait is not None:
            row["predicted_s"] = wait
        row["available_mib"] = avail / MIB
        rows.append(row)
        if row.get("whole_s") is None:
            log(f"{row['element']} {dofs:>9,} DOFs: {row['note']}")
            skipped = True
            continue
        history.append((row["dofs"], row["whole_inc_mib"] * MIB))
        times.append((row["dofs"], row["whole_s"]))
        log(
            f"{row['element']} {row['dofs']:>9,} DOFs: "
            + ", ".join(f"{p} {row[f'{p}_s']:.3g} s" for p in PHASES)
            + f"; peak {row['whole_peak_mib'] / 1024:.2f} GiB "
            f"({time.perf_counter() - t0:.0f} s, {row['runs']} run(s))"
        )
        gc.collect()
    return rows


# --- fits -------------------------------------------------------------------------------


def fit_slope(x: Sequence[float], y: Sequence[float]) -> float:
    """Least-squares slope of ``log y`` against ``log x`` (NaN with fewer than 2 points)."""
    pts = [(a, b) for a, b in zip(x, y) if a and b and a > 0 and b > 0 and b == b]
    if len(pts) < 2 or len({a for a, _ in pts}) < 2:
        return float("nan")
    lx, ly = np.log([a for a, _ in pts]), np.log([b for _, b in pts])
    return float(np.polyfit(lx, ly, 1)[0])


def _fit_power(x: Sequence[float], y: Sequence[float]) -> tuple[float, float]:
    """``(slope, log-intercept)`` of the least-squares power law through positive points."""
    pts = [(a, b) for a, b in zip(x, y) if a > 0 and b is not None and b > 0]
    lx, ly = np.log([a for a, _ in pts]), np.log([b for _, b in pts])
    slope, icpt = np.polyfit(lx, ly, 1)
    return float(slope), float(icpt)


#: The fitted quantities: (key in the rows, phase, "time" or "memory").
FITTED: tuple[tuple[str, str, str], ...] = (
    *((f"{p}_s", p, "time") for p in (*PHASES, "whole")),
    *((f"{p}_inc_mib", p, "memory increment") for p in (*PHASES, "whole")),
    ("whole_peak_mib", "whole", "process peak"),
)


def _fits(cubes: list[dict]) -> list[dict]:
    """Slope rows: per element and fitted quantity, over the sizes >= FIT_FROM DOFs."""
    out = []
    for label in ELEMENTS.values():
        done = [r for r in cubes if r["element"] == label and r.get("whole_s") is not None]
        big = [r for r in done if r["dofs"] >= FIT_FROM]
        used, over = (big, f">= {FIT_FROM:,} DOFs") if len(big) >= 2 else (done, "all sizes")
        for key, phase, what in FITTED:
            floor = NOISE_MIB if key.endswith("_mib") else 0.0
            x = [r["dofs"] for r in used]
            y = [r[key] if r[key] >= floor else None for r in used]
            out.append(
                {
                    "kind": "fit",
                    "element": label,
                    "phase": phase,
                    "measure": what,
                    "quantity": key,
                    "slope": fit_slope(x, y),
                    "fit_points": sum(1 for v in y if v is not None and v > 0),
                    "fit_over": over,
                    "fit_min_dofs": min(x) if x else None,
                    "fit_max_dofs": max(x) if x else None,
                }
            )
    return out


# --- the example ------------------------------------------------------------------------


def _run_child(cmd: list[str], timeout: float) -> tuple[float, float, int, str]:
    """Run ``cmd`` from the repository root: wall time, peak RSS (bytes), status, output."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH")) if p)
    with tempfile.TemporaryFile() as out:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=out, stderr=subprocess.STDOUT)
        timer = threading.Timer(timeout, proc.kill)
        timer.start()
        try:
            if hasattr(os, "wait4"):  # this child's own rusage
                _, status, usage = os.wait4(proc.pid, 0)
                proc.returncode = os.waitstatus_to_exitcode(status)
                maxrss = usage.ru_maxrss
            else:  # pragma: no cover - not Linux
                import resource

                proc.wait()
                maxrss = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
        finally:
            timer.cancel()
        wall = time.perf_counter() - t0
        out.seek(0)
        text = out.read().decode(errors="replace")
    scale = 1 if sys.platform == "darwin" else 1024  # ru_maxrss: bytes on macOS, else KiB
    return wall, maxrss * scale, int(proc.returncode), text


def _summary_split(summary: dict) -> dict[str, Any]:
    """Frames, verdicts and the time split that ``summary.json`` records."""
    frames = summary.get("frames", [])
    timings = [f.get("timings", {}) for f in frames]
    tail = summary.get("timings", {})
    return {
        "frames": len(frames),
        "all_converged": summary.get("all_converged"),
        "all_realistic": summary.get("all_realistic"),
        "setup_s": sum(t.get("setup", 0.0) for t in timings),
        "contact_s": sum(t.get("total", 0.0) for t in timings),
        "writing_s": sum(t.get("write", 0.0) for t in timings) + tail.get("finish", 0.0),
        "pictures_s": tail.get("pictures"),
        "pictures": summary.get("pictures"),
    }


def run_example(
    label: str,
    *,
    pictures: bool = True,
    frames: Sequence[int] | None = None,
    traced: bool = False,
    scene: str = EXAMPLE_SCENE,
    timeout: float = EXAMPLE_TIMEOUT,
) -> dict[str, Any]:
    """Run the grasp example end to end in a subprocess; one ``kind = "example"`` row.

    Parameters
    ----------
    label : str
        Name of the run in the report.
    pictures : bool
        False adds ``--no-pictures``.
    frames : sequence of int, optional
        ``--frames``; all frames by default.
    traced : bool
        Run through ``benchmarks/_grasp_trace.py``, which splits the time into
        :data:`STAGES`; else ``python -m contact.grasp`` as the README has it.
    scene : str
        The scene, relative to the repository root.
    timeout : float
        Seconds after which the child is killed.

    Returns
    -------
    dict
        ``wall_s``, ``child_peak_mib``, ``exit_status``, the verdicts and the time split
        (``summary.json``'s frame timings; stage by stage when traced).
    """
    with tempfile.TemporaryDirectory(prefix="bench-scaling-") as tmp:
        out = Path(tmp) / "out"
        args = [scene, "--out", str(out)]
        if frames is not None:
            args += ["--frames", *map(str, frames)]
        if not pictures:
            args.append("--no-pictures")
        trace = Path(tmp) / "trace.json"
        if traced:
            cmd = [sys.executable, str(TRACE_SCRIPT), str(trace), *args]
        else:
            cmd = [sys.executable, "-m", "contact.grasp", *args]
        shown = ["python", "-m", "contact.grasp", *args[:1], "--out", "TMP", *args[3:]]
        wall, rss, status, text = _run_child(cmd, timeout)
        row: dict[str, Any] = {
            "kind": "example",
            "label": label,
            "command": " ".join(shown) + (" (traced)" if traced else ""),
            "wall_s": wall,
            "child_peak_mib": rss / MIB,
            "exit_status": status,
        }
        summary_path = out / "summary.json"
        if summary_path.is_file():
            row.update(_summary_split(json.loads(summary_path.read_text())))
        if traced and trace.is_file():
            tr = json.loads(trace.read_text())
            st = tr["stages"]
            for name in STAGES[1:]:
                row[f"{name}_s"] = st.get(name, 0.0)
            # the rest of the wall time: the interpreter's start and exit, the imports
            row["startup_s"] = wall - sum(row[f"{name}_s"] for name in STAGES[1:])
            row["imports_s"] = st.get("imports")
            row["setup_s"] = row["posing_s"] + row["assemble_factor_s"]
        if "contact_s" in row:
            row["rest_s"] = wall - row["setup_s"] - row["contact_s"] - row["writing_s"]
        if status not in (0, 1) or not summary_path.is_file():
            row["note"] = f"failed (exit {status}): " + " | ".join(text.strip().splitlines()[-3:])
    return row


def _examples(quick: bool, log: Callable[[str], None]) -> list[dict]:
    if quick:
        plan = [
            ("traced, frame 0, no pictures", {"frames": [0], "pictures": False, "traced": True})
        ]
    else:
        plan = [
            ("README command, no pictures", {"pictures": False}),
            ("README command (pictures, GIF)", {"pictures": True}),
            ("traced, no pictures", {"pictures": False, "traced": True}),
        ]
    rows = []
    for label, kw in plan:
        row = run_example(label, **kw)
        rows.append(row)
        log(
            f"example, {label}: {row['wall_s']:.1f} s, peak {row['child_peak_mib']:.0f} MiB, "
            f"exit {row['exit_status']}" + (f" ({row['note']})" if row.get("note") else "")
        )
    return rows


# --- report -----------------------------------------------------------------------------

CSV_KEYS = (
    "kind", "element", "divisions", "cells", "nodes", "dofs", "free_dofs", "nnz_k", "nnz_k11",
    "factor_nnz", "pardiso_mem_mib", "backend", "runs",
    *(f"{p}_s" for p in PHASES), "whole_s",
    *(f"{p}_inc_mib" for p in PHASES), "whole_inc_mib",
    *(f"{p}_peak_mib" for p in PHASES), "whole_peak_mib", "start_mib", "memory_method",
    "predicted_inc_mib", "predicted_s", "available_mib", "balance", "max_u", "max_von_mises",
    "child_wall_s", "label", "command", "wall_s", "child_peak_mib", "exit_status", "frames",
    "all_converged", "all_realistic", "pictures", *(f"{s}_s" for s in STAGES), "imports_s",
    "setup_s",
    "contact_s", "writing_s", "pictures_s", "rest_s",
    "phase", "measure", "quantity", "slope", "fit_points", "fit_over", "fit_min_dofs",
    "fit_max_dofs", "note",
)  # fmt: skip

TIME_COLUMNS = (
    Column("element", "element"),
    Column("dofs", "DOFs", ","),
    Column("cells", "cells", ","),
    Column("nnz_k11", "nnz(K11)", ","),
    Column("factor_nnz", "nnz(factor)", ","),
    *(Column(f"{p}_s", f"{p} (s)", ".3g") for p in PHASES),
    Column("whole_s", "whole (s)", ".3g"),
    Column("runs", "runs", "d"),
    Column("balance", "balance", ".0e"),
    Column("note", "note"),
)

MEMORY_COLUMNS = (
    Column("element", "element"),
    Column("dofs", "DOFs", ","),
    *(Column(f"{p}_inc_mib", f"{p} (MiB)", ",.0f") for p in PHASES),
    Column("whole_inc_mib", "whole increment (MiB)", ",.0f"),
    Column("whole_peak_mib", "process peak (MiB)", ",.0f"),
    Column("child_peak_mib", "child's max RSS (MiB)", ",.0f"),
    Column("pardiso_mem_mib", "PARDISO's own report (MiB)", ",.0f"),
    Column("predicted_inc_mib", "predicted increment (MiB)", ",.0f"),
    Column("available_mib", "available (MiB)", ",.0f"),
)

EXAMPLE_COLUMNS = (
    Column("label", "run"),
    Column("frames", "frames", "d"),
    Column("wall_s", "wall (s)", ".1f"),
    Column("child_peak_mib", "peak RSS (MiB)", ",.0f"),
    Column("exit_status", "exit", "d"),
    Column("startup_s", "interpreter + imports + exit (s)", ".2f"),
    Column("load_mesh_s", "load + mesh (s)", ".2f"),
    Column("posing_s", "posing (s)", ".2f"),
    Column("assemble_factor_s", "assemble + factor (s)", ".2f"),
    Column("setup_s", "frame set-up (s)", ".2f"),
    Column("contact_s", "contact (s)", ".2f"),
    Column("writing_s", "writing (s)", ".2f"),
    Column("pictures_s", "of which pictures (s)", ".2f"),
    Column("other_s", "other (s)", ".2f"),
    Column("rest_s", "rest (s)", ".2f"),
)


def _slope_table(fits: list[dict]) -> str:
    """Slopes as a table: a row per element and phase, time and memory side by side."""
    rows = []
    for label in ELEMENTS.values():
        for phase in (*PHASES, "whole"):
            got = {f["measure"]: f for f in fits if f["element"] == label and f["phase"] == phase}
            t = got.get("time", {})
            rows.append(
                {
                    "element": label,
                    "phase": phase,
                    "time": t.get("slope"),
                    "memory": got.get("memory increment", {}).get("slope"),
                    "peak": got.get("process peak", {}).get("slope"),
                    "points": t.get("fit_points"),
                    "range": (
                        f"{t['fit_min_dofs']:,}..{t['fit_max_dofs']:,} ({t['fit_over']})"
                        if t.get("fit_min_dofs") is not None
                        else None
                    ),
                }
            )
    cols = (
        Column("element", "element"),
        Column("phase", "phase"),
        Column("time", "time slope", ".2f"),
        Column("memory", "memory-increment slope", ".2f"),
        Column("peak", "process-peak slope", ".2f"),
        Column("points", "sizes", "d"),
        Column("range", "DOFs fitted"),
    )
    return markdown_table(rows, cols)


def _memory_goal(cubes: list[dict], fits: list[dict], cap: int) -> list[dict]:
    """Per element: the process peak at ~1M DOFs, measured or (capped) extrapolated."""
    out = []
    for label in ELEMENTS.values():
        series = [r for r in cubes if r["element"] == label]
        done = [r for r in series if r.get("whole_peak_mib") is not None]
        big = [r for r in done if r["dofs"] >= MILLION * (1 - CAP_SLACK)]
        goal = f"{MILLION:,} DOFs ({label}) fits in {MEMORY_GOAL / GIB:.0f} GiB"
        if big:
            r = big[-1]
            peak = max(r["whole_peak_mib"], r.get("child_peak_mib") or 0.0) * MIB
            ok = "met" if peak <= MEMORY_GOAL else "missed"
            measured = (
                f"{peak / GIB:.2f} GiB peak resident memory of the process at {r['dofs']:,} "
                f"DOFs (factor {r['factor_s']:.0f} s, whole {r['whole_s']:.0f} s)"
            )
        else:
            skipped = [r for r in series if r.get("whole_peak_mib") is None]
            # the increment's power law over the fitted sizes plus the RSS the process held
            fitted = [r for r in done if r["dofs"] >= FIT_FROM]
            if len(fitted) >= 2:
                slope, icpt = _fit_power(
                    [r["dofs"] for r in fitted], [r["whole_inc_mib"] * MIB for r in fitted]
                )
                guess = np.exp(icpt) * MILLION**slope + fitted[-1]["start_mib"] * MIB
                extra = f"; extrapolated from the fit (slope {slope:.2f}): {guess / GIB:.1f} GiB"
            else:
                extra = ""
            largest = done[-1]["dofs"] if done else 0
            if skipped and skipped[-1]["dofs"] >= MILLION * (1 - CAP_SLACK):
                why = skipped[-1]["note"]
                failed = why.startswith("failed")
                ok = "missed (the run failed)" if failed else "missed (predicted not to fit)"
            else:
                why = f"not run: sizes capped at {cap:,} DOFs"
                ok = "not measured"
            measured = f"{why}; largest run {largest:,} DOFs{extra}"
        out.append({"goal": goal, "measured": measured, "status": ok})
    return out


def _example_goal(examples: list[dict]) -> dict:
    goal = f"README example end to end <= {EXAMPLE_GOAL:.0f} s"
    readme = [r for r in examples if r["label"].startswith("README command (pictures")]
    if not readme:
        return {
            "goal": goal,
            "measured": "not measured (--quick runs one frame only)",
            "status": "not measured",
        }
    r = readme[0]
    if r.get("note"):
        return {"goal": goal, "measured": r["note"], "status": "missed (failed)"}
    ok = "met" if r["wall_s"] <= EXAMPLE_GOAL else "missed"
    return {
        "goal": goal,
        "measured": f"{r['wall_s']:.1f} s wall, {r['child_peak_mib']:.0f} MiB peak RSS "
        f"({r['frames']} frames, pictures and GIF)",
        "status": ok,
    }


def _write_report(
    folder: Path,
    info: dict[str, str],
    cubes: list[dict],
    fits: list[dict],
    examples: list[dict],
    cap: int,
    quick: bool,
) -> None:
    goals = [*_memory_goal(cubes, fits, cap), _example_goal(examples)]
    gcols = (Column("goal", "goal"), Column("measured", "measured"), Column("status", "status"))
    sections = [
        ("Goals", markdown_table(goals, gcols)),
        (
            "Clamped cube: time per phase" + (" (quick: small sizes)" if quick else ""),
            markdown_table(cubes, TIME_COLUMNS)
            + "\n\nPhases: `mesh` (box_mesh, boundary faces, clamped DOFs, pressure load), "
            "`assembly` (assemble_stiffness), `factor` (StaticSolver: partition of K and "
            "the factorisation of K11 with the default backend), `solve` (one "
            "StaticSolver.solve), `stress` (cell_stress, von_mises, nodal_average); `whole` "
            "their sum. Times: wall clock, the best of `runs` runs of the whole pipeline "
            "(one where a run is long). `balance`: |sum of reactions + load| / |load|. "
            "nnz(factor): PARDISO's count of the factor's nonzeros.",
        ),
        (
            "Clamped cube: peak memory per phase",
            markdown_table(cubes, MEMORY_COLUMNS)
            + "\n\nEvery size runs in a fresh process (a clean memory baseline: memory "
            "freed by a previous size and kept by the allocator would hide increments). A "
            "phase's memory is its peak increment: the highest resident memory of the "
            "process during the phase less that at its start (kernel high-water mark, from "
            "the first run at each size). `whole increment`: the highest over all phases "
            "less the resident memory before the mesh phase; `process peak`: the highest "
            "resident memory of the process during the phases (interpreter and libraries "
            "included); `child's max RSS`: the same from the child's rusage (imports and a "
            "warm-up solve of a 2-cube included). `PARDISO's own report`: its peak memory "
            "estimate (iparm 15 to 17). "
            f"`predicted increment`: what the last sizes' power law (exponent at least "
            f"{MIN_MEMORY_EXPONENT:.2f}) predicted before the size ran; a size whose "
            f"prediction times {MEMORY_MARGIN} passes the memory available is skipped.",
        ),
        (
            "Fitted slopes (log-log least squares)",
            _slope_table(fits)
            + f"\n\nFitted over the sizes of at least {FIT_FROM:,} DOFs (all sizes where "
            f"fewer than two are). Memory increments below {NOISE_MIB:g} MiB (a few pages, "
            "allocator noise) are left out of the fits and the plot; `sizes` counts the "
            "sizes of the time fit. `fem.assemble_stiffness` works through the cells in "
            "chunks (`fem.assembly.CHUNK` cells), so its transient memory grows more slowly "
            "than the DOFs once a mesh holds several chunks (the tet meshes here).",
        ),
        (
            "The README example end to end",
            markdown_table(examples, EXAMPLE_COLUMNS)
            + "\n\nWall: the subprocess from start to exit; peak RSS: the child's own "
            "(`wait4` rusage). README runs: `frame set-up` (posing, placing the ball, "
            "assembling and factoring new bodies), `contact` and `writing` (VTU files, "
            "stresses, convergence plot, pictures, GIF, summary) add up the per-frame "
            "timings of `summary.json`; `rest` is the wall time outside them (interpreter, "
            "imports, reading the scene, the ball's mesh, loading the hand). The traced run "
            "(`benchmarks/_grasp_trace.py`) times the stages directly; its `rest` is "
            "interpreter + imports, load + mesh and other.",
        ),
    ]
    notes = [f"- {r['element']} {r['dofs']:,} DOFs: {r['note']}" for r in cubes if r.get("note")]
    if notes:
        sections.insert(1, ("Skipped sizes", "\n".join(notes)))
    write_markdown(
        folder / "scaling.md",
        "Scaling: time and peak memory against DOFs, and the grasp example end to end",
        info,
        sections,
    )


def _plot(path: Path, cubes: list[dict], fits: list[dict]) -> None:
    """Two log-log panels: time and peak memory against DOFs, slopes in the legends."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    slopes = {(f["element"], f["quantity"]): f["slope"] for f in fits}
    fig, axes = plt.subplots(1, 2, figsize=(14, 9))
    colours = dict(zip((*PHASES, "whole"), plt.get_cmap("tab10").colors))
    styles = {"tet4": ("-", "o"), "hex8": ("--", "s")}
    panels = (
        (axes[0], "time (s)", [(f"{p}_s", p) for p in (*PHASES, "whole")], 1.0),
        (
            axes[1],
            "peak memory (GiB)",
            [(f"{p}_inc_mib", p) for p in PHASES] + [("whole_peak_mib", "whole (process peak)")],
            MIB / GIB,
        ),
    )
    for ax, ylabel, keys, scale in panels:
        for label, (ls, marker) in styles.items():
            rows = [r for r in cubes if r["element"] == label and r.get("whole_s") is not None]
            for key, name in keys:
                floor = NOISE_MIB if key.endswith("_mib") else 0.0
                pts = [(r["dofs"], r[key] * scale) for r in rows if (r.get(key) or 0) > floor]
                if not pts:
                    continue
                s = slopes.get((label, key), float("nan"))
                colour = colours[name.split(" ")[0]]
                ax.loglog(
                    *zip(*pts),
                    ls=ls,
                    marker=marker,
                    color=colour,
                    label=f"{label} {name} (slope {s:.2f})" if s == s else f"{label} {name}",
                )
        ax.set_xlabel("DOFs (3 x nodes)")
        ax.set_ylabel(ylabel)
        ax.grid(True, which="both", alpha=0.3)
    axes[1].axhline(MEMORY_GOAL / GIB, color="red", ls=":", lw=1.5, label="24 GiB")
    axes[0].set_title("Time per phase, clamped cube")
    axes[1].set_title("Peak memory: phase increments and process peak")
    for ax in axes:
        ax.legend(fontsize="small", ncol=2, loc="upper center", bbox_to_anchor=(0.5, -0.1))
    fig.suptitle(f"Slopes fitted over sizes >= {FIT_FROM:,} DOFs (all sizes if fewer than two)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


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
