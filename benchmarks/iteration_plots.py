"""The contact-iteration study's plots: ``iteration.png`` and ``iteration_counts.png``."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from .iteration_cases import (
    CONTACT_SPACE,
    GOAL_UPDATES,
    PRESS_RATIOS,
    RATIOS,
    REFINE_RATIOS,
    SCENES,
    SEED_AITKEN,
    variants,
)

__all__ = ["CLIP", "STYLES"]


STYLES = {
    "contact space": ("k", "o"),
    "contact space, one way": ("0.5", "o"),
    "seed, none": ("tab:red", "s"),
    "seed, fixed 0.5": ("tab:orange", "^"),
    "seed, Aitken": ("tab:blue", "D"),
    "seed, Aitken, softer body Dirichlet": ("tab:green", "v"),
    "seed, none, pairs both ways": ("tab:purple", "x"),
}


#: Top of the history plots' y-axes (diverging seed iterates go far beyond).
CLIP = 1e4


def _plot_histories(path: Path, history: list[dict], quick: bool) -> None:
    """Semilog-y panels of the largest change per iteration: a panel per scene and ratio."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ratios = RATIOS[quick]
    fig, axes = plt.subplots(
        len(SCENES), len(ratios), figsize=(3.4 * len(ratios), 3.2 * len(SCENES)), squeeze=False
    )
    for i, scene in enumerate(SCENES):
        for j, ratio in enumerate(ratios):
            ax = axes[i, j]
            sel = [h for h in history if h["study"] == "ratio" and h["scene"] == scene]
            sel = [h for h in sel if h["ratio"] == ratio]
            for label in dict.fromkeys(h["variant"] for h in sel):
                pts = [
                    (h["iteration"], h.get("max_change_rel", math.nan))
                    for h in sel
                    if h["variant"] == label
                ]
                x = [p[0] for p in pts]
                y = [min(p[1], CLIP) for p in pts]  # diverging iterates drawn at the clip
                color, marker = STYLES.get(label, (None, "."))
                ax.semilogy(x, y, marker=marker, color=color, ms=3, lw=1, label=label)
            ax.axhline(1e-4, color="0.6", ls=":", lw=0.8)
            low, high = ax.get_ylim()
            if high > CLIP:
                ax.set_ylim(low, 3 * CLIP)
            ax.set_title(f"{scene}, E ratio {ratio:g}", fontsize="small")
            ax.set_xlabel("iteration")
            if j == 0:
                ax.set_ylabel("change / |u|max of contact space")
            ax.grid(True, which="both", alpha=0.3)
    handles: dict[str, Any] = {}
    for ax in axes.ravel():
        for h, lb in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lb, h)
    fig.legend(handles.values(), handles.keys(), loc="lower center", ncol=4, fontsize="small")
    fig.suptitle(
        "Largest change of a nodal displacement per iteration (dotted: the seed loop's "
        f"tolerance 1e-4; values above {CLIP:g} drawn at {CLIP:g}: diverging)",
        fontsize="medium",
    )
    fig.tight_layout(rect=(0, 0.08, 1, 0.96))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _plot_counts(path: Path, rows: list[dict], quick: bool) -> None:
    """Iterations against the ratio, the mesh and the press (open markers: not converged)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2, a3) = plt.subplots(1, 3, figsize=(15, 6.8))
    lines = {"hand cup": "-", "sphere-block": "--"}

    def draw(ax: Any, sel: Sequence[dict], xkey: str, label: str, style: tuple) -> None:
        color, marker, ls = style
        x = [r[xkey] for r in sel]
        y = [r["iterations"] for r in sel]
        ax.plot(x, y, ls=ls, marker=marker, color=color, label=label, ms=5)
        bad = [(r[xkey], r["iterations"]) for r in sel if not r["converged"]]
        if bad:
            ax.plot(*zip(*bad), ls="", marker="o", ms=11, mfc="none", color="r")

    for scene in SCENES:
        for v in variants(scene, quick):
            sel = [
                r
                for r in rows
                if r["study"] == "ratio" and r["scene"] == scene and r["variant"] == v.label
            ]
            color, marker = STYLES.get(v.label, (None, "."))
            draw(a1, sel, "ratio", f"{scene}: {v.label}", (color, marker, lines[scene]))
        for ratio in REFINE_RATIOS[quick]:
            sel = [
                r
                for r in rows
                if r["study"] == "refinement" and r["scene"] == scene and r["ratio"] == ratio
            ]
            draw(a2, sel, "dofs", f"{scene}, E ratio {ratio:g}", (None, "o", lines[scene]))
    for ratio in PRESS_RATIOS[quick]:
        for v in (CONTACT_SPACE, SEED_AITKEN):
            sel = [
                r
                for r in rows
                if r["study"] == "press" and r["ratio"] == ratio and r["variant"] == v.label
            ]
            color, marker = STYLES[v.label]
            ls = "-" if ratio < 1 else "--"
            sel = [{**r, "press_mm": 1e3 * r["press"]} for r in sel]
            draw(a3, sel, "press_mm", f"E ratio {ratio:g}: {v.label}", (color, marker, ls))
    a1.set_xscale("log")
    a1.set_xlabel("E ball / E other body")
    a2.set_xscale("log")
    a2.set_xlabel("DOFs (three meshes per scene)")
    a3.set_xlabel("press of the cup (mm)")
    for ax, title in zip(
        (a1, a2, a3),
        (
            "against the stiffness ratio",
            "against mesh refinement (contact space)",
            "hand cup: against the press",
        ),
    ):
        ax.axhline(GOAL_UPDATES, color="0.5", ls=":", lw=1)
        ax.set_ylabel("iterations")
        ax.set_title(title, fontsize="medium")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize="x-small", loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2)
    fig.suptitle("Iterations of a frame (ringed: not converged; dotted: the goal of 10)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
