"""Sweeps on Dask: throughput on one and two local workers, overhead per run, a cluster.

``python -m benchmarks sweep`` runs one sweep of the pads (``examples/pads.toml`` on a
6 mm mesh, both pads' friction varied: 16 runs; 4 with ``--quick``) with
:func:`contact.sweep.sweep`:

- on an embedded cluster of 1 and of 2 worker processes: runs per second, and their ratio
  (the goal: >= 1.7 on two cores);
- the overhead of a run against a plain ``python -m contact.grasp`` of one of its scenes
  (a fresh process: start, imports, numba's cached kernels loaded): a run's own seconds in
  the warm worker against the process's wall time;
- (full run) on a scheduler and two workers started as separate processes
  (``dask scheduler``, ``dask worker``), through ``--scheduler``.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from contact.sweep import sweep

from ._common import Column, machine_info, markdown_table, results_dir, write_csv, write_markdown

__all__ = ["run"]

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
#: Throughput of two local workers over one that the goal asks for.
GOAL = 1.7

COLUMNS = (
    Column("case", "case"),
    Column("runs", "runs", "d"),
    Column("seconds", "wall (s)", ".1f"),
    Column("per_second", "runs / s", ".3f"),
    Column("ratio", "over 1 worker", ".2f"),
)


def _sweep_file(folder: Path, runs: int) -> Path:
    values = [0.4, 0.5, 0.6, 0.7][: round(runs**0.5)]
    text = (
        "[sweep]\n"
        f'scene = "{(EXAMPLES / "pads.toml").as_posix()}"\n'
        'mode = "product"\n\n'
        "[vary]\n"
        '"ball.mesh_size" = [0.006]\n'
        f'"plane[0].friction" = {values}\n'
        f'"plane[1].friction" = {values}\n'
    )
    path = folder / "sweep.toml"
    path.write_text(text)
    return path


def _timed(path: Path, out: Path, **kw: Any) -> tuple[float, int]:
    shutil.rmtree(out, ignore_errors=True)
    t0 = time.perf_counter()
    status = sweep(path, out=out, quiet=True, **kw)
    return time.perf_counter() - t0, status


def _row_seconds(out: Path) -> list[float]:
    import csv

    with (out / "sweep.csv").open() as f:
        return [float(r["seconds"]) for r in csv.DictReader(f)]


def _cluster(path: Path, out: Path) -> tuple[float, int] | None:
    """The sweep on a scheduler and two workers started as separate processes."""
    dask = shutil.which("dask", path=str(Path(sys.executable).parent)) or shutil.which("dask")
    if dask is None:
        return None
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    port = "8799"
    procs = [subprocess.Popen([dask, "scheduler", "--port", port], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]  # fmt: skip
    try:
        time.sleep(3.0)
        for _ in range(2):
            procs.append(subprocess.Popen(
                [dask, "worker", f"tcp://127.0.0.1:{port}", "--nthreads", "1"],
                env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            ))  # fmt: skip
        time.sleep(5.0)
        return _timed(path, out, scheduler=f"tcp://127.0.0.1:{port}")
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(10)
            except subprocess.TimeoutExpired:
                p.kill()


def run(quick: bool = False, out: str | None = None) -> list[dict[str, Any]]:
    """Run the study; write ``sweep.csv`` and ``sweep.md``; return the rows."""
    folder = results_dir(out, quick)
    runs = 4 if quick else 16
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        path = _sweep_file(work, runs)
        rows = []
        for workers in (1, 2):
            seconds, status = _timed(path, work / f"w{workers}", workers=workers)
            rows.append({
                "case": f"embedded, {workers} worker(s)", "runs": runs, "seconds": seconds,
                "per_second": runs / seconds, "status": status,
            })  # fmt: skip
        rows[1]["ratio"] = rows[1]["per_second"] / rows[0]["per_second"]
        rows[0]["ratio"] = 1.0
        warm = sorted(_row_seconds(work / "w1"))[len(_row_seconds(work / "w1")) // 2]
        scene = next((work / "w1" / "runs").glob("*/scene.toml"))
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "contact.grasp", str(scene), "--out",
                        str(work / "plain"), "--quiet", "--no-pictures"], check=False)  # fmt: skip
        plain = time.perf_counter() - t0
        if not quick:
            got = _cluster(path, work / "cluster")
            if got is not None:
                rows.append({
                    "case": "scheduler and 2 workers, separate processes", "runs": runs,
                    "seconds": got[0], "per_second": runs / got[0],
                    "ratio": runs / got[0] / rows[0]["per_second"], "status": got[1],
                })  # fmt: skip
    write_csv(folder / "sweep.csv", rows, [c.key for c in COLUMNS] + ["status"])
    ratio = rows[1]["ratio"]
    goals = [
        f"- Two local workers over one: x{ratio:.2f} (goal >= {GOAL}): "
        f"{'met' if ratio >= GOAL else '**missed**'}.",
        f"- A run's median {warm:.2f} s in a warm worker against {plain:.2f} s for a plain "
        f"`python -m contact.grasp` of one of its scenes (a fresh process): the worker "
        f"saves {plain - warm:.2f} s a run (process start, imports, kernels loaded).",
    ]
    sections = [("Goals", "\n".join(goals)), ("Sweeps", markdown_table(rows, COLUMNS))]
    write_markdown(folder / "sweep.md", "Sweeps on Dask", machine_info(), sections)
    return rows
