"""Shared helpers of the benchmarks: machine info, timing, peak memory and result files."""

from __future__ import annotations

import csv
import datetime as _dt
import gc
import importlib.metadata
import os
import platform
import re
import threading
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import psutil

__all__ = [
    "GIB",
    "MIB",
    "Column",
    "Measurement",
    "PeakMemory",
    "load_average",
    "machine_info",
    "measure",
    "plot_loglog",
    "results_dir",
    "with_models",
    "write_csv",
    "write_markdown",
]

MIB = 1024**2
GIB = 1024**3


def with_models(scene: Any, flesh: str, ball: str | None = None) -> Any:
    """``scene`` with its hand's flesh (and its ball, where given) of material ``model``.

    The studies of the linear frame's cost take the flesh ``"linear"``: the shipped hand
    examples' is neo-Hookean (``benchmarks/finite_example.py`` measures it).
    """
    if ball is not None and scene.ball is not None:
        scene = replace(scene, ball=replace(scene.ball, model=ball))
    if scene.hand is None:
        return scene
    return replace(scene, hand=replace(scene.hand, flesh=replace(scene.hand.flesh, model=flesh)))


#: Where full runs write their results.
RESULTS = Path(__file__).resolve().parent / "results"


def results_dir(out: str | os.PathLike[str] | None, quick: bool) -> Path:
    """The folder results go to: ``out`` if given, else ``results/`` (``results/quick/``)."""
    path = Path(out) if out is not None else (RESULTS / "quick" if quick else RESULTS)
    path.mkdir(parents=True, exist_ok=True)
    return path


# --- machine information ----------------------------------------------------------------


def _cpu_model() -> str:
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return platform.processor() or platform.machine()
    m = re.search(r"^model name\s*:\s*(.+)$", text, flags=re.MULTILINE)
    return m.group(1).strip() if m else (platform.processor() or platform.machine())


def _version(dist: str) -> str:
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return "not installed"


def machine_info() -> dict[str, str]:
    """What the numbers were measured on: CPU, cores, memory, library versions and date.

    Returns
    -------
    dict of str to str
        Ordered for display.
    """
    vm = psutil.virtual_memory()
    return {
        "date": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "cpu": _cpu_model(),
        "cores": f"{psutil.cpu_count(logical=False)} physical, {os.cpu_count()} logical",
        "memory": f"{vm.total / GIB:.1f} GiB total, {vm.available / GIB:.1f} GiB available",
        "load average at start": load_average(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "numpy": _version("numpy"),
        "scipy": _version("scipy"),
        "pypardiso": _version("pypardiso"),
        "mkl": _version("mkl"),
        "scikit-fem": _version("scikit-fem"),
        "fem": _fem_version(),
    }


def load_average() -> str:
    """The 1, 5 and 15 minute load averages (other work on the machine skews timings)."""
    try:
        return ", ".join(f"{v:.2f}" for v in os.getloadavg())
    except OSError:
        return "unknown"


def _fem_version() -> str:
    """fem's version and a digest of its sources, to tie results to the code measured."""
    import hashlib

    import fem

    files = sorted(Path(fem.__file__).parent.glob("*.py"))
    digest = hashlib.sha1(b"".join(f.read_bytes() for f in files)).hexdigest()[:12]
    newest = max(f.stat().st_mtime for f in files)
    when = _dt.datetime.fromtimestamp(newest, _dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    return f"{fem.__version__} (sources sha1 {digest}, last modified {when})"


# --- peak memory ------------------------------------------------------------------------

_STATUS = Path("/proc/self/status")
_CLEAR_REFS = Path("/proc/self/clear_refs")


def _status_kib(field: str) -> int | None:
    try:
        m = re.search(rf"^{field}:\s+(\d+) kB", _STATUS.read_text(), flags=re.MULTILINE)
    except OSError:
        return None
    return int(m.group(1)) if m else None


def _reset_hwm() -> bool:
    """Reset the kernel's peak-RSS counter of this process (Linux >= 4.0); False if not."""
    try:
        with _CLEAR_REFS.open("w") as f:
            f.write("5")
    except OSError:
        return False
    return _status_kib("VmHWM") is not None


class PeakMemory:
    """Peak resident memory of this process while the ``with`` block runs.

    On Linux the kernel's own high-water mark (``VmHWM``) is reset on entry and read on
    exit, which is exact and catches allocations made by C libraries (MKL, SuperLU) as
    well as numpy's. Elsewhere a thread samples the RSS with psutil every millisecond,
    which can miss very short peaks.

    Attributes
    ----------
    start : int
        RSS on entry (bytes).
    peak : int
        Highest RSS during the block (bytes).
    method : str
        ``"VmHWM"`` or ``"psutil sampling"``.
    """

    def __init__(self, interval: float = 1e-3) -> None:
        self.interval = interval
        self.start = 0
        self.peak = 0
        self.method = ""
        self._proc = psutil.Process()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    @property
    def increment(self) -> int:
        """Peak above the RSS on entry (bytes): what the block itself needed."""
        return max(self.peak - self.start, 0)

    def __enter__(self) -> PeakMemory:
        gc.collect()
        self.start = self._proc.memory_info().rss
        self.peak = self.start
        if _reset_hwm():
            self.method = "VmHWM"
        else:
            self.method = "psutil sampling"
            self._stop.clear()
            self._thread = threading.Thread(target=self._sample, daemon=True)
            self._thread.start()
        return self

    def _sample(self) -> None:
        while not self._stop.is_set():
            self.peak = max(self.peak, self._proc.memory_info().rss)
            time.sleep(self.interval)

    def __exit__(self, *exc: object) -> None:
        if self._thread is not None:
            self._stop.set()
            self._thread.join()
            self._thread = None
        hwm = _status_kib("VmHWM") if self.method == "VmHWM" else None
        now = self._proc.memory_info().rss
        self.peak = max(self.peak, now, 1024 * hwm if hwm is not None else 0)


# --- timing -----------------------------------------------------------------------------


@dataclass
class Measurement:
    """Timings of repeated calls of one function.

    Attributes
    ----------
    best : float
        Fastest wall time (s).
    times : list of float
        Every wall time (s), in order.
    peak_increment : int
        Peak RSS above the RSS before the first call (bytes), measured on the first call.
    peak : int
        Peak RSS of the process during the first call (bytes).
    result : Any
        What the last call returned.
    """

    best: float
    times: list[float]
    peak_increment: int
    peak: int
    result: Any

    @property
    def n(self) -> int:
        """Number of calls timed."""
        return len(self.times)


def measure(fn: Callable[[], Any], repeat: int = 1, budget: float = 0.0) -> Measurement:
    """Call ``fn`` up to ``repeat`` times and keep the best wall time.

    The first call also measures peak memory. Further calls are made only while the
    time spent so far plus one more call stays within ``budget`` seconds, so large cases
    run once and small ones are the best of several.

    Parameters
    ----------
    fn : callable
        No arguments; its result of the last call is kept (earlier ones are dropped
        before the next call, so they do not inflate memory).
    repeat : int
        Most calls.
    budget : float
        Seconds that the repeats may take in all.

    Returns
    -------
    Measurement
    """
    with PeakMemory() as mem:
        t0 = time.perf_counter()
        result = fn()
        times = [time.perf_counter() - t0]
    while len(times) < repeat and sum(times) + min(times) <= budget:
        result = None
        gc.collect()
        t0 = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t0)
    return Measurement(min(times), times, mem.increment, mem.peak, result)


# --- result files -----------------------------------------------------------------------


@dataclass(frozen=True)
class Column:
    """One column of a results table: the row key, its header and a format spec."""

    key: str
    header: str
    fmt: str = ""

    def cell(self, row: Mapping[str, Any]) -> str:
        """The formatted value of this column in ``row`` (blank when missing)."""
        value = row.get(self.key)
        if value is None or value == "":
            return "-"
        if isinstance(value, float) and value != value:  # NaN
            return "-"
        try:
            return format(value, self.fmt)
        except (TypeError, ValueError):
            return str(value)


def write_csv(path: Path, rows: Sequence[Mapping[str, Any]], keys: Sequence[str]) -> None:
    """Write ``rows`` (dicts) as CSV with the columns ``keys``; missing values blank."""
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(keys), extrasaction="ignore")
        w.writeheader()
        for row in rows:
            w.writerow({k: ("" if row.get(k) is None else row.get(k)) for k in keys})


def markdown_table(rows: Iterable[Mapping[str, Any]], columns: Sequence[Column]) -> str:
    """A GitHub-flavoured markdown table of ``rows``."""
    lines = [
        "| " + " | ".join(c.header for c in columns) + " |",
        "|" + "|".join("---:" if c.fmt else "---" for c in columns) + "|",
    ]
    lines += ["| " + " | ".join(c.cell(r) for c in columns) + " |" for r in rows]
    return "\n".join(lines)


def write_markdown(
    path: Path,
    title: str,
    info: Mapping[str, str],
    sections: Sequence[tuple[str, str]],
) -> None:
    """Write a markdown report: a title, the machine info, then ``(heading, body)`` sections."""
    parts = [f"# {title}", "", "| machine | |", "|---|---|"]
    parts += [f"| {k} | {v} |" for k, v in info.items()]
    for heading, body in sections:
        parts += ["", f"## {heading}", "", body.rstrip()]
    path.write_text("\n".join(parts) + "\n")


def plot_loglog(
    path: Path,
    series: Mapping[str, tuple[Sequence[float], Sequence[float]]],
    *,
    title: str,
    xlabel: str = "DOFs",
    ylabel: str = "time (s)",
) -> None:
    """Save a log-log line plot of several ``label -> (x, y)`` series as a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 5))
    markers = "osD^vP*X<>"
    for i, (label, (x, y)) in enumerate(series.items()):
        pts = [(a, b) for a, b in zip(x, y) if b is not None and b == b and b > 0]
        if pts:
            xs, ys = zip(*pts)
            ax.loglog(xs, ys, marker=markers[i % len(markers)], label=label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
