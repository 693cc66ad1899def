"""Hertz verification: contact radius, peak pressure and iterations against the mesh size.

An elastic ball (R = 1 m, E = 1 Pa, nu = 0.3) between two rigid frictionless plates, each
advancing by 0.01 R (a/R about 0.1), modelled by its octant with three symmetry planes on
:func:`fem.generators.graded_ball_mesh`, refined at the poles
(:func:`contact.cases.hertz.hertz_check`). Errors are against Hertz for the solver's own total
force: the moment radius with the interpolation excess removed (and without it, "nodal"),
the radius and the peak pressure of the Hertz profile fitted to the interior nodal
forces (consistently, and lumped: to the nodal pressures f_i / A_i; see
:mod:`contact.cases.hertz`).
"""

from __future__ import annotations

import gc
import time
from pathlib import Path

from contact.cases.hertz import hertz_check

from ._common import (
    Column,
    load_average,
    machine_info,
    markdown_table,
    plot_loglog,
    results_dir,
    write_csv,
    write_markdown,
)

__all__ = ["DEPTH", "SIZES", "run"]

#: Plate advance (m) for R = 1: a/R is about 0.1.
DEPTH = 0.01

#: Cell sizes at the poles (m): full run and ``--quick``.
SIZES: dict[bool, tuple[float, ...]] = {
    False: (0.03, 0.02, 0.015, 0.0125, 0.01, 0.0075, 0.006),
    True: (0.06, 0.04),
}

COLUMNS = (
    Column("fine_size", "fine size (m)", ".4g"),
    Column("dofs", "DOFs", ","),
    Column("cells_per_a", "cells per a", ".1f"),
    Column("a_over_R", "a/R", ".3f"),
    Column("iterations", "iterations", "d"),
    Column("contacts", "contact nodes", "d"),
    Column("radius_err_pct", "radius err (%)", "+.2f"),
    Column("radius_nodal_err_pct", "nodal radius err (%)", "+.2f"),
    Column("fit_radius_err_pct", "fit radius err (%)", "+.2f"),
    Column("pressure_err_pct", "peak pressure err (%)", "+.2f"),
    Column("pressure_lumped_err_pct", "lumped peak pressure err (%)", "+.2f"),
    Column("mesh_s", "mesh (s)", ".2f"),
    Column("body_s", "assemble+factor (s)", ".1f"),
    Column("contact_s", "contact (s)", ".1f"),
)


def run(quick: bool = False, out: str | Path | None = None) -> list[dict]:
    """Run the Hertz convergence study and write ``hertz.{csv,md,png}``.

    Parameters
    ----------
    quick : bool
        Two coarse meshes (seconds).
    out : path, optional
        Results folder; ``benchmarks/results`` (``.../quick`` for quick runs) by default.

    Returns
    -------
    list of dict
        One row per mesh.
    """
    folder = results_dir(out, quick)
    info = machine_info()
    rows: list[dict] = []
    for h in SIZES[quick]:
        t0 = time.perf_counter()
        chk = hertz_check(depth=DEPTH, fine_size=h)
        a, hp = chk.hertz.contact_radius, chk.hertz.peak_pressure
        row = {
            "fine_size": h,
            "dofs": chk.mesh.n_dofs,
            "cells_per_a": a / h,
            "a_over_R": a / chk.hertz.radius,
            "iterations": chk.result.iterations,
            "contacts": len(chk.patch.nodes),
            "radius_err_pct": 100 * chk.radius_error,
            "radius_nodal_err_pct": 100 * (chk.patch.contact_radius_nodal / a - 1),
            "fit_radius_err_pct": 100 * (chk.patch.fit_radius / a - 1),
            "pressure_err_pct": 100 * chk.pressure_error,
            "pressure_lumped_err_pct": 100 * (chk.patch.peak_pressure_lumped / hp - 1),
            "mesh_s": chk.seconds["mesh"],
            "body_s": chk.seconds["body"],
            "contact_s": chk.seconds["contact"],
            "load": load_average(),
        }
        rows.append(row)
        print(
            f"[hertz] {row['dofs']:>8,} DOFs: radius {row['radius_err_pct']:+.2f} %, peak "
            f"pressure {row['pressure_err_pct']:+.2f} %, {row['iterations']} iterations "
            f"({time.perf_counter() - t0:.0f} s)",
            flush=True,
        )
        del chk
        gc.collect()
    write_csv(folder / "hertz.csv", rows, [c.key for c in COLUMNS] + ["load"])
    write_markdown(
        folder / "hertz.md",
        "Hertz: a ball between two plates (octant model, graded hex mesh)",
        info,
        [("Errors against Hertz for the solver's own force", markdown_table(rows, COLUMNS))],
    )
    dofs = [r["dofs"] for r in rows]
    plot_loglog(
        folder / "hertz.png",
        {
            "|radius error|": (dofs, [max(abs(r["radius_err_pct"]), 1e-3) for r in rows]),
            "|peak pressure error|": (dofs, [max(abs(r["pressure_err_pct"]), 1e-3) for r in rows]),
        },
        title="Hertz: errors against DOFs",
        ylabel="relative error (%)",
    )
    return rows
