"""The SfePy comparison on tetrahedral octants judged and tabulated: rule, verdict, columns.

When a SfePy run of :mod:`benchmarks.sfepy_patch` has the same accuracy as ours
(:func:`same_accuracy`), the verdict on each mesh and press (:func:`verdicts`) and the
columns of its table and CSV file.
"""

from __future__ import annotations

from typing import Any

from ._common import Column

__all__ = [
    "COLUMNS",
    "CSV_KEYS",
    "GOAL_TIME_RATIO",
    "SAME_ACCURACY_PP",
    "same_accuracy",
    "verdicts",
]

#: SfePy's errors may exceed ours by this much (percentage points) for the same accuracy.
SAME_ACCURACY_PP = 0.5
#: The goal: ours in at most this fraction of SfePy's time at the same accuracy.
GOAL_TIME_RATIO = 0.1


def same_accuracy(row: dict[str, Any], ours: dict[str, Any]) -> bool:
    """Whether a SfePy run converged with both errors within ours + SAME_ACCURACY_PP."""
    return (
        row["converged"] == "yes"
        and abs(row["radius_err_pct"]) <= abs(ours["radius_err_pct"]) + SAME_ACCURACY_PP
        and abs(row["pressure_err_pct"]) <= abs(ours["pressure_err_pct"]) + SAME_ACCURACY_PP
    )


def _excess(row: dict[str, Any], ours: dict[str, Any]) -> float:
    """How far (percentage points) a run's worse error lies past ours: the least is the most
    accurate run."""
    return max(
        abs(row["radius_err_pct"]) - abs(ours["radius_err_pct"]),
        abs(row["pressure_err_pct"]) - abs(ours["pressure_err_pct"]),
    )


def _fastest(rows: list[dict], ours: dict) -> dict | None:
    """SfePy's fastest run at the same accuracy as ``ours`` (same mesh and press)."""
    same = [r for r in rows if r["code"] == "SfePy" and r["same_accuracy"] == "yes"]
    return min(same, key=lambda r: r["total_s"]) if same else None


def verdicts(rows: list[dict]) -> tuple[list[str], bool | None]:
    """One summary line per mesh and press, and whether the goal is met on all of them.

    Returns
    -------
    lines : list of str
    met : bool or None
        None when no SfePy run was made.
    """
    lines, met = [], []
    for ours in (r for r in rows if r["code"] == "ours"):
        key = (ours["fine_size"], ours["depth"])
        theirs = [r for r in rows if r["code"] == "SfePy" and (r["fine_size"], r["depth"]) == key]
        head = f"- {ours['dofs']:,} DOFs, d/R {ours['depth']:g}: "
        if not theirs:
            lines.append(head + "no SfePy run.")
            continue
        best = _fastest(theirs, ours)
        note = ""
        if best is None:
            best = min(theirs, key=lambda r: (r["converged"] != "yes", _excess(r, ours)))
            note = (
                " (no SfePy run reaches the same accuracy: against its most accurate run, "
                f"k = {best['penalty']:.0e}, {_excess(best, ours):+.2f} points past ours"
                + ("" if best["converged"] == "yes" else ", not converged")
                + ")"
            )
        ratio = ours["total_s"] / best["total_s"]
        ok = ratio <= GOAL_TIME_RATIO
        met.append(ok)
        lines.append(
            head + f"ours / SfePy's fastest run at the same accuracy = {ratio:.3f} "
            f"(goal <= {GOAL_TIME_RATIO:g}: {'met' if ok else 'missed'}); ours "
            f"{ours['total_s']:.2f} s (radius {ours['radius_err_pct']:+.2f} %, peak p "
            f"{ours['pressure_err_pct']:+.2f} %), SfePy k = {best['penalty']:.0e} "
            f"{best['total_s']:.2f} s (radius {best['radius_err_pct']:+.2f} %, peak p "
            f"{best['pressure_err_pct']:+.2f} %, {best['runs']} run(s))" + note + "."
        )
    return lines, (all(met) if met else None)


COLUMNS = (
    Column("dofs", "DOFs", ","),
    Column("depth", "d/R", ".3f"),
    Column("cells_per_a", "cells per a", ".1f"),
    Column("code", "code", ""),
    Column("penalty", "penalty k (E/R)", ".0e"),
    Column("iterations", "iterations", "d"),
    Column("converged", "converged", ""),
    Column("contacts", "contact nodes", "d"),
    Column("radius_err_pct", "radius err (%)", "+.2f"),
    Column("pressure_err_pct", "peak p err (%)", "+.2f"),
    Column("same_accuracy", "same accuracy", ""),
    Column("force_vs_ours_pct", "force vs ours (%)", "+.3f"),
    Column("total_s", "time (s)", ".2f"),
    Column("runs", "runs", "d"),
    Column("load1", "load (1 min)", ".1f"),
    Column("ours_over_this", "ours / this", ".3f"),
)

CSV_KEYS = [
    "fine_size",
    "dofs",
    "depth",
    "cells_per_a",
    "code",
    "penalty",
    "iterations",
    "converged",
    "contacts",
    "force",
    "force_vs_ours_pct",
    "radius_err_pct",
    "pressure_err_pct",
    "same_accuracy",
    "equilibrium",
    "total_s",
    "runs",
    "assemble_s",
    "factor_s",
    "setup_s",
    "matrix_s",
    "solve_s",
    "residual_s",
    "ours_over_this",
    "load1",
    "load",
]
