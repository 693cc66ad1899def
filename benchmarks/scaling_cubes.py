"""The scaling study's cubes: their sizes, one clamped cube solved phase by phase in a child
process, the series up to the memory available, and the log-log fits.
"""

from __future__ import annotations

import gc
import json
import os
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import psutil

import fem

from ._common import GIB, MIB, PeakMemory
from .scaling_example import _run_child

__all__ = [
    "BUDGET",
    "CAP_SLACK",
    "CHILD_TIMEOUT",
    "ELEMENTS",
    "ENV_MAX_DOFS",
    "FITTED",
    "FIT_FROM",
    "FULL_MAX_DOFS",
    "FULL_MIN_DOFS",
    "MEMORY_MARGIN",
    "MIN_MEMORY_EXPONENT",
    "NOISE_MIB",
    "NU",
    "PHASES",
    "PRESSURE",
    "QUICK_MAX_DOFS",
    "QUICK_MIN_DOFS",
    "REPEAT",
    "E",
    "cube_divisions",
    "fit_slope",
    "max_dofs_cap",
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


#: Longest one cube size may run in its child process (s).
CHILD_TIMEOUT = 4 * 3600.0


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
