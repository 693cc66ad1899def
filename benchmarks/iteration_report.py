"""The contact-iteration study's report: its goals and the markdown tables.

:func:`_goals` measures the study's goals on the frames of :mod:`benchmarks.iteration`;
:func:`_write_report` writes ``iteration.md``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ._common import Column, markdown_table, write_markdown
from .iteration_cases import (
    CUP_LEVELS,
    GOAL_REFINEMENT,
    GOAL_UPDATES,
    HERTZ_SIZES,
    MAX_ITERATIONS,
    PRESS,
    REFINE_RATIOS,
    SCENES,
    variants,
)

__all__ = ["DETAIL_COLUMNS", "GOAL_COLUMNS"]


# --- goals --------------------------------------------------------------------------------


def _goals(rows: list[dict], quick: bool) -> list[dict]:
    """The goal rows: measured value and met / missed."""
    goals: list[dict] = []
    for scene in SCENES:
        for ratio in REFINE_RATIOS[quick]:
            sel = [
                r
                for r in rows
                if r["study"] == "refinement" and r["scene"] == scene and r["ratio"] == ratio
            ]
            if not sel:
                continue
            n = np.array([r["iterations"] for r in sel], dtype=float)
            mean = float(n.mean())
            dev = float(np.abs(n / mean - 1.0).max())
            spread = float(n.max() / n.min() - 1.0)
            ok = all(r["converged"] for r in sel)
            goals.append(
                {
                    "goal": f"contact iterations over {len(sel)} refinements: within +-30 %",
                    "case": f"{scene}, E ratio {ratio:g}, contact space",
                    "measured": (
                        f"{', '.join(r['cell'] for r in sel)} (mean {mean:.2f}); largest "
                        f"deviation from the mean {100 * dev:.0f} %; max/min - 1 = "
                        f"{100 * spread:.0f} %"
                    ),
                    "verdict": _flag(ok and dev <= GOAL_REFINEMENT)
                    + (
                        ""
                        if spread <= GOAL_REFINEMENT or not ok or dev > GOAL_REFINEMENT
                        else " (max/min - 1 over 30 %)"
                    ),
                }
            )
    for scene in SCENES:
        for v in variants(scene, quick):
            for study, what in (("ratio", "study-1 mesh"), ("refinement", "every mesh")):
                sel = [
                    r
                    for r in rows
                    if r["study"] == study and r["scene"] == scene and r["variant"] == v.label
                ]
                if not sel:
                    continue
                ok = all(r["converged"] and r["iterations"] <= GOAL_UPDATES for r in sel)
                failed = [r for r in sel if not r["converged"]]
                most = max(
                    (r for r in sel if r["converged"]), key=lambda r: r["iterations"], default=None
                )
                goals.append(
                    {
                        "goal": f"contact-set updates, E ratio 0.01 to 100: <= {GOAL_UPDATES}",
                        "case": f"{scene}, {v.label}, {what}",
                        "measured": (
                            "; ".join(
                                f"E ratio {r['ratio']:g}"
                                + (f", {r['mesh']}" if study == "refinement" else "")
                                + f": {r['cell']}"
                                for r in sel
                            )
                            + (
                                f" (most when converged: {most['iterations']})"
                                if most is not None
                                else ""
                            )
                            + (f"; {len(failed)} of {len(sel)} not converged" if failed else "")
                        ),
                        "verdict": _flag(ok),
                    }
                )
    return goals


def _flag(ok: bool) -> str:
    return "met" if ok else "MISSED"


# --- the report ---------------------------------------------------------------------------

GOAL_COLUMNS = (
    Column("goal", "goal"),
    Column("case", "case"),
    Column("measured", "measured"),
    Column("verdict", "verdict"),
)
DETAIL_COLUMNS = (
    Column("scene", "scene"),
    Column("ratio", "E ratio", "g"),
    Column("mesh", "mesh"),
    Column("press", "press (m)", "g"),
    Column("dofs", "DOFs", ","),
    Column("variant", "algorithm"),
    Column("cell", "iterations"),
    Column("contacts", "contacts"),
    Column("back_solves_by_body", "back-solves"),
    Column("partial_solves", "partial solves"),
    Column("contact_s", "contact solve (s)", ".2f"),
    Column("force_z", "force on hand / block, z (N)", ".4g"),
    Column("force_vs_cs_pct", "vs contact space (%)", "+.2f"),
    Column("penetration_ratio", "penetration / cell", ".1e"),
)


def _pivot(rows: list[dict], scene: str, key: str, fmt: str) -> str:
    """A table of one scene's ratio study: a row per ratio, a column per variant."""
    sel = [r for r in rows if r["study"] == "ratio" and r["scene"] == scene]
    labels = list(dict.fromkeys(r["variant"] for r in sel))
    table = []
    for ratio in dict.fromkeys(r["ratio"] for r in sel):
        line: dict[str, Any] = {"ratio": ratio}
        for r in sel:
            if r["ratio"] == ratio:
                line[r["variant"]] = r.get(key)
        table.append(line)
    cols = [Column("ratio", "E ratio", "g"), *(Column(lb, lb, fmt) for lb in labels)]
    return markdown_table(table, cols)


def _notes(rows: list[dict]) -> str:
    """Frames that failed, seed answers away from contact space, penetrations left."""
    lines = []
    failed = [r for r in rows if not r["converged"]]
    if failed:
        lines.append("Frames that did not converge (stop reason):")
        lines += [
            f"- {r['study']}: {r['scene']}, E ratio {r['ratio']:g}, {r['mesh']}, press "
            f"{r['press']:g}: {r['variant']}: {r['iterations']} iterations, {r['stop_reason']}"
            for r in failed
        ]
    off = [
        r
        for r in rows
        if r["converged"]
        and r["algorithm"] == "seed"
        and abs(r.get("force_vs_cs_pct") or 0.0) > 2.0
    ]
    if off:
        lines.append("")
        lines.append(
            "Seed frames that converged to a contact force (the resultant on the hand or "
            "block) more than 2 % away from contact space's on the same frame (another "
            "contact set: the rows are linearised where each algorithm's iterates met the "
            "master surface):"
        )
        lines += [
            f"- {r['study']}: {r['scene']}, E ratio {r['ratio']:g}, {r['mesh']}, press "
            f"{r['press']:g}: {r['variant']}: {r['force_vs_cs_pct']:+.1f} % ("
            f"{r['iterations']} iterations, penetration / cell {r['penetration_ratio']:.1e})"
            for r in off
        ]
    deep = [r for r in rows if r["converged"] and r["penetration_ratio"] > 1e-3]
    if deep:
        lines.append("")
        lines.append(
            "Converged frames that leave a node inside its master by more than the gap "
            "tolerance (1e-3 of its local cell size; penetration / cell):"
        )
        lines += [
            f"- {r['study']}: {r['scene']}, E ratio {r['ratio']:g}, {r['mesh']}, press "
            f"{r['press']:g}: {r['variant']}: {r['penetration_ratio']:.1e}"
            for r in deep
        ]
    heavy = [r for r in rows if r["algorithm"] == "contact-space" and r["back_solves"] > 100]
    if heavy:
        lines.append("")
        lines.append(
            "Contact-space frames with more than 100 full back-solves (rows whose compliance "
            "did not come from partial solves on a body's marked contact zone):"
        )
        lines += [
            f"- {r['study']}: {r['scene']}, E ratio {r['ratio']:g}, {r['mesh']}, press "
            f"{r['press']:g}: {r['back_solves_by_body']} (partial {r['partial_solves']}), "
            f"contact solve {r['contact_s']:.1f} s"
            for r in heavy
        ]
    return "\n".join(lines) if lines else "Every frame converged."


def _write_report(
    folder: Path, info: dict, rows: list[dict], goals: list[dict], quick: bool
) -> None:
    q = " (quick)" if quick else ""
    by_study = {s: [r for r in rows if r["study"] == s] for s in ("ratio", "refinement", "press")}
    sections = [
        (
            "Goals" + q,
            markdown_table(goals, GOAL_COLUMNS)
            + "\n\nRefinement: met when each mesh's iterations lie within +-30 % of the "
            "mean of the three (max/min - 1 is given too, a stricter reading); a frame "
            "that does not converge misses. Updates: every frame converged in at most "
            f"{GOAL_UPDATES} iterations (for contact space, contact-set solves; for the "
            "seed loop, loops of its steps 2 to 5). The goal is the solver's (contact "
            "space, the default); the seed loop's rows are given for comparison.",
        ),
        (
            "Iterations against the stiffness ratio: hand cup" + q,
            _pivot(rows, "hand cup", "cell", "")
            + f"\n\nMesh {CUP_LEVELS[quick][0].name}, press {PRESS * 1e3:g} mm; limit "
            f"{MAX_ITERATIONS[quick]} iterations. The seed loop's Dirichlet body is the ball.",
        ),
        (
            "Iterations against the stiffness ratio: sphere on block" + q,
            _pivot(rows, "sphere-block", "cell", "")
            + f"\n\nFine size {HERTZ_SIZES[quick][0]:g} m (R = 1 m, interference 0.01 m). "
            "Seed rows: the sphere's nodes against the block (one way), the sphere the "
            "Dirichlet body, unless the label says otherwise.",
        ),
        (
            "Contact solve time (s) against the stiffness ratio: hand cup" + q,
            _pivot(rows, "hand cup", "contact_s", ".2f"),
        ),
        (
            "Contact solve time (s) against the stiffness ratio: sphere on block" + q,
            _pivot(rows, "sphere-block", "contact_s", ".2f"),
        ),
        (
            "Every frame of the stiffness ratio study" + q,
            markdown_table(by_study["ratio"], DETAIL_COLUMNS)
            + "\n\nBack-solves: columns of a body's compliance computed with its "
            "factorisation (n_back_solves), partial solves: those computed on the marked "
            "DOFs only (n_partial_solves, where the solver has them). The seed loop's "
            "Neumann side adds one full solve of the other body per iteration, not "
            "counted there. vs contact space: the resultant contact force on the hand "
            "(block) along z against contact space's on the same frame (blank where the "
            "seed loop diverged). Contact solve: the "
            "frame's wall time less the bodies' "
            "factorisation (done in the frame when the bodies factor lazily; "
            "`factor_s` in the CSV).",
        ),
        (
            "Iterations against mesh refinement (contact space)" + q,
            markdown_table(by_study["refinement"], DETAIL_COLUMNS)
            + "\n\nHand cup meshes: the shipped hand (coarse or fine) and the ball's cells "
            "(divisions of its core cube / layers to the sphere); Hertz: the cell size at "
            "the contact of both graded meshes.",
        ),
        (
            "Iterations against the press depth (hand cup)" + q,
            markdown_table(by_study["press"], DETAIL_COLUMNS)
            + "\n\nThe press is the cup's rise. The ball's top touches the lowest skin "
            "node above its centre's footprint, which lies off its pole: the skin's nearest "
            "node is "
            + ", ".join(
                sorted({f"{1e3 * r['clearance']:.2f} mm ({r['mesh']})" for r in by_study["press"]})
            )
            + " from the ball at press 0, so the indentation is the press less that.",
        ),
        ("Notes" + q, _notes(rows)),
    ]
    write_markdown(folder / "iteration.md", "The contact iteration", info, sections)
