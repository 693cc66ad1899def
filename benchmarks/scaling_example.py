"""The scaling study's second part: the README's example run end to end in a subprocess,
timed, its peak memory measured, and a traced run split into stages.
"""

from __future__ import annotations

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

from ._common import MIB

__all__ = ["EXAMPLE_SCENE", "EXAMPLE_TIMEOUT", "ROOT", "STAGES", "TRACE_SCRIPT", "run_example"]


#: The README's example, run from the repository root; longest it may run (s).
ROOT = Path(__file__).resolve().parents[1]
EXAMPLE_SCENE = "examples/grasp.toml"
EXAMPLE_TIMEOUT = 900.0


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
