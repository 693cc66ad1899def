"""The contact-patch study's graded octants by node rows and by weighted gaps: cost and accuracy.

The graded meshes and presses of :mod:`benchmarks.patch` (fTetWild octants of a ball,
R = 1, E = 1, nu = 0.3, fine within 0.2 R of the pole, a rigid table pressed along z,
symmetry rollers on the cut planes), each press solved twice: a row per contact node,
and one weighted row per covered node over the body's smoothed faces
(:mod:`contact.solver.planemortar`). Reports each press's frame (assembly apart: the
factorisation and the contact solve), the weighted frame over the node rows' (the issue's
goal: at most :data:`GOAL`), the closed rows, and the force, contact radius and peak
pressure against Hertz.

The meshes are :func:`benchmarks.patch.mesh_of`'s, cached in the temporary folder
(fTetWild takes minutes on the finest). Run ``python -m benchmarks.patch_gaps [--quick]``.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from ._common import (
    Column,
    machine_info,
    markdown_table,
    plot_loglog,
    results_dir,
    write_csv,
    write_markdown,
)
from .patch import DEPTHS, SIZES, mesh_of, run_case

__all__ = ["GOAL", "run"]

#: The goal: a weighted frame at most this multiple of the node rows' on the same press.
GOAL = 1.5

COLUMNS = (
    Column("dofs", "DOFs", ","),
    Column("fine_size", "h pole (m)", ".4f"),
    Column("depth", "d/R", ".3f"),
    Column("gaps", "gaps"),
    Column("updates", "updates", "d"),
    Column("rows", "closed rows", ","),
    Column("factor_s", "factor (s)", ".2f"),
    Column("contact_s", "contact (s)", ".2f"),
    Column("frame_s", "frame (s)", ".2f"),
    Column("over_nodal", "frame / node rows' frame", ".2f"),
    Column("radius_err_pct", "radius err (%)", "+.2f"),
    Column("pressure_err_pct", "peak p err (%)", "+.2f"),
    Column("force_err_pct", "force vs Hertz(d) (%)", "+.2f"),
)


def run(quick: bool = False, out: str | Path | None = None) -> list[dict]:
    """Run the study and write ``patch_gaps.{csv,md,png}``; one row per mesh, press and gaps.

    Parameters
    ----------
    quick : bool
        :mod:`benchmarks.patch`'s quick mesh and press.
    out : path, optional
        Results folder; ``benchmarks/results`` (``.../quick`` for quick runs) by default.
    """
    folder = results_dir(out, quick)
    info = machine_info()
    rows: list[dict] = []
    made: list[str] = []
    for h in SIZES[quick]:
        mesh, secs = mesh_of(h)
        made.append(f"h = {h:g}: {mesh.n_dofs:,} DOFs, {len(mesh.cells['tetra']):,} tetrahedra"
                    + (", cached" if math.isnan(secs) else f", fTetWild {secs:.0f} s"))  # fmt: skip
        for d in DEPTHS[quick]:
            nodal = run_case(mesh, h, d)
            weighted = run_case(mesh, h, d, weighted=True)
            for r in (nodal, weighted):
                r["over_nodal"] = r["frame_s"] / nodal["frame_s"]
                rows.append(r)
            print(f"[patch_gaps] {mesh.n_dofs:>8,} DOFs d/R {d}: rows {nodal['rows']} / "
                  f"{weighted['rows']}, frame {nodal['frame_s']:.2f} / {weighted['frame_s']:.2f} s "
                  f"(x{weighted['over_nodal']:.2f}), force {nodal['force_err_pct']:+.2f} / "
                  f"{weighted['force_err_pct']:+.2f} %", flush=True)  # fmt: skip
    write_csv(folder / "patch_gaps.csv", rows,
              [c.key for c in COLUMNS] + ["converged", "assemble_s", "load"])  # fmt: skip
    title = "The patch study's meshes: node rows and weighted gaps"
    write_markdown(folder / "patch_gaps.md", title, info,
                   [("Runs", _notes(made) + "\n\n" + markdown_table(rows, COLUMNS)),
                    ("Goal", _goal(rows))])  # fmt: skip
    plot_loglog(
        folder / "patch_gaps.png",
        {g: ([r["dofs"] for r in rows if r["gaps"] == g],
             [r["frame_s"] for r in rows if r["gaps"] == g]) for g in ("nodal", "weighted")},
        title="A press's frame against the mesh", xlabel="DOFs",
    )  # fmt: skip
    return rows


def _notes(made: list[str]) -> str:
    return ("The graded octants and presses of `benchmarks.patch`, each press solved by node "
            "rows and by weighted gaps over the smoothed faces. 'frame' = the contact solve, "
            "its factorisation included (assembly apart); 'closed rows' = contact nodes for "
            "node rows, closed weighted rows for weighted gaps (whose forces spread onto their "
            "facets' nodes). Presses under a second are timed three times, the fastest kept. "
            "Meshes: " + "; ".join(made) + ".")  # fmt: skip


def _goal(rows: list[dict]) -> str:
    """The cost goal per press, and whether every press met it."""
    weighted = [r for r in rows if r["gaps"] == "weighted"]
    worst = max(r["over_nodal"] for r in weighted)
    missed = [r for r in weighted if r["over_nodal"] > GOAL or not r["converged"]]
    out = (f"goal: a weighted frame <= {GOAL:g}x the node rows' on every press: "
           f"**{'missed' if missed else 'met'}** (largest x{worst:.2f})")  # fmt: skip
    if missed:
        out += "; missed on " + "; ".join(
            f"{r['dofs']:,} DOFs d/R {r['depth']:g}: x{r['over_nodal']:.2f}"
            + ("" if r["converged"] else " (not converged)") for r in missed)  # fmt: skip
    return out + "."


def main(argv: list[str] | None = None) -> None:
    """Command line: ``python -m benchmarks.patch_gaps [--quick] [--out DIR]``."""
    ap = argparse.ArgumentParser(prog="python -m benchmarks.patch_gaps", description=__doc__)
    ap.add_argument("--quick", action="store_true", help="one coarse mesh, one press")
    ap.add_argument("--out", help="results folder")
    run(**vars(ap.parse_args(argv)))


if __name__ == "__main__":
    main()
