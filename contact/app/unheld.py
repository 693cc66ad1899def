"""A run that loses its free body: it stops at the first frame not held.

A free body that its contacts do not hold has no place at the end of that frame (statics
says only that it goes), so no later frame can start from a defined state.
So :func:`contact.grasp.run` stops at the first frame whose result is not held (exit
status 1, everything solved so far written), and the frames asked for after it are
reported as not solved, with why: under ``"not_solved"`` in ``summary.json``
(:func:`add_not_solved`), in one stdout line (:func:`not_solved_line`), on stderr
(:func:`not_solved_message`), and in the closing line's verdict (:func:`closing_line`).
A later frame that cannot be set up (a bone the keyframes close through where the ball
went) stops the run the same way, its own frame first among those not solved
(:func:`cannot_set_up`, exit status 2).
"""

from __future__ import annotations

import shlex
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from ..output.summary import update_summary
from ..solver.results import FrameResult
from .report import SUMMARY_KEYS, parse_line, summary_line

__all__ = [
    "NOT_SOLVED_KEYS",
    "add_not_solved",
    "cannot_set_up",
    "closing_line",
    "lost",
    "not_solved",
    "not_solved_line",
    "not_solved_message",
]

#: The keys of the not-solved line on stdout, in order.
NOT_SOLVED_KEYS = ("not_solved", "t", "why")


def lost(result: FrameResult) -> bool:
    """Whether the frame lost a free body: not held by its contacts (``held`` False)."""
    return result.held is False


def not_solved(
    index: int, time: float, result: FrameResult, rest: Sequence[tuple[int, float]]
) -> list[dict[str, Any]]:
    """The records of the frames left unsolved after frame ``index`` lost its body.

    Parameters
    ----------
    index, time : int, float
        The frame not held, where the run stops.
    result : FrameResult
        Its solve (its ``stop_reason`` says which body and which way it went).
    rest : sequence of (int, float)
        The frames asked for after it: index and time.

    Returns
    -------
    list of dict
        ``{"index", "time", "reason"}`` each, the reason naming the frame that lost the
        body and its stop reason.
    """
    why = (
        f"not solved: the body was lost at frame {index} (t = {time:g}), where the run "
        f"stopped: {result.stop_reason}"
    )
    return [{"index": int(i), "time": float(t), "reason": why} for i, t in rest]


def cannot_set_up(
    time: float, error: Exception, frames: Sequence[tuple[int, float]]
) -> list[dict[str, Any]]:
    """The records of the frames left unsolved where the frame at ``time`` could not be set up.

    ``frames``: that frame and those asked for after it (index, time); ``error`` why.
    """
    why = f"not solved: the frame at t = {time:g} could not be set up: {error}"
    return [{"index": int(i), "time": float(t), "reason": why} for i, t in frames]


def add_not_solved(path: str | Path, records: Sequence[Mapping[str, Any]]) -> None:
    """Add the frames not solved to a written ``summary.json`` (top-level ``not_solved``).

    ``all_converged`` and ``all_realistic`` become false: a frame not solved is neither.

    Raises
    ------
    OutputError
        When the file cannot be read or written back.
    """
    update_summary(
        path,
        {"not_solved": [dict(r) for r in records], "all_converged": False,
         "all_realistic": False},
        "the frames not solved",
    )  # fmt: skip


def not_solved_line(records: Sequence[Mapping[str, Any]]) -> str:
    """The stdout line of the frames not solved: indices, times and why (one reason)."""
    values = [
        ",".join(str(r["index"]) for r in records),
        ",".join(f"{float(r['time']):g}" for r in records),
        records[0]["reason"],
    ]
    pairs = zip(NOT_SOLVED_KEYS, values, strict=True)
    return " ".join(f"{k}={shlex.quote(str(v))}" for k, v in pairs)


def not_solved_message(records: Sequence[Mapping[str, Any]]) -> str:
    """The stderr line of the frames not solved: ``frames 2, 3 (t = 1, 1.5): <reason>``."""
    which = ", ".join(str(r["index"]) for r in records)
    when = ", ".join(f"{float(r['time']):g}" for r in records)
    word = "frame" if len(records) == 1 else "frames"
    return f"{word} {which} (t = {when}): {records[0]['reason']}"


def closing_line(
    entries: Sequence[Mapping[str, Any]], results: str | Path, unsolved: Sequence[Mapping]
) -> str:
    """The report's closing line; its verdict unrealistic where frames were not solved."""
    line = summary_line(entries, results)
    if not unsolved:
        return line
    values = parse_line(line)
    values["verdict"] = "unrealistic"
    return " ".join(f"{k}={shlex.quote(values[k])}" for k in SUMMARY_KEYS)
