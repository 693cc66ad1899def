"""Coulomb friction: a frame's cost against the same frame frictionless, and its iterations.

Two studies, run together by ``python -m benchmarks friction [--quick]``:

1. *cost*: a frame with friction against the same frame without it, each the fastest of
   :data:`REPEAT` runs taken in turn in one run (goal: at most :data:`GOAL_RATIO` times).
   Scenes: the hand cup (:func:`benchmarks.scenes.hand_cup`, every pair at ``mu =``
   :data:`MU`), the two-pad pinch (``examples/pads.toml``: its frames in order, the last
   one timed; frictionless, the ball is held by a frictionless table 0.1 mm into its
   bottom instead) and the bowl example (``examples/bowl.toml`` with ``[hand]
   friction = 0.5``, every frame in order, as ``python -m contact.grasp`` solves it). The
   frame's split: geometry, compliance rows (:meth:`ContactSpace.system`: the Delassus
   operator of the normal and tangential rows), the law (the semismooth Newton solve, or
   the frictionless LCP), the bodies' states, factorisation, the rest.
2. *iterations*: Newton steps per frame (summed over its contact-set updates) and the
   updates against ``mu`` (0.1 to 2), the stiffness ratio (0.01 to 100) and three mesh
   refinements (goal: within +-:data:`GOAL_REFINEMENT` of their mean), on the hand cup and
   on Hertz's sphere pressed into a block (:func:`contact.cases.hertz_bodies.hertz_scene`).
"""

from __future__ import annotations

from pathlib import Path

from ._common import machine_info, markdown_table, results_dir, write_csv, write_markdown
from .friction_cases import (
    GOAL_RATIO,
    GOAL_REFINEMENT,
    MU,
    MUS,
    PARTS,
    PRESS,
    REPEAT,
    _iteration,
    _iteration_cases,
    cost_rows,
    split,
)
from .friction_report import (
    COST_COLUMNS,
    GOAL_COLUMNS,
    ITER_COLUMNS,
    NOTES,
    SPLIT_COLUMNS,
    _plot,
    _refinement_goals,
    _split_rows,
    _summary,
)
from .iteration import _code_version

__all__ = [
    "GOAL_RATIO",
    "GOAL_REFINEMENT",
    "MU",
    "MUS",
    "PARTS",
    "REPEAT",
    "cost_rows",
    "run",
    "split",
]


def run(quick: bool = False, out: str | Path | None = None) -> list[dict]:
    """Run both studies and write ``friction.{csv,md,png}``.

    Parameters
    ----------
    quick : bool
        Small scenes, each once: seconds.
    out : path, optional
        Results folder; ``benchmarks/results`` (``.../quick``) by default.

    Returns
    -------
    list of dict
        The cost rows (``study == "cost"``), then one row per frame of study 2.
    """
    folder = results_dir(out, quick)
    info = machine_info()
    info["code"] = _code_version()
    cost = cost_rows(quick)
    for r in cost:
        print(
            f"[friction] {r['scene']}, {r['case']}: {r['frame_s']:.3f} s against "
            f"{r.get('free_frame_s', float('nan')):.3f} s ({r['ratio']:.2f})"
        )
    iters = [_iteration(*case, quick) for case in _iteration_cases(quick)]
    rows = cost + iters
    goals = _refinement_goals(iters)
    keys = list(dict.fromkeys(k for r in rows for k in r))
    write_csv(folder / "friction.csv", rows, keys)
    q = " (quick)" if quick else ""
    by = {s: [r for r in iters if r["study"] == s] for s in ("mu", "ratio", "refinement")}
    sections = [
        ("Summary" + q, _summary(cost, goals, rows)),
        (
            "Cost: a frame with friction against the same frame frictionless" + q,
            markdown_table(cost, COST_COLUMNS)
            + f"\n\nmu = {MU:g} on every pair of the hand cup and on the bowl example's "
            "hand; the pinch's pads carry its own. Each side is the fastest of "
            f"{REPEAT[quick]} runs, taken in turn. Newton steps: the semismooth Newton "
            "solve's, summed over the frame's contact-set updates; stick and slip: closed "
            "contacts at the end. The pinch and the bowl example solve their frames in "
            "order (the anchors carried) and reuse the ball's factorisation after the "
            "first frame; the hand cup's frames factor their bodies.",
        ),
        (
            "Where the time goes (s)" + q,
            markdown_table(_split_rows(cost), SPLIT_COLUMNS)
            + "\n\nCompliance rows: the Delassus operator of the rows (normal and "
            "tangential), from the bodies' factorisations; Newton / LCP: the frictional "
            "solve (dense Jacobians) or the frictionless LCP; states: the bodies' "
            "displacements under the forces; other: contact-set bookkeeping, anchors, "
            "tangential rows.",
        ),
        (
            "Refinement goal" + q,
            markdown_table(goals, GOAL_COLUMNS) + "\n\n`*`: not solved (counts as missed).",
        ),
        ("Newton steps against mu (E ratio 1)" + q, markdown_table(by["mu"], ITER_COLUMNS)),
        (
            f"Newton steps against the stiffness ratio (mu {MU:g})" + q,
            markdown_table(by["ratio"], ITER_COLUMNS),
        ),
        (
            "Newton steps against mesh refinement" + q,
            markdown_table(by["refinement"], ITER_COLUMNS)
            + f"\n\nHand cup: press {PRESS * 1e3:g} mm; Hertz: R = 1 m, interference 0.01 m, "
            "quarter model, pairs both ways.",
        ),
        ("Notes", NOTES),
    ]
    write_markdown(folder / "friction.md", "Coulomb friction: cost and iterations", info, sections)
    _plot(folder / "friction.png", cost, iters)
    return rows
