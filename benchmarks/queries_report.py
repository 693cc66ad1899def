"""The report of the query benchmark: its table columns, CSV keys and plot.

Used by :func:`benchmarks.queries.run` to write ``queries.{csv,md,png}``.
"""

from __future__ import annotations

from pathlib import Path

from ._common import Column
from .queries_candidates import CANDIDATES

__all__ = ["COLUMNS", "CSV_KEYS"]


COLUMNS = (
    Column("skin", "skin"),
    Column("facets", "facets", ","),
    Column("library", "library"),
    Column("precision", "precision"),
    Column("points", "points", ","),
    Column("build_s", "build (ms)", ".2f"),
    Column("query_s", "query (ms)", ".2f"),
    Column("us_per_point", "query µs/point", ".2f"),
    Column("max_point_err", "max point err (m)", ".1e"),
    Column("rel_dist_err", "max rel. dist err", ".1e"),
    Column("points_off", "points off (>1e-9 diag)", "d"),
    Column("inside_wrong", "inside wrong", "d"),
    Column("note", "note"),
)

CSV_KEYS = (
    "skin", "facets", "library", "query", "dist", "version", "precision", "points", "build_s",
    "query_s", "us_per_point", "total_s", "runs", "max_dist_err", "max_point_err",
    "rel_dist_err", "points_off", "inside_wrong", "note",
)  # fmt: skip


def _ms(rows: list[dict]) -> list[dict]:
    out = []
    for r in rows:
        r2 = dict(r)
        for key in ("build_s", "query_s"):
            if r2.get(key) is not None:
                r2[key] = 1e3 * r2[key]
        out.append(r2)
    return out


def _plot(path: Path, rows: list[dict], skin: str) -> None:
    """Build + query time against the number of points, closest point and inside apart."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(13, 5.5))
    markers = "osD^vP*X<>h"
    for ax, kind in zip(axes, ("closest", "inside")):
        cands = [c for c in CANDIDATES if c.kind == kind]
        for i, cand in enumerate(cands):
            rk = [
                r
                for r in rows
                if r["library"] == cand.name and r["skin"] == skin and r.get("query_s")
            ]
            if rk:
                ax.loglog(
                    [r["points"] for r in rk],
                    [r["total_s"] for r in rk],
                    marker=markers[i % len(markers)],
                    color=plt.cm.tab10(i % 10),
                    linestyle="-" if cand.precision == "float64" else "--",
                    label=f"{cand.name} ({cand.precision})",
                )
        ax.set_xlabel("query points")
        ax.set_ylabel("build + query (s)")
        ax.set_title(f"{'Closest point' if kind == 'closest' else 'Inside'}, {skin} skin")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
