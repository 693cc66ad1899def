"""The terminal report of a grasp run: one line a frame, a closing line, and their parser.

Every line is ``key=value`` pairs separated by spaces, in a fixed order, with the units in
the keys; a value that could hold a space (a path) is quoted as a POSIX shell would, so
that :func:`parse_line` (``shlex``) reads every line back. A frame's line::

    frame=2 t=1 status=converged held=- verdict=realistic grip_N=0.199
    fingers_N=P:0,T:0,I:0.199,M:0,R:0,L:0 bone=index_distal bone_N=0.182 updates=3 s=0.74

(on one line): ``status`` is ``converged`` or the stop reason's head (``iteration-limit``,
``not-held``, ``penetration-left``, ...), ``held`` is ``yes``, ``no`` or ``-`` (no free
body), ``verdict`` is ``realistic`` or ``unrealistic``, ``fingers_N`` the normal force of
each hand part by its letter (``-`` without a hand), ``bone`` and ``bone_N`` the bone that
carries the largest force and its magnitude (``-`` and 0 where no bone carries any), ``updates`` the
contact-set updates and ``s`` the seconds of the frame. The closing line::

    frames=3 converged=3 held=- realistic=3 verdict=realistic results=results/finger_press

The figures are the frame's ``summary.json`` record's, rounded to 3 digits.

With ``--least-grip``, each trial of the search gives a progress line on stderr
(:func:`trial_line`) and the outcome one line on stdout after the closing line::

    least_grip=0.363 margin=2.75 forces_N=left_pad:0.363,right_pad:0.363
    bracket=0.361..0.363 steps=3 solves=3 s=2.1 note='held at 0.3632x, not at 0.3608x'

(on one line): ``least_grip`` is the least scale of the scene's grip that held (``none``
where none did up to the bound), ``margin`` its inverse, ``forces_N`` each force-driven
element's force at that scale, ``bracket`` the scales that did not and did hold.
"""

from __future__ import annotations

import shlex
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ..hand.fingers import part_letters

__all__ = [
    "FRAME_KEYS",
    "LEAST_GRIP_KEYS",
    "SUMMARY_KEYS",
    "frame_line",
    "least_grip_line",
    "parse_line",
    "pose_line",
    "summary_line",
    "trial_line",
]

#: The keys of a frame's line, in order.
FRAME_KEYS = (
    "frame",
    "t",
    "status",
    "held",
    "verdict",
    "grip_N",
    "fingers_N",
    "bone",
    "bone_N",
    "updates",
    "s",
)
#: The keys of the closing line, in order.
SUMMARY_KEYS = ("frames", "converged", "held", "realistic", "verdict", "results")
#: The keys of the least grip's line, in order.
LEAST_GRIP_KEYS = (
    "least_grip", "margin", "forces_N", "bracket", "limit", "steps", "solves", "s", "note",
)  # fmt: skip


def _num(x: float) -> str:
    """A figure in 3 significant digits, without a sign on zero."""
    return f"{float(x) + 0.0:.3g}"


def _status(entry: Mapping[str, Any]) -> str:
    if entry["converged"]:
        return "converged"
    head = str(entry["stop_reason"]).split(":")[0].strip()
    return "-".join(head.split()) or "stopped"


def _held(held: bool | None) -> str:
    return "-" if held is None else ("yes" if held else "no")


def _parts(values: Mapping[str, float]) -> str:
    """``P:0,T:0.31,I:0.52,...``: one letter per part, in the given order."""
    if not values:
        return "-"
    letters = part_letters(list(values))
    return ",".join(f"{c}:{_num(v)}" for c, v in zip(letters, values.values(), strict=True))


def frame_line(entry: Mapping[str, Any], seconds: float) -> str:
    """A frame's line, from its ``summary.json`` record.

    Parameters
    ----------
    entry : mapping
        The record (:func:`contact.output.summary.frame_entry`) with the ``grip_force``
        and ``fingers`` items.
    seconds : float
        Wall time of the frame (set-up, solve, writing).

    Returns
    -------
    str
        The line, keys :data:`FRAME_KEYS`.
    """
    bones = entry.get("bone_forces") or {}
    bone, force = "-", 0.0
    if bones:
        name, rec = max(bones.items(), key=lambda kv: kv[1]["magnitude"])
        if rec["magnitude"] > 0.0:
            bone, force = name, rec["magnitude"]
    fingers = entry.get("fingers") or {}
    values = [
        entry["index"],
        f"{float(entry['time']):g}",
        _status(entry),
        _held(entry.get("held")),
        "realistic" if entry["verdict"]["realistic"] else "unrealistic",
        _num(entry.get("grip_force", 0.0)),
        _parts({k: v["normal"] for k, v in fingers.items()}),
        bone,
        _num(force),
        entry["iterations"],
        f"{seconds:.2f}",
    ]
    return " ".join(f"{k}={shlex.quote(str(v))}" for k, v in zip(FRAME_KEYS, values, strict=True))


def summary_line(entries: Sequence[Mapping[str, Any]], results: str | Path) -> str:
    """The closing line: frames converged, held, realistic, the overall verdict, the folder.

    ``held`` counts the frames whose free bodies are held, ``-`` where no frame has a free
    body; ``verdict`` is ``realistic`` only when every frame is.
    """
    known = [e["held"] for e in entries if e.get("held") is not None]
    realistic = sum(bool(e["verdict"]["realistic"]) for e in entries)
    values = [
        len(entries),
        sum(bool(e["converged"]) for e in entries),
        sum(map(bool, known)) if known else "-",
        realistic,
        "realistic" if realistic == len(entries) else "unrealistic",
        str(results),
    ]
    return " ".join(f"{k}={shlex.quote(str(v))}" for k, v in zip(SUMMARY_KEYS, values, strict=True))


def _opt(x: float | None) -> str:
    return "-" if x is None else _num(x)


def least_grip_line(record: Mapping[str, Any]) -> str:
    """The least grip's line, from its ``summary.json`` item (keys :data:`LEAST_GRIP_KEYS`)."""
    forces = record.get("forces") or {}
    lo, hi = record["bracket"]
    values = [
        "none" if record["scale"] is None else _num(record["scale"]),
        _opt(record["margin"]),
        ",".join(f"{k}:{_num(v)}" for k, v in forces.items()) or "-",
        f"{_opt(lo)}..{_opt(hi)}",
        record.get("limit") or "-",
        record["steps"],
        record["solves"],
        f"{float(record['seconds']):.2f}",
        record.get("note", ""),
    ]
    return " ".join(
        f"{k}={shlex.quote(str(v))}" for k, v in zip(LEAST_GRIP_KEYS, values, strict=True)
    )


def trial_line(number: int, scale: float, holds: bool, h: float | None, reason: str) -> str:
    """A least-grip trial's progress line: its scale, held or not, its measure, why not."""
    head = "held" if holds else (reason.split(":")[0].strip() or "stopped")
    return (
        f"least_grip_trial={number} scale={_num(scale)} held={'yes' if holds else 'no'} "
        f"h={_opt(h)} why={shlex.quote('-'.join(head.split()))}"
    )


def pose_line(
    index: int, time: float, nearest: Mapping[str, float], tips: Mapping[str, float]
) -> str:
    """A ``--pose-only`` frame's line: where each hand part is from the ball (mm).

    ``nearest_mm``: the signed distance to the ball's surface of each part's skin node
    nearest it, by part letter; ``tip_mm``: each fingertip's (negative inside the ball).
    """
    near = _parts({k: 1e3 * v for k, v in nearest.items()})
    tip = _parts({k: 1e3 * v for k, v in tips.items()})
    return f"frame={index} t={time:g} nearest_mm={near} tip_mm={tip}"


def parse_line(line: str) -> dict[str, str]:
    """A report line as a dict of its keys to their values (as written, unquoted).

    Raises
    ------
    ValueError
        When a word of the line is not ``key=value``.
    """
    out = {}
    for word in shlex.split(line):
        key, sep, value = word.partition("=")
        if not sep or not key:
            raise ValueError(f"not a report line: {line!r}")
        out[key] = value
    return out
