"""The friction study's report: its refinement goal, tables, summary, notes and plot.

What :func:`benchmarks.friction.run` writes in ``friction.md`` and ``friction.png``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._common import Column
from .friction_cases import GOAL_RATIO, GOAL_REFINEMENT

__all__ = ["COST_COLUMNS", "GOAL_COLUMNS", "ITER_COLUMNS", "NOTES", "SPLIT_COLUMNS"]

#: What the tables need to be read right.
NOTES = """\
- Hertz's sphere on a block is a quarter model: the contacts on its two symmetry planes have
  a tangential row across the plane, a direction both bodies hold fixed there, so that row
  has no compliance (the contact on the axis has two). The Delassus operator is then
  singular (rank 175-177 of 198 rows at h = 0.045), each Newton step's Jacobian too (the
  solve falls back on least squares), and frames at E ratio 0.01 or 100, or mu = 2, stop at
  the Newton limit. Dropping the tangential rows that lie in both bodies' prescribed
  directions would make these frames well posed.
- The split comes from wrappers around the contact solve's parts; a profile (cProfile) of
  the hand cup at E ratio 0.1 puts the Newton time in the dense LU factorisation of each
  step's Jacobian (about 7 ms a step, 31 steps) and in least-squares fallbacks where that
  Jacobian is singular (about 55 ms each, 4 in the frame); the compliance rows cost about
  three times the frictionless ones (three rows a contact).
- The frictionless pinch stands on a table 0.1 mm into the ball's bottom (the solver
  reports the overlap at the first frame): on a table touching it exactly, the table
  carries all but about 1e-5 of the weight and the frame stops "not held".
"""


def _refinement_goals(rows: list[dict]) -> list[dict]:
    goals = []
    sel = [r for r in rows if r["study"] == "refinement"]
    for key in dict.fromkeys((r["scene"], r["ratio"], r["mu"]) for r in sel):
        group = [r for r in sel if (r["scene"], r["ratio"], r["mu"]) == key]
        steps = np.array([r["newton"] for r in group], dtype=float)
        spread = float(np.abs(steps / steps.mean() - 1).max())
        ok = all(r["solved"] for r in group) and spread <= GOAL_REFINEMENT
        goals.append(
            {
                "scene": key[0],
                "ratio": key[1],
                "mu": key[2],
                "newton": " / ".join(
                    f"{r['newton']}" + ("" if r["solved"] else "*") for r in group
                ),
                "updates": " / ".join(str(r["updates"]) for r in group),
                "spread": spread,
                "verdict": "met" if ok else "**missed**",
            }
        )
    return goals


# --- the report ---------------------------------------------------------------------------

COST_COLUMNS = (
    Column("scene", "scene"),
    Column("case", "case"),
    Column("dofs", "DOFs", ","),
    Column("free_frame_s", "frictionless (s)", ".3f"),
    Column("frame_s", "friction (s)", ".3f"),
    Column("ratio", "ratio", ".2f"),
    Column("met", "<= 2"),
    Column("free_updates", "updates, frictionless", "d"),
    Column("updates", "updates", "d"),
    Column("newton", "Newton steps", "d"),
    Column("stick", "stick", "d"),
    Column("slip", "slip", "d"),
    Column("residual", "residual", ".1e"),
)
SPLIT_COLUMNS = (
    Column("scene", "scene"),
    Column("case", "case"),
    Column("side", "side"),
    Column("geometry_s", "geometry", ".3f"),
    Column("rows_s", "compliance rows", ".3f"),
    Column("law_s", "Newton / LCP", ".3f"),
    Column("states_s", "states", ".3f"),
    Column("factor_s", "factorisation", ".3f"),
    Column("other_s", "other", ".3f"),
    Column("frame_s", "frame", ".3f"),
)
ITER_COLUMNS = (
    Column("scene", "scene"),
    Column("mesh", "mesh"),
    Column("dofs", "DOFs", ","),
    Column("ratio", "E ratio", "g"),
    Column("mu", "mu", "g"),
    Column("updates", "updates", "d"),
    Column("newton", "Newton steps", "d"),
    Column("per_update", "per update", ".1f"),
    Column("contacts", "contacts", "d"),
    Column("stick", "stick", "d"),
    Column("slip", "slip", "d"),
    Column("residual", "residual", ".1e"),
    Column("frame_s", "frame (s)", ".2f"),
    Column("stop_reason", "stop"),
)
GOAL_COLUMNS = (
    Column("scene", "scene"),
    Column("ratio", "E ratio", "g"),
    Column("mu", "mu", "g"),
    Column("newton", "Newton steps (3 meshes)"),
    Column("updates", "updates"),
    Column("spread", "largest deviation from the mean", ".0%"),
    Column("verdict", "+-30 %"),
)


def _split_rows(cost: list[dict]) -> list[dict]:
    out = []
    for r in cost:
        if "free_frame_s" in r:
            free = {k[5:]: v for k, v in r.items() if k.startswith("free_")}
            out.append({"scene": r["scene"], "case": r["case"], "side": "frictionless", **free})
        out.append({**r, "side": f"mu {r['mu']:g}"})
    return out


def _summary(cost: list[dict], goals: list[dict], rows: list[dict]) -> str:
    timed = [r for r in cost if r["met"] != "-"]
    worst = max(timed, key=lambda r: r["ratio"])
    met = sum(r["ratio"] <= GOAL_RATIO for r in timed)
    lines = [
        f"Cost: friction / frictionless <= {GOAL_RATIO:g} on {met} of {len(timed)} frames; "
        f"worst {worst['ratio']:.2f} ({worst['scene']}, {worst['case']}).",
        f"Refinement: Newton steps within +-{GOAL_REFINEMENT:.0%} of their mean on "
        f"{sum(g['verdict'] == 'met' for g in goals)} of {len(goals)} (scene, E ratio, mu).",
    ]
    missed = [r for r in timed if r["ratio"] > GOAL_RATIO]
    if missed:
        lines += ["", "Where each missed frame's extra time goes (friction less frictionless):"]
        lines += [
            f"- {r['scene']}, {r['case']}: +{r['frame_s'] - r['free_frame_s']:.3f} s, of which "
            + ", ".join(
                f"{label} {r[k] - r['free_' + k]:+.3f} s"
                for label, k in (
                    ("Newton against LCP", "law_s"),
                    ("compliance rows", "rows_s"),
                    ("states", "states_s"),
                    ("other", "other_s"),
                )
            )
            + f" ({r['newton']} Newton steps, {r['contacts']} contacts)"
            for r in missed
        ]
    failed = [r for r in rows if not r["solved"]]
    if failed:
        lines.append("")
        lines.append("Frames not solved (stop reason):")
        lines += [
            f"- {r['study']}: {r['scene']}, {r.get('mesh') or r.get('case')}, E ratio "
            f"{r.get('ratio', '-')}, mu {r['mu']:g}: {r['stop_reason']}"
            for r in failed
        ]
    return "\n".join(lines)


def _plot(path: Path, cost: list[dict], iters: list[dict]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(12, 9))
    a0, a1, a2, a3 = axes.ravel()
    timed = [r for r in cost if r["met"] != "-"]
    x = np.arange(len(timed))
    a0.bar(x, [r["ratio"] for r in timed], color="tab:blue")
    a0.axhline(GOAL_RATIO, color="k", ls="--", lw=1, label=f"goal {GOAL_RATIO:g}")
    a0.set_xticks(
        x, [f"{r['scene']}\n{r['case'][:24]}" for r in timed], fontsize=7, rotation=30, ha="right"
    )
    a0.set_ylabel("friction / frictionless")
    a0.set_title("cost of a frame")
    a0.legend(fontsize="small")
    for ax, study, key, log in (
        (a1, "mu", "mu", True),
        (a2, "ratio", "ratio", True),
        (a3, "refinement", "dofs", True),
    ):
        sel = [r for r in iters if r["study"] == study]
        groups = dict.fromkeys(
            (
                r["scene"],
                r["ratio"] if study != "ratio" else None,
                r["mu"] if study == "refinement" else None,
            )
            for r in sel
        )
        for scene, ratio, mu in groups:
            g = [
                r
                for r in sel
                if r["scene"] == scene
                and (ratio is None or r["ratio"] == ratio)
                and (mu is None or r["mu"] == mu)
            ]
            label = scene + (f", E ratio {ratio:g}" if study == "refinement" else "")
            label += f", mu {mu:g}" if mu is not None else ""
            ax.plot([r[key] for r in g], [r["newton"] for r in g], marker="o", label=label)
            bad = [(r[key], r["newton"]) for r in g if not r["solved"]]
            if bad:
                ax.plot(*zip(*bad), ls="", marker="o", ms=11, mfc="none", color="r")
        ax.set_xscale("log" if log else "linear")
        ax.set_ylabel("Newton steps per frame")
        ax.set_xlabel({"mu": "mu", "ratio": "E ball / E other body", "dofs": "DOFs"}[key])
        ax.set_title(f"against {study} (ringed: not solved)", fontsize="medium")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize="x-small")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
