"""The Dask cluster of a sweep: the scheduler's address and answer, the embedded cluster.

:func:`check_address` checks a ``--scheduler`` address without connecting; :func:`client`
asks an existing scheduler who it is under one deadline (:data:`SCHEDULER_TIMEOUT`) before
Dask's client connects, or starts an embedded ``distributed.LocalCluster`` of single-slot
worker processes; :func:`hold` holds its workers to the cores and the runs to do, and each
run's threads to the cores, with a warning saying so.
"""

from __future__ import annotations

import asyncio
import logging
import os
import re
from concurrent.futures import ThreadPoolExecutor
from concurrent.futures import TimeoutError as FutureTimeout

from .spec import SweepError

__all__ = [
    "ALLOWED_FAILURES", "SCHEDULER_TIMEOUT", "THREAD_VARIABLES", "check_address", "client",
    "hold",
]  # fmt: skip

log = logging.getLogger(__name__)

#: Seconds to wait for a ``--scheduler`` to answer before giving up (exit 2).
SCHEDULER_TIMEOUT = 10.0
#: A scheduler's address: ``[PROTOCOL://]HOST:PORT``, HOST a name, an IPv4 or a bracketed IPv6.
_ADDRESS = re.compile(
    r"^(?:(tcp|tls|ws|wss|ucx)://)?(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9._-]+):(\d{1,5})$"
)
#: The thread-count variables a worker process gets, read by the BLAS, PARDISO and numba.
THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS",
                    "NUMBA_NUM_THREADS")  # fmt: skip
#: Worker deaths a run survives on the embedded cluster (``distributed.scheduler.
#: allowed-failures``); one more and the run is a ``KilledWorker`` failed row. An existing
#: cluster's scheduler uses its own setting (Dask's default is also 3).
ALLOWED_FAILURES = 3


def check_address(address: str) -> None:
    """Check a scheduler's address, ``[tcp://]HOST:PORT`` (no connection is made).

    Raises
    ------
    SweepError
        One line naming the address and the form expected.
    """
    m = _ADDRESS.match(address) if isinstance(address, str) else None
    if m is None or not 0 < int(m.group(3)) < 65536:
        raise SweepError(f"--scheduler {address!r}: not a scheduler address; expected "
                         "[PROTOCOL://]HOST:PORT, e.g. tcp://10.0.0.5:8786, PORT 1 to 65535, "
                         "PROTOCOL tcp, tls, ws, wss or ucx")  # fmt: skip


def _probe(address: str, timeout: float) -> None:
    """Ask the scheduler who it is; raise :class:`TimeoutError` or OSError without an answer.

    The whole handshake runs under one deadline: a port that accepts and never answers
    would otherwise hold Dask's client past its own timeout.
    """
    from distributed.comm import connect

    async def ask() -> None:
        comm = await connect(address, timeout=timeout)
        try:
            await comm.write({"op": "identity", "reply": True})
            await comm.read()
        finally:
            comm.abort()

    async def within() -> None:
        try:
            await asyncio.wait_for(ask(), timeout)
        except asyncio.TimeoutError:  # not the builtin one before Python 3.11
            raise TimeoutError(f"no answer within {timeout:g} s") from None

    pool = ThreadPoolExecutor(1)  # its own event loop, whatever loop the caller runs
    try:
        pool.submit(asyncio.run, within()).result(timeout + 5)
    except FutureTimeout:
        raise TimeoutError(f"no answer within {timeout:g} s") from None
    finally:
        pool.shutdown(wait=False)


def hold(workers: int | None, threads: int | None, runs: int) -> tuple[int, int]:
    """The embedded cluster's workers and threads a run, held to the cores and the runs.

    More workers than cores or runs to do would only cost memory (each is a process), more
    threads a run than cores would oversubscribe them: either is held, with a warning.
    """
    cores = os.cpu_count() or 1
    n = min(workers or cores, cores, max(runs, 1))
    if workers is not None and workers > n:
        log.warning("--workers %d: held to %d (%d cores, %d runs to do)", workers, n, cores, runs)
    if threads is not None and threads > cores:
        log.warning("--threads %d: held to the %d cores", threads, cores)
        threads = cores
    return n, threads or max(1, cores // n)


def client(scheduler: str | None, workers: int, threads: int):
    """A Dask client and the cluster it owns (None with ``--scheduler``)."""
    import dask
    from distributed import Client, LocalCluster

    logging.getLogger("distributed").setLevel(logging.ERROR)
    if scheduler is not None:
        _probe(scheduler, SCHEDULER_TIMEOUT)
        return Client(scheduler, timeout=SCHEDULER_TIMEOUT), None
    env = {v: str(threads) for v in THREAD_VARIABLES}
    with dask.config.set({"distributed.scheduler.allowed-failures": ALLOWED_FAILURES}):
        cluster = LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0",
            silence_logs=logging.CRITICAL, env=env,
        )  # fmt: skip
    try:
        return Client(cluster), cluster
    except BaseException:
        cluster.close()
        raise
