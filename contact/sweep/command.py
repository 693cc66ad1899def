"""``python -m contact.sweep SWEEP.toml``: many scenes run on a Dask cluster.

The sweep file (:mod:`contact.sweep.spec`, ``docs/sweep.md``) names a base scene and the keys
to vary; each combination is written as ``runs/NNNN/scene.toml`` in the sweep's folder and
loaded before anything runs. Each run is one :func:`contact.grasp.run` into
``runs/NNNN/results`` on a Dask worker: an embedded ``distributed.LocalCluster`` (processes,
one task slot each, one per core by default) or, with ``--scheduler``, an existing cluster
(whose workers must see the sweep's folder).

Threads: each run holds its BLAS / OpenMP pools (``threadpoolctl``), PARDISO and numba to
``--threads N``. The default is the core share for the embedded cluster (cores // workers,
also set as the worker processes' ``OMP_NUM_THREADS`` etc.), so that the workers together do
not oversubscribe the cores, and 1 on an existing cluster (a worker runs ``nthreads`` tasks
at once: together they take its ``nthreads`` threads).

Faults: a run that raises or exits 2 or more is a failed row and the sweep goes on; a run
whose worker process dies is resubmitted by the scheduler (up to
:data:`contact.sweep.cluster.ALLOWED_FAILURES` deaths, then a ``KilledWorker`` failed row).
A run whose results folder is complete for the same scene text is not redone. The table is
``sweep.csv`` (:mod:`contact.sweep.table`) with a plot, ``sweep.png``.

Bounds: a sweep has at most :data:`contact.sweep.spec.MAX_RUNS` runs; the embedded
cluster's workers and each run's threads are held to the cores (and the workers to the runs
to do), with a warning saying so.

Order: the sweep file, the scheduler's address, every generated scene (loaded from a
temporary folder) and the output folder are checked first; then the cluster is started or
the scheduler asked (a handshake within :data:`contact.sweep.cluster.SCHEDULER_TIMEOUT`);
only then are the run folders written. Bad input thus leaves nothing behind.

Exit status (:data:`EXIT_STATUS`): 0 every run done, 1 a run failed, 2 bad input: a bad
sweep file, a bad generated scene, a bad or silent scheduler (one line, nothing written),
3 an internal error (one line naming the exception and a log file with its traceback, as
``contact.grasp``), 130 / 143 interrupted by SIGINT / SIGTERM (one line; the runs done so
far are kept and a second sweep resumes from them).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import logging
import os
import signal
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..app.cli import guarded
from ..errors import ContactError
from ..grasp import run as grasp_run
from ..scene.read import load_scene
from . import cluster
from .cluster import check_address, client, hold
from .spec import Sweep, SweepError, SweepRun, expand, load_sweep
from .table import columns, figures, plot, read_summary, write_table

__all__ = [
    "EXIT_STATUS", "RETRIES", "TEST_KILL_ONCE", "main", "run_one", "sweep",
]  # fmt: skip

#: The exit statuses of the command line, as ``--help`` and ``docs/sweep.md`` list them.
EXIT_STATUS = (
    "Exit status: 0 every run done; 1 a run failed (its row says why); 2 bad input: the "
    "sweep file, a generated scene, the scheduler's address or a scheduler that does not "
    "answer (one line; nothing written); 3 an internal error (one line and the path of a "
    "log file with its traceback); 130 / 143 interrupted by SIGINT / SIGTERM (the runs done "
    "are kept: run the sweep again to resume)."
)

#: Dask ``retries`` of a task that raises (``run_one`` itself catches a run's exceptions, so
#: this covers the rest, e.g. a result that does not travel back); deaths are counted above.
RETRIES = 1
#: Test-only hook: with this environment variable naming a file that does not exist, the
#: first run to create it (its pid inside) kills its own worker process (SIGKILL) once its
#: results are written and before it reports back; later runs and attempts go on.
TEST_KILL_ONCE = "CONTACT_SWEEP_TEST_KILL_ONCE"


def _limit_threads(threads: int) -> contextlib.AbstractContextManager:
    """Hold this process's BLAS / OpenMP pools and numba to ``threads`` (a context)."""
    from threadpoolctl import threadpool_limits

    try:
        import numba

        numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    except (ImportError, ValueError):
        pass
    return threadpool_limits(limits=threads)


def _kill_once() -> None:
    """The :data:`TEST_KILL_ONCE` hook: the first run to create the marker kills its process."""
    marker = os.environ.get(TEST_KILL_ONCE)
    if not marker:
        return
    try:
        fd = os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
    except FileExistsError:
        return
    os.write(fd, str(os.getpid()).encode())
    os.close(fd)
    os.kill(os.getpid(), getattr(signal, "SIGKILL", signal.SIGTERM))
    os._exit(70)  # where the signal is not immediate


def run_one(
    scene: str, results: str, pictures: bool, least: bool, threads: int | None = None
) -> dict:
    """One run, in a worker: :func:`contact.grasp.run`, its figures or its error's one line.

    Parameters
    ----------
    scene, results : str
        The generated scene file and its results folder.
    pictures, least : bool
        Render pictures; search the least grip.
    threads : int, optional
        This run's threads (BLAS, OpenMP, PARDISO, numba); default 1 (a worker's task slot).

    Returns
    -------
    dict
        ``status`` (``"done"`` or ``"failed: ..."``), ``exit_status``, ``seconds`` and, when
        done, the figures of :func:`contact.sweep.table.figures`.
    """
    t0 = time.perf_counter()
    threads = threads or 1  # a worker runs nthreads tasks at once: one thread each
    err = io.StringIO()
    try:
        with _limit_threads(threads), contextlib.redirect_stderr(err), \
                contextlib.redirect_stdout(io.StringIO()):  # fmt: skip
            code = grasp_run(scene, out=results, pictures=pictures, quiet=True, least=least)
        _kill_once()
    except Exception as exc:  # the sweep goes on: the row says what raised
        line = (str(exc).splitlines() or [""])[0][:300]
        return {"status": f"failed: {type(exc).__name__}: {line}", "exit_status": 3,
                "seconds": time.perf_counter() - t0}  # fmt: skip
    seconds = time.perf_counter() - t0
    summary = read_summary(Path(results), least) if code < 2 else None
    if summary is None:
        lines = [x for x in err.getvalue().splitlines() if x.strip()]
        why = lines[-1].removeprefix("error: ") if lines else "no complete summary.json"
        return {"status": f"failed: {why[:300]}", "exit_status": code, "seconds": seconds}
    return {**figures(summary), "status": "done", "exit_status": code, "seconds": seconds}


def _check(sw: Sweep, out: Path) -> list[tuple[SweepRun, dict | None]]:
    """Load each run's scene from a temporary folder; ``(run, resumed row or None)``.

    Nothing is written under ``out``. A run whose folder holds the same scene text and a
    complete summary is resumed.

    Raises
    ------
    SweepError
        A generated scene that does not load: one line naming the run and the key.
    """
    checked = []
    with tempfile.TemporaryDirectory(prefix="contact-sweep-") as tmp:
        trial = Path(tmp) / "scene.toml"
        for r in expand(sw, out / "runs"):
            scene = out / "runs" / r.name / "scene.toml"
            trial.write_text(r.text)
            try:
                load_scene(trial)
            except (ContactError, ValueError, OSError) as exc:
                values = ", ".join(f"{k} = {v!r}" for k, v in r.values.items())
                why = str(exc).replace(str(trial), str(scene))
                raise SweepError(f"run {r.name} ({values}): {why}") from None
            same = scene.is_file() and scene.read_text() == r.text
            done = read_summary(scene.parent / "results", sw.least_grip) if same else None
            row = None if done is None else {**figures(done), "status": "done", "seconds": 0.0}
            checked.append((r, row))
    return checked


def _writable(folder: Path) -> None:
    """Raise :class:`SweepError` where ``folder`` cannot be made and written (nothing made)."""
    up = folder
    while not up.exists() and up != up.parent:
        up = up.parent
    if up.exists() and not up.is_dir():
        raise SweepError(f"{folder}: cannot be made: {up} is not a folder")
    if not os.access(up, os.W_OK | os.X_OK):
        raise SweepError(f"{folder}: cannot be written ({up} is read-only)")


def _write(todo: list[SweepRun], out: Path) -> None:
    """Write each run's ``runs/NNNN/scene.toml`` (kept where it holds the same text)."""
    for r in todo:
        scene = out / "runs" / r.name / "scene.toml"
        if not (scene.is_file() and scene.read_text() == r.text):
            scene.parent.mkdir(parents=True, exist_ok=True)
            scene.write_text(r.text)


def _unguarded_child() -> bool:
    """True in a spawned process while it imports its parent's script as ``__mp_main__``.

    During that import ``__mp_main__`` is the script's module, not yet ``__main__``.
    """
    mp_main = sys.modules.get("__mp_main__")
    return mp_main is not None and mp_main is not sys.modules.get("__main__")


def sweep(
    path: str | Path,
    *,
    out: str | Path | None = None,
    scheduler: str | None = None,
    workers: int | None = None,
    threads: int | None = None,
    quiet: bool = False,
) -> int:
    """Run a sweep file; write ``runs/``, ``sweep.csv`` and ``sweep.png`` into ``out``.

    Parameters
    ----------
    path : str or Path
        The sweep file (``docs/sweep.md``).
    out : str or Path, optional
        The sweep's folder; default ``sweep.directory``, else ``results/<file stem>``.
    scheduler : str, optional
        A Dask scheduler's address; default an embedded local cluster.
    workers : int, optional
        Local worker processes; default one per core.
    threads : int, optional
        Threads per run (BLAS, OpenMP, PARDISO, numba); default the core share on the
        embedded cluster (cores // workers), 1 with ``scheduler`` (one per task slot).
    quiet : bool
        No progress bar and no closing line.

    Returns
    -------
    int
        0 every run done, 1 a run failed, 2 bad input (one line on stderr, nothing run).
        A script that calls it without ``if __name__ == "__main__":`` is imported again by
        each worker process it starts: there it returns 2 at once, doing nothing.
    """
    if _unguarded_child():
        return 2  # a worker process re-importing a script that calls sweep() unguarded
    for name, n in (("workers", workers), ("threads", threads)):
        if n is not None and (isinstance(n, bool) or not isinstance(n, int) or n < 1):
            print(f"error: {name} must be a positive integer, got {n!r}", file=sys.stderr)
            return 2
    try:
        if scheduler is not None:
            check_address(scheduler)
        sw = load_sweep(path)
        folder = Path(out or sw.directory or Path("results") / Path(path).stem).resolve()
        _writable(folder)
        checked = _check(sw, folder)
    except (ContactError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    rows: dict[int, dict[str, Any]] = {}
    todo = []
    for r, row in checked:
        if row is not None:
            rows[r.index] = {"run": r.name, **r.values, **row}
        else:
            todo.append(r)
    if todo:
        if scheduler is None:
            n, share = hold(workers, threads, len(todo))
        else:  # an existing cluster's workers: one thread a task slot unless told
            n, share = 0, threads or 1
        try:
            cl, local = client(scheduler, n, share)
        except (OSError, TimeoutError) as exc:
            why = (str(exc).splitlines() or [""])[0] or type(exc).__name__
            print(f"error: scheduler {scheduler}: does not answer within "
                  f"{cluster.SCHEDULER_TIMEOUT:g} s ({why})", file=sys.stderr)  # fmt: skip
            return 2
        except RuntimeError as exc:  # spawned workers re-import an unguarded script
            line = (str(exc).splitlines() or [""])[0]
            print(
                f"error: the local cluster's worker processes did not start ({line}): a script "
                'that calls contact.sweep.sweep() must call it under if __name__ == "__main__":',
                file=sys.stderr,
            )
            return 2
        try:
            _write(todo, folder)
            _submit(cl, [(r, folder / "runs" / r.name) for r in todo], sw, share, rows, quiet)
        except OSError as exc:  # the folder checked writable went away: nothing run
            print(f"error: {exc}", file=sys.stderr)
            return 2
        finally:
            try:
                cl.close()
            finally:
                if local is not None:
                    local.close()
    folder.mkdir(parents=True, exist_ok=True)
    ordered = [rows[i] for i in sorted(rows)]
    write_table(ordered, columns(sw.keys, sw.least_grip), folder)
    plot(ordered, sw.keys, sw.plot_y, folder / "sweep.png")
    failed = sum(1 for r in ordered if r["status"] != "done")
    if not quiet:
        print(f"runs={len(ordered)} done={len(ordered) - failed} failed={failed} "
              f"resumed={len(ordered) - len(todo)} table={folder / 'sweep.csv'}")  # fmt: skip
    return 1 if failed else 0


def _submit(client, todo, sw: Sweep, threads: int | None, rows: dict, quiet: bool) -> None:
    """Submit the runs, gather them as they complete, one bar with done / failed counts."""
    from distributed import as_completed
    from tqdm import tqdm

    futures = {}
    for r, run_folder in todo:
        fut = client.submit(
            run_one, str(run_folder / "scene.toml"), str(run_folder / "results"),
            sw.pictures, sw.least_grip, threads, key=f"grasp-run-{r.name}-{os.getpid()}",
            retries=RETRIES, pure=False,
        )  # fmt: skip
        futures[fut] = r
    done = failed = 0
    with tqdm(total=len(todo), desc="runs", unit="run", disable=quiet) as bar:
        for fut in as_completed(futures):
            r = futures[fut]
            try:
                res = fut.result()
            except Exception as exc:  # KilledWorker: its workers died past ALLOWED_FAILURES
                line = (str(exc).splitlines() or [""])[0][:300]
                res = {"status": f"failed: {type(exc).__name__}: {line}", "exit_status": 3}
            rows[r.index] = {"run": r.name, **r.values, **res}
            if res["status"] == "done":
                done += 1
            else:
                failed += 1
            bar.set_postfix(done=done, failed=failed)
            bar.update(1)


def main(argv: Sequence[str] | None = None) -> int:
    """The command line; returns the exit status (:data:`EXIT_STATUS`)."""
    ap = argparse.ArgumentParser(
        prog="python -m contact.sweep",
        description="Run a sweep of grasp scenes (a base scene and the keys to vary) on a "
        "Dask cluster; write each run's results, sweep.csv and sweep.png.",
        epilog=EXIT_STATUS + " The sweep keys are documented in docs/sweep.md.",
    )
    ap.add_argument("sweep", help="the sweep file (TOML; see docs/sweep.md)")
    ap.add_argument("--scheduler", metavar="ADDRESS",
                    help="a Dask scheduler (tcp://host:8786); default an embedded local cluster")
    ap.add_argument("--workers", metavar="N",
                    help="local worker processes (default one per core; held to the cores and "
                    "the runs to do)")
    ap.add_argument("--threads", metavar="N",
                    help="threads per run: BLAS, PARDISO, numba (default the core share on the "
                    "embedded cluster, 1 with --scheduler: one per task slot)")
    ap.add_argument("--out", metavar="DIR",
                    help="the sweep's folder (default sweep.directory, else results/<stem>)")
    ap.add_argument("--quiet", action="store_true", help="no progress bar, no closing line")
    args = ap.parse_args(argv)
    counts = {}
    for flag in ("workers", "threads"):
        text = getattr(args, flag)
        try:
            counts[flag] = None if text is None else int(text)
        except ValueError:
            counts[flag] = 0
        if text is not None and counts[flag] < 1:
            print(f"error: --{flag} must be a positive integer, got {text!r}", file=sys.stderr)
            return 2
    logging.basicConfig(level=logging.ERROR if args.quiet else logging.WARNING,
                        format="%(levelname)s: %(message)s")  # fmt: skip
    return guarded(
        lambda: sweep(args.sweep, out=args.out, scheduler=args.scheduler,
                      workers=counts["workers"], threads=counts["threads"],
                      quiet=args.quiet),
        "the runs done are kept: run the sweep again to resume",
    )  # fmt: skip

