"""Sparse direct solves: ``fem.factorize`` (PARDISO, SuperLU) against scipy's ``spsolve``.

The systems are clamped elastic cubes: a unit cube of TET4 cells (six per brick), the
``z = 0`` face clamped, a uniform pressure on the top face. The stiffness is partitioned
as :class:`fem.StaticSolver` does and the free-free block ``K11`` solved for the load on
the free DOFs. Every solver gets the same ``K11`` and right-hand side; the relative
residual ``||K11 x - f|| / ||f||`` checks each answer.

``spsolve`` is scipy's default: SuperLU with COLAMD ordering, factor and solve in one call
(UMFPACK is used only where scikit-umfpack is installed; the report says which ran).
``fem.factorize(..., backend="superlu")`` is SuperLU with a symmetric minimum-degree
ordering. The full run ends with a system of about a million DOFs, assembled and factored
with PARDISO, with its peak memory.
"""

from __future__ import annotations

import gc
import importlib.util
import time
from pathlib import Path
from typing import Any

import numpy as np
import psutil
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import fem

from ._common import (
    GIB,
    MIB,
    Column,
    PeakMemory,
    load_average,
    machine_info,
    markdown_table,
    measure,
    plot_loglog,
    results_dir,
    write_csv,
    write_markdown,
)

__all__ = ["TARGETS", "clamped_cube", "divisions_for", "run"]

#: Young's modulus (Pa), Poisson's ratio and top pressure (Pa) of the cubes.
E, NU, PRESSURE = 1.0e6, 0.3, 1.0e3

#: Target numbers of free DOFs: full run, ``--quick``.
TARGETS: dict[bool, tuple[int, ...]] = {
    False: (10_000, 30_000, 100_000),
    True: (500, 1_000, 2_000),
}

#: Free DOFs of the large PARDISO system of the full run.
MILLION = 1_000_000

#: Goal: PARDISO (factor + solve) at least this many times faster than spsolve at the
#: largest size.
GOAL = 10.0

#: The slow solvers are skipped where a power law through the last two sizes predicts
#: more than this many seconds, or more memory than this fraction of what is available.
SLOW_TIME_LIMIT = 900.0
MEMORY_FRACTION = 0.6

#: Seconds the repeats of one timing may take (full run, quick run).
BUDGET = {False: 60.0, True: 0.2}


def divisions_for(target: int) -> int:
    """Cube divisions ``n`` whose clamped cube has closest to ``target`` free DOFs.

    The free DOFs are ``3 n (n + 1)^2``: every node but the ``(n + 1)^2`` clamped ones.
    """
    n = np.arange(1, 400)
    return int(n[np.argmin(np.abs(3 * n * (n + 1) ** 2 - target))])


def clamped_cube(
    n: int,
) -> tuple[fem.Mesh, sp.csr_matrix, np.ndarray, np.ndarray, np.ndarray]:
    """An ``n``-cube of tets, clamped at ``z = 0``, pressed on top.

    Returns
    -------
    mesh : fem.Mesh
    K : scipy.sparse.csr_matrix
        Full stiffness.
    free : ndarray of int
        Free DOFs.
    fixed : ndarray of int
        Clamped DOFs.
    f : ndarray
        Nodal loads on all DOFs.
    """
    mesh = fem.box_mesh((1.0, 1.0, 1.0), (n, n, n), element="tetra")
    k = fem.assemble_stiffness(mesh, fem.LinearElastic(E, NU))
    fixed = fem.node_dofs(np.flatnonzero(np.isclose(mesh.points[:, 2], 0.0)))
    mask = np.ones(mesh.n_dofs, dtype=bool)
    mask[fixed] = False
    tri = mesh.boundary.faces["triangle"]
    top = np.isclose(mesh.points[tri, 2], 1.0).all(axis=1)
    f = fem.pressure_load(mesh, {"triangle": tri[top]}, PRESSURE)
    return mesh, k, np.flatnonzero(mask), fixed, f


def reduce(k: sp.csr_matrix, free: np.ndarray) -> sp.csr_matrix:
    """The free-free block ``K11``, sliced as :class:`fem.StaticSolver` does."""
    return k[free][:, free]


def residual(a: sp.spmatrix, x: np.ndarray, b: np.ndarray) -> float:
    """``||a x - b|| / ||b||``."""
    return float(np.linalg.norm(a @ x - b) / np.linalg.norm(b))


def spsolve_method() -> str:
    """Which solver ``scipy.sparse.linalg.spsolve`` uses here for a real matrix."""
    try:
        found = importlib.util.find_spec("scikits.umfpack") is not None
    except ModuleNotFoundError:
        found = False
    return "UMFPACK (scikit-umfpack)" if found else "SuperLU, COLAMD ordering"


def _predict(history: list[tuple[int, float, float]], dofs: int) -> tuple[float, float]:
    """Time and memory at ``dofs`` from a power law through the last two ``history``."""
    if not history:
        return 0.0, 0.0
    if len(history) == 1:
        (d0, t0, m0), p = history[0], 2.0
        return t0 * (dofs / d0) ** p, m0 * (dofs / d0) ** 1.5
    (d0, t0, m0), (d1, t1, m1) = history[-2:]
    r = np.log(dofs / d1)
    pt = np.log(max(t1, 1e-6) / max(t0, 1e-6)) / np.log(d1 / d0)
    pm = np.log(max(m1, 1.0) / max(m0, 1.0)) / np.log(d1 / d0)
    return t1 * np.exp(max(pt, 1.0) * r), m1 * np.exp(max(pm, 1.0) * r)


def _too_big(history: list, dofs: int, name: str) -> str | None:
    t, m = _predict(history, dofs)
    avail = psutil.virtual_memory().available
    if t > SLOW_TIME_LIMIT or m > MEMORY_FRACTION * avail:
        return (
            f"{name} skipped: predicted {t:.0f} s and {m / GIB:.1f} GiB "
            f"(limits {SLOW_TIME_LIMIT:.0f} s, {MEMORY_FRACTION * avail / GIB:.1f} GiB)"
        )
    return None


def _bench_factorize(a: sp.csr_matrix, b: np.ndarray, backend: str, quick: bool) -> dict:
    """Factor and solve with ``fem.factorize``; best times, peak memory, residual."""
    splits: list[tuple[float, float]] = []

    def call() -> np.ndarray:
        t0 = time.perf_counter()
        fact = fem.factorize(a, backend=backend)
        t1 = time.perf_counter()
        x = fact.solve(b)
        splits.append((t1 - t0, time.perf_counter() - t1))
        del fact
        return x

    m = measure(call, 5, BUDGET[quick])
    fac = min(s[0] for s in splits)
    sol = min(s[1] for s in splits)
    return {
        f"{backend}_factor_s": fac,
        f"{backend}_solve_s": sol,
        f"{backend}_s": m.best,
        f"{backend}_runs": m.n,
        f"{backend}_peak_mib": m.peak_increment / MIB,
        f"{backend}_residual": residual(a, m.result, b),
    }


def _bench_size(n: int, quick: bool, slow: dict[str, list]) -> dict:
    mesh, k, free, _, f = clamped_cube(n)
    a = reduce(k, free)
    b = f[free]
    row: dict[str, Any] = {
        "divisions": n,
        "cells": len(mesh.cells["tetra"]),
        "dofs": mesh.n_dofs,
        "free_dofs": len(free),
        "nnz": a.nnz,
    }
    del mesh, k
    row.update(_bench_factorize(a, b, "pardiso", quick))
    notes = []
    for name in ("superlu", "spsolve"):
        note = _too_big(slow[name], len(free), name)
        if note:
            notes.append(note)
            continue
        if name == "superlu":
            res = _bench_factorize(a, b, "superlu", quick)
        else:
            m = measure(lambda: spla.spsolve(a, b), 3, BUDGET[quick])
            res = {
                "spsolve_s": m.best,
                "spsolve_runs": m.n,
                "spsolve_peak_mib": m.peak_increment / MIB,
                "spsolve_residual": residual(a, m.result, b),
            }
        row.update(res)
        slow[name].append((len(free), res[f"{name}_s"], res[f"{name}_peak_mib"] * MIB))
    if row.get("spsolve_s") is not None:
        row["ratio_spsolve"] = row["spsolve_s"] / row["pardiso_s"]
    if row.get("superlu_s") is not None:
        row["ratio_superlu"] = row["superlu_s"] / row["pardiso_s"]
    row["note"] = "; ".join(notes)
    return row


def _bench_million(target: int) -> dict:
    """Assemble, reduce, factor (PARDISO) and solve a clamped cube of ``target`` free DOFs.

    Every step's time and peak memory increment; ``peak_gib`` is the process's peak
    resident memory over all of them.
    """
    n = divisions_for(target)
    cells = 6 * n**3
    row: dict[str, Any] = {"divisions": n, "cells": cells}
    with PeakMemory() as whole:
        t0 = time.perf_counter()
        mesh = fem.box_mesh((1.0, 1.0, 1.0), (n, n, n), element="tetra")
        row["mesh_s"] = time.perf_counter() - t0
        with PeakMemory() as mem:
            t0 = time.perf_counter()
            k = fem.assemble_stiffness(mesh, fem.LinearElastic(E, NU))
            row["assemble_s"] = time.perf_counter() - t0
        row["assemble_peak_gib"] = mem.increment / GIB
        fixed = fem.node_dofs(np.flatnonzero(np.isclose(mesh.points[:, 2], 0.0)))
        mask = np.ones(mesh.n_dofs, dtype=bool)
        mask[fixed] = False
        free = np.flatnonzero(mask)
        tri = mesh.boundary.faces["triangle"]
        top = np.isclose(mesh.points[tri, 2], 1.0).all(axis=1)
        f = fem.pressure_load(mesh, {"triangle": tri[top]}, PRESSURE)
        row.update(dofs=mesh.n_dofs, free_dofs=len(free), nnz_k=k.nnz)
        del mesh, tri
        t0 = time.perf_counter()
        a = reduce(k, free)
        row["reduce_s"] = time.perf_counter() - t0
        del k
        b = f[free]
        row["nnz"] = a.nnz
        gc.collect()
        with PeakMemory() as mem:
            t0 = time.perf_counter()
            fact = fem.factorize(a, backend="pardiso")
            row["factor_s"] = time.perf_counter() - t0
        row["factor_peak_gib"] = mem.increment / GIB
        t0 = time.perf_counter()
        x = fact.solve(b)
        row["solve_s"] = time.perf_counter() - t0
        row["residual"] = residual(a, x, b)
        del fact
    row["peak_gib"] = whole.peak / GIB
    row["peak_increment_gib"] = whole.increment / GIB
    row["memory_method"] = whole.method
    return row


COLUMNS = (
    Column("free_dofs", "free DOFs", ","),
    Column("nnz", "nnz(K11)", ","),
    Column("pardiso_factor_s", "pardiso factor (s)", ".3f"),
    Column("pardiso_solve_s", "pardiso solve (s)", ".4f"),
    Column("pardiso_s", "pardiso total (s)", ".3f"),
    Column("pardiso_peak_mib", "pardiso peak (MiB)", ",.0f"),
    Column("pardiso_residual", "pardiso residual", ".1e"),
    Column("superlu_factor_s", "superlu factor (s)", ".3f"),
    Column("superlu_solve_s", "superlu solve (s)", ".4f"),
    Column("superlu_peak_mib", "superlu peak (MiB)", ",.0f"),
    Column("superlu_residual", "superlu residual", ".1e"),
    Column("spsolve_s", "spsolve (s)", ".3f"),
    Column("spsolve_peak_mib", "spsolve peak (MiB)", ",.0f"),
    Column("spsolve_residual", "spsolve residual", ".1e"),
    Column("ratio_spsolve", "spsolve / pardiso", ".1f"),
    Column("ratio_superlu", "superlu / pardiso", ".1f"),
)

CSV_KEYS = (
    "divisions", "cells", "dofs", "free_dofs", "nnz",
    "pardiso_factor_s", "pardiso_solve_s", "pardiso_s", "pardiso_runs", "pardiso_peak_mib",
    "pardiso_residual",
    "superlu_factor_s", "superlu_solve_s", "superlu_s", "superlu_runs", "superlu_peak_mib",
    "superlu_residual",
    "spsolve_s", "spsolve_runs", "spsolve_peak_mib", "spsolve_residual",
    "ratio_spsolve", "ratio_superlu", "note",
)  # fmt: skip

MILLION_KEYS = (
    "divisions", "cells", "dofs", "free_dofs", "nnz_k", "nnz", "mesh_s", "assemble_s",
    "assemble_peak_gib", "reduce_s", "factor_s", "factor_peak_gib", "solve_s", "residual",
    "peak_gib", "peak_increment_gib", "memory_method",
)  # fmt: skip


def run(quick: bool = False, out: str | Path | None = None) -> list[dict]:
    """Run the linear-solver benchmark and write ``linear_solve.{csv,md,png}``.

    Parameters
    ----------
    quick : bool
        Tiny systems (seconds) and no million-DOF system.
    out : path, optional
        Results folder; ``benchmarks/results`` (``.../quick`` for quick runs) by default.

    Returns
    -------
    list of dict
        One row per size; the million-DOF row (full runs) last, marked ``"million"``.
    """
    folder = results_dir(out, quick)
    info = machine_info()
    info["spsolve"] = spsolve_method()
    rows: list[dict] = []
    slow: dict[str, list] = {"superlu": [], "spsolve": []}
    for target in TARGETS[quick]:
        t0 = time.perf_counter()
        row = _bench_size(divisions_for(target), quick, slow)
        rows.append(row)
        print(
            f"[linear_solve] {row['free_dofs']:>8,} DOFs: pardiso {row['pardiso_s']:.3f} s, "
            f"superlu {row.get('superlu_s', float('nan')):.3f} s, "
            f"spsolve {row.get('spsolve_s', float('nan')):.3f} s "
            f"({time.perf_counter() - t0:.0f} s)",
            flush=True,
        )
        gc.collect()
    big = None
    if not quick:
        gc.collect()
        print(f"[linear_solve] {MILLION:,}-DOF system ...", flush=True)
        big = _bench_million(MILLION)
        print(
            f"[linear_solve] {big['free_dofs']:,} DOFs: assemble {big['assemble_s']:.1f} s, "
            f"factor {big['factor_s']:.1f} s, solve {big['solve_s']:.2f} s, "
            f"peak {big['peak_gib']:.2f} GiB",
            flush=True,
        )
    info["load average at end"] = load_average()
    write_csv(folder / "linear_solve.csv", rows, CSV_KEYS)
    if big is not None:
        write_csv(folder / "linear_solve_1M.csv", [big], MILLION_KEYS)
    _write_report(folder, info, rows, big, quick)
    x = [r["free_dofs"] for r in rows]
    series = {
        "pardiso factor+solve (fem default)": (x, [r["pardiso_s"] for r in rows]),
        "superlu factor+solve (fem)": (x, [r.get("superlu_s") for r in rows]),
        "scipy spsolve": (x, [r.get("spsolve_s") for r in rows]),
    }
    if big is not None:
        series["pardiso, ~1M DOFs"] = ([big["free_dofs"]], [big["factor_s"] + big["solve_s"]])
    plot_loglog(folder / "linear_solve.png", series, title="Sparse direct solve, clamped cube")
    if big is not None:
        rows.append({"million": True, **big})
    return rows


def _write_report(
    folder: Path, info: dict, rows: list[dict], big: dict | None, quick: bool
) -> None:
    body = markdown_table(rows, COLUMNS)
    body += (
        "\n\nTimes: best of several calls for the small systems, one call where a call is "
        "long (see the CSV's `*_runs`); wall clock. Peak: resident memory above what the "
        "process held before the call (kernel high-water mark). Residual: "
        "`||K11 x - f|| / ||f||`. spsolve times are factor + solve in one call."
    )
    notes = [f"- {r['free_dofs']:,} DOFs: {r['note']}" for r in rows if r.get("note")]
    if notes:
        body += "\n\n" + "\n".join(notes)
    sections = [("Results" + (" (quick: tiny sizes, not representative)" if quick else ""), body)]
    last = rows[-1]
    if last.get("ratio_spsolve") is not None:
        ok = "meets" if last["ratio_spsolve"] >= GOAL else "MISSES"
        verdict = (
            f"At {last['free_dofs']:,} DOFs PARDISO (factor + solve) is "
            f"{last['ratio_spsolve']:.1f}x faster than spsolve: {ok} the goal of "
            f"{GOAL:.0f}x. Ratios at all sizes: "
            + ", ".join(format(r["ratio_spsolve"], ".1f") for r in rows if r.get("ratio_spsolve"))
            + "."
        )
    else:
        verdict = "spsolve did not run at the largest size; no ratio."
    sections.append((f"Against the goal (>= {GOAL:.0f}x faster than spsolve)", verdict))
    if big is not None:
        cols = (
            Column("free_dofs", "free DOFs", ","),
            Column("cells", "tets", ","),
            Column("nnz", "nnz(K11)", ","),
            Column("assemble_s", "assemble (s)", ".1f"),
            Column("assemble_peak_gib", "assemble peak (GiB)", ".2f"),
            Column("reduce_s", "reduce (s)", ".1f"),
            Column("factor_s", "factor (s)", ".1f"),
            Column("factor_peak_gib", "factor peak (GiB)", ".2f"),
            Column("solve_s", "solve (s)", ".2f"),
            Column("residual", "residual", ".1e"),
            Column("peak_gib", "process peak (GiB)", ".2f"),
        )
        avail = psutil.virtual_memory().total / GIB
        sections.append(
            (
                "A million-DOF system with PARDISO",
                markdown_table([big], cols)
                + "\n\nAssembled with `fem.assemble_stiffness`, reduced to the free DOFs, "
                'factored with `fem.factorize(backend="pardiso")`, solved once. Step peaks are '
                "increments over the memory held before the step; the process peak is the "
                f"highest resident memory of the whole process ({big['memory_method']}), "
                f"against {avail:.1f} GiB of RAM.",
            )
        )
    write_markdown(
        folder / "linear_solve.md", "Sparse direct solvers: fem vs scipy", info, sections
    )
