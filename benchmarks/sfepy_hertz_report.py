"""The Hertz comparison with SfePy judged and reported: its goal, tables, verdict and plot.

The accuracy and time goal of :mod:`benchmarks.sfepy_hertz`, the columns of its table,
profile and CSV file, the verdict on each mesh, the plot, and the note written where
SfePy is not installed (:func:`sfepy_missing`, also used by :mod:`benchmarks.sfepy_patch`).
"""

from __future__ import annotations

from pathlib import Path

from ._common import Column, machine_info, write_markdown

__all__ = [
    "COLUMNS",
    "CSV_KEYS",
    "GOAL_PRESSURE_PCT",
    "GOAL_RADIUS_PCT",
    "GOAL_TIME_RATIO",
    "PROFILE_COLUMNS",
    "sfepy_missing",
]

#: The goal: the same accuracy (contact radius and peak pressure against Hertz, in %)
#: in at most this fraction of SfePy's time.
GOAL_RADIUS_PCT = 0.5
GOAL_PRESSURE_PCT = 1.0
GOAL_TIME_RATIO = 0.1


def _meets(radius_pct: float, pressure_pct: float) -> bool:
    return abs(radius_pct) <= GOAL_RADIUS_PCT and abs(pressure_pct) <= GOAL_PRESSURE_PCT


COLUMNS = (
    Column("fine_size", "fine size (m)", ".4g"),
    Column("dofs", "DOFs", ","),
    Column("code", "code", ""),
    Column("penalty", "penalty k (E/R)", ".0e"),
    Column("iterations", "iterations", "d"),
    Column("converged", "converged", ""),
    Column("contacts", "contact nodes", "d"),
    Column("force_vs_ours_pct", "force vs ours (%)", "+.3f"),
    Column("radius_err_pct", "radius err (%)", "+.2f"),
    Column("pressure_err_pct", "peak pressure err (%)", "+.2f"),
    Column("accuracy_met", "accuracy goal met", ""),
    Column("total_s", "solve (s)", ".2f"),
    Column("runs", "runs", "d"),
    Column("load1", "load (1 min)", ".1f"),
    Column("ours_over_this", "our time / this", ".3f"),
)

PROFILE_COLUMNS = (
    Column("fine_size", "fine size (m)", ".4g"),
    Column("dofs", "DOFs", ","),
    Column("code", "code", ""),
    Column("penalty", "penalty k (E/R)", ".0e"),
    Column("iterations", "iterations", "d"),
    Column("setup_s", "set-up / assembly (s)", ".2f"),
    Column("factor_s", "factorisations (s)", ".2f"),
    Column("matrix_s", "tangent assembly (s)", ".2f"),
    Column("solve_s", "linear solves (s)", ".2f"),
    Column("residual_s", "residuals (s)", ".2f"),
    Column("rest_s", "rest (s)", ".2f"),
    Column("total_s", "total (s)", ".2f"),
)

CSV_KEYS = [
    "fine_size",
    "dofs",
    "code",
    "linear_solver",
    "penalty",
    "order",
    "iterations",
    "converged",
    "contacts",
    "force",
    "force_vs_ours_pct",
    "radius_err_pct",
    "radius_nodal_err_pct",
    "fit_radius_err_pct",
    "pressure_err_pct",
    "pressure_lumped_err_pct",
    "accuracy_met",
    "equilibrium",
    "total_s",
    "runs",
    "load1",
    "setup_s",
    "factor_s",
    "matrix_s",
    "solve_s",
    "residual_s",
    "rest_s",
    "ours_over_this",
    "load",
]


def _candidates(rows: list[dict], h: float) -> list[dict]:
    """SfePy's runs (PARDISO) on mesh ``h`` that converged within the accuracy goal."""
    return [
        r
        for r in rows
        if r["fine_size"] == h
        and r["code"] == "SfePy"
        and r["accuracy_met"] == "yes"
        and r["converged"] == "yes"
    ]


def _goal(rows: list[dict]) -> tuple[str, bool | None]:
    """The verdict: on each mesh where both codes meet the accuracy, our time / SfePy's."""
    lines, verdicts = [], []
    for h in sorted({r["fine_size"] for r in rows}, reverse=True):
        ours = next(r for r in rows if r["fine_size"] == h and r["code"] == "ours")
        theirs = _candidates(rows, h)
        head = f"- fine size {h:g} m ({ours['dofs']:,} DOFs): "
        if ours["accuracy_met"] != "yes":
            lines.append(
                head + f"ours misses the accuracy itself (radius {ours['radius_err_pct']:+.2f} %, "
                f"peak pressure {ours['pressure_err_pct']:+.2f} %): not judged."
            )
            continue
        if not theirs:
            lines.append(head + "no SfePy run meets the accuracy: not judged.")
            continue
        best = min(theirs, key=lambda r: r["total_s"])
        ratio = ours["total_s"] / best["total_s"]
        ok = ratio <= GOAL_TIME_RATIO
        verdicts.append(ok)
        lines.append(
            head + f"ours {ours['total_s']:.2f} s (radius {ours['radius_err_pct']:+.2f} %, peak "
            f"pressure {ours['pressure_err_pct']:+.2f} %), SfePy's fastest run within the "
            f"accuracy {best['total_s']:.2f} s (k = {best['penalty']:.0e}: radius "
            f"{best['radius_err_pct']:+.2f} %, peak pressure {best['pressure_err_pct']:+.2f} %): "
            f"ratio {ratio:.3f}, goal {'met' if ok else 'MISSED'}."
        )
        stiff = max((r for r in theirs if r["code"] == "SfePy"), key=lambda r: r["penalty"])
        gap = max(
            abs(stiff["radius_err_pct"] - ours["radius_err_pct"]),
            abs(stiff["pressure_err_pct"] - ours["pressure_err_pct"]),
        )
        lines.append(
            f"  (context, not the verdict: against SfePy's stiffest penalty, k = "
            f"{stiff['penalty']:.0e}, whose force differs from ours by "
            f"{stiff['force_vs_ours_pct']:+.3f} % and whose errors are ours to {gap:.2f} %, "
            "the ratio is "
            f"{ours['total_s'] / stiff['total_s']:.3f} ({stiff['runs']} run(s)).)"
        )
    met = all(verdicts) if verdicts else None
    return "\n".join(lines), met


def _plot(path: Path, rows: list[dict], penalties: tuple[float, ...]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 5))
    ours = [r for r in rows if r["code"] == "ours"]
    series = [("ours", ours)] + [
        (f"SfePy k={k:.0e}", [r for r in rows if r["code"] == "SfePy" and r["penalty"] == k])
        for k in penalties
    ]
    markers = "osD^vP*X"
    for i, (label, rs) in enumerate(series):
        if not rs:
            continue
        x = [r["dofs"] for r in rs]
        mk = markers[i % len(markers)]
        ax1.semilogx(x, [r["radius_err_pct"] for r in rs], marker=mk, label=f"{label}: radius")
        ax1.semilogx(
            x, [r["pressure_err_pct"] for r in rs], marker=mk, ls="--", label=f"{label}: peak p"
        )
        ax2.loglog(x, [r["total_s"] for r in rs], marker=mk, label=label)
    for y in (GOAL_RADIUS_PCT, -GOAL_RADIUS_PCT):
        ax1.axhline(y, color="grey", lw=0.8, ls=":")
    ax1.set_ylim(-6, 6)
    ax1.set_xlabel("DOFs")
    ax1.set_ylabel("error against Hertz (%)")
    ax1.set_title("Hertz: accuracy, ours and SfePy's penalty")
    ax1.grid(True, which="both", alpha=0.3)
    ax1.legend(fontsize="x-small", ncol=2)
    ax2.set_xlabel("DOFs")
    ax2.set_ylabel("whole solve (s)")
    ax2.set_title("time (both with MKL PARDISO)")
    ax2.grid(True, which="both", alpha=0.3)
    ax2.legend(fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def sfepy_missing(folder: Path, study: str, title: str) -> list[dict]:
    """Without SfePy: ``<study>.md`` says so and how to install it; no rows."""
    write_markdown(
        folder / f"{study}.md",
        f"{title}: not run",
        machine_info(),
        [
            (
                "SfePy is not installed",
                "SfePy could not be imported, so this comparison did not run. Install the "
                "optional extra (`pip install .[benchmarks]`; SfePy ships an sdist only, "
                f"built with a C compiler) and run `python -m benchmarks.{study}`.",
            )
        ],
    )
    return []
