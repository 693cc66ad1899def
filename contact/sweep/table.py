"""A sweep's table and plot: one row per run from its ``summary.json``; ``sweep.csv``, a PNG.

:func:`figures` turns one results folder's summary into the row's figures (it runs in the
worker that ran the scene, or in the sweep's process for a run resumed from its folder);
:func:`write_table` writes ``sweep.csv`` (and ``sweep.parquet`` where pyarrow imports);
:func:`plot` draws a chosen figure against the first varied key, one line per value of the
second, its axes labelled with their units; a run that did not converge is a hollow marker.

``held`` is three-valued, as in a frame's record: ``False`` when a frame's free body slipped
away, ``None`` (an empty cell) when some frame could not tell (it did not converge, or no
body is free), ``True`` only when every frame held.
"""

from __future__ import annotations

import csv
import json
import math
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

__all__ = [
    "COLUMNS", "UNITS", "columns", "figures", "plot", "read_summary", "unit", "write_table",
]

#: The table's columns after the run id and the varied keys.
COLUMNS = (
    "status", "exit_status", "converged", "realistic", "held", "least_grip_scale",
    "max_bone_force", "max_bone", "grip_force", "iterations", "seconds",
)  # fmt: skip


#: Units of the table's figures and of the scene keys (by their last name, docs/scene.md);
#: ``"-"`` for a ratio. A key not here is labelled without one.
UNITS = {
    "grip_force": "N", "max_bone_force": "N", "seconds": "s", "iterations": "count",
    "least_grip_scale": "-", "gravity": "m/s²", "radius": "m", "thickness": "m",
    "pressure": "Pa", "mesh_size": "m", "center": "m", "E": "Pa", "nu": "-",
    "density": "kg/m³", "friction": "-", "rotation": "degrees", "bone_force_limit": "N",
    "time": "s", "times": "s", "start": "s", "stop": "s", "angles": "degrees",
    "epsilon": "m", "press": "m", "point": "m", "force": "N", "force_tolerance": "-",
}  # fmt: skip


def unit(key: str) -> str | None:
    """The unit of a table column or of a varied key path (by its last name), or None."""
    name = re.sub(r"\[\d+\]", "", key).rsplit(".", 1)[-1]
    return UNITS.get(name)


def _label(key: str) -> str:
    u = unit(key)
    return key if u is None else f"{key} ({u})"


def read_summary(results: Path, least: bool) -> dict | None:
    """A results folder's complete ``summary.json`` (with ``least_grip`` when asked), or None."""
    try:
        summary = json.loads((Path(results) / "summary.json").read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(summary, dict) or "frames" not in summary:
        return None
    if least and "least_grip" not in summary:
        return None
    return summary


def _magnitude(v: Any) -> float:
    if isinstance(v, Mapping):
        v = v.get("magnitude", 0.0)
    try:
        return float(v)
    except (TypeError, ValueError):
        return 0.0


def figures(summary: Mapping[str, Any]) -> dict[str, Any]:
    """One run's figures from its summary (see docs/sweep.md for each).

    Returns
    -------
    dict
        ``exit_status`` (0 every frame realistic, else 1, as ``contact.grasp``),
        ``converged``, ``realistic``, ``held`` (False a frame not held, None a frame that
        cannot tell, True every frame held), ``least_grip_scale``
        (None unless searched), ``max_bone_force`` (N) and ``max_bone`` over all frames,
        ``grip_force`` at the last frame (N), ``iterations`` (summed over the frames).
    """
    frames = summary.get("frames", [])
    best, bone = 0.0, ""
    for f in frames:
        for name, v in (f.get("bone_forces") or {}).items():
            m = _magnitude(v)
            if m > best:
                best, bone = m, name
    least = summary.get("least_grip")
    realistic = bool(summary.get("all_realistic"))
    helds = [f.get("held") for f in frames]
    held = (False if any(h is False for h in helds)
            else True if helds and all(h is True for h in helds) else None)  # fmt: skip
    return {
        "exit_status": 0 if realistic else 1,
        "converged": bool(summary.get("all_converged")),
        "realistic": realistic,
        "held": held,
        "least_grip_scale": least.get("scale") if isinstance(least, Mapping) else None,
        "max_bone_force": best,
        "max_bone": bone,
        "grip_force": float(frames[-1].get("grip_force", 0.0)) if frames else 0.0,
        "iterations": int(sum(f.get("iterations", 0) for f in frames)),
    }


def columns(keys: Sequence[str], least: bool) -> list[str]:
    """The table's header: ``run``, the varied keys, then :data:`COLUMNS`."""
    return ["run", *keys, *(c for c in COLUMNS if least or c != "least_grip_scale")]


def _cell(v: Any) -> Any:
    if isinstance(v, (list, tuple, dict)):
        return json.dumps(v)
    return "" if v is None else v


def write_table(rows: Sequence[Mapping[str, Any]], header: Sequence[str], out: Path) -> list[Path]:
    """Write ``sweep.csv`` (and ``sweep.parquet`` where pyarrow imports); the files written."""
    out = Path(out)
    path = out / "sweep.csv"
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for row in rows:
            w.writerow([_cell(row.get(c)) for c in header])
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return [path]
    table = pa.table({c: _column(pa, [r.get(c) for r in rows]) for c in header})
    pq.write_table(table, out / "sweep.parquet")
    return [path, out / "sweep.parquet"]


def _column(pa: Any, values: list[Any]) -> Any:
    """One Parquet column: typed, with nulls where the CSV is empty (a failed run's figures).

    Lists and tables are JSON text, as in the CSV; a column of mixed types (a varied key
    given a number and a string) is written as the CSV's text.
    """
    cells = [None if v is None else _cell(v) for v in values]
    try:
        return pa.array(cells)
    except (pa.ArrowInvalid, pa.ArrowTypeError, TypeError):
        return pa.array([None if v is None else str(_cell(v)) for v in values], pa.string())


def _number(v: Any) -> float | None:
    try:
        x = float(v)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def plot(rows: Sequence[Mapping[str, Any]], keys: Sequence[str], y: str, path: Path) -> Path:
    """Draw :func:`_figure` into ``path`` (PNG)."""
    import matplotlib.pyplot as plt

    fig = _figure(rows, keys, y)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return Path(path)


def _figure(rows: Sequence[Mapping[str, Any]], keys: Sequence[str], y: str) -> Any:
    """``y`` against the first varied key (its values, or their order where not numbers).

    Keys given one value are passed over; a second varied key gives one line per value;
    failed runs are left out; a run that did not converge is a hollow marker (its figures
    are those of an unconverged state), with a legend entry saying so.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    keys = [k for k in keys if len({json.dumps(r[k]) for r in rows}) > 1] or list(keys[:1])
    x_key = keys[0]
    xs = [r[x_key] for r in rows]
    numeric = all(_number(v) is not None for v in xs)
    ticks = list(dict.fromkeys(json.dumps(v) for v in xs))
    groups: dict[str, list[Mapping[str, Any]]] = {}
    for r in rows:
        label = f"{keys[1]} = {json.dumps(r[keys[1]])}" if len(keys) > 1 else ""
        groups.setdefault(label, []).append(r)
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    hollow = False
    for label, members in groups.items():
        pts = []
        for r in members:
            yv = _number(r.get(y)) if r.get("status") == "done" else None
            if yv is None:
                continue
            xv = _number(r[x_key]) if numeric else ticks.index(json.dumps(r[x_key]))
            pts.append((xv, yv, r.get("converged") is True))
        pts.sort()
        (line,) = ax.plot([p[0] for p in pts], [p[1] for p in pts], "-", label=label or None)
        for ok in (True, False):
            sel = [p for p in pts if p[2] is ok]
            hollow |= not ok and bool(sel)
            ax.plot([p[0] for p in sel], [p[1] for p in sel], "o", color=line.get_color(),
                    markerfacecolor=None if ok else "none", linestyle="none")  # fmt: skip
    if not numeric:
        ax.set_xticks(range(len(ticks)), ticks, rotation=30, ha="right")
    ax.set_xlabel(_label(x_key) if numeric else x_key)
    ax.set_ylabel(_label(y))
    ax.set_title(f"{y} against {x_key}")
    handles, labels = ax.get_legend_handles_labels()
    if hollow:
        handles.append(Line2D([], [], marker="o", markerfacecolor="none", color="grey",
                              linestyle="none"))  # fmt: skip
        labels.append("did not converge")
    if handles:
        ax.legend(handles, labels, fontsize="small")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig
