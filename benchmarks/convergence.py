"""Mesh convergence: Lame's thick sphere and Hertz's ball, errors against h with fitted rates.

Lame: a hollow sphere (inner radius 0.8 m, outer 1 m, E = 1 MPa) under an internal
pressure of 10 kPa, meshed whole as a free body (no support; the rigid-body modes are
removed exactly) by :func:`fem.shell_mesh` (a cubed sphere of bricks, ``4 k`` cells along
each face edge and ``k`` through the wall, so the cell shapes stay the same as ``k``
grows) and, for tet4, by the same bricks split into 24 tetrahedra each
(:func:`fem.hex_to_tet`). Errors against Lame's exact solution:

- ``max u_r``: the largest nodal error of the radial displacement, relative to the
  largest exact radial displacement (at the inner surface);
- ``L2 u``: the relative L2 norm of the displacement error (vector), integrated over the
  mesh with a quadrature exact to degree 5 (27 Gauss points per brick, 64 collapsed-cube
  points per tetrahedron), not the stiffness rule;
- ``L2 sigma``: the relative L2 norm of the stress error (Frobenius), same quadrature;
- ``hoop mid``: the largest error of the hoop stress at the centroids of the cells that
  reach the mid-wall sphere ``r = 0.9 m`` (a pointwise check), relative to the exact hoop
  stress there.

``h`` is the mean edge length of the cells. Poisson's ratio 0.3; the same meshes are also
run at 0.45, where fully integrated bricks stiffen (volumetric locking, a known limit of
HEX8 in :mod:`fem`). Rates are least-squares slopes of ``log error`` against ``log h``.

Hertz: the octant model of :mod:`contact.cases.hertz` (ball R = 1 m, E = 1 Pa, nu = 0.3,
between rigid frictionless plates advancing 0.01 R), ``h`` its cell size at the poles;
the contact radius and peak pressure against Hertz for the solver's own force (as in
:mod:`benchmarks.hertz`) and the total force against Hertz's force for the plate's advance.
"""

from __future__ import annotations

import gc
import time
from pathlib import Path

from ._common import (
    Column,
    load_average,
    machine_info,
    markdown_table,
    results_dir,
    write_csv,
    write_markdown,
)
from .convergence_cases import (
    HERTZ_DEPTH,
    HERTZ_SIZES,
    LAME,
    LAME_LEVELS,
    LAME_NU,
    hertz_case,
    lame_case,
    lame_exact,
    mean_edge_length,
)
from .convergence_rates import HERTZ_ERRORS, LAME_ERRORS, fitted_rate, rate_rows
from .convergence_report import _notes, _plot

__all__ = [
    "HERTZ_DEPTH",
    "HERTZ_SIZES",
    "LAME",
    "LAME_LEVELS",
    "LAME_NU",
    "fitted_rate",
    "hertz_case",
    "lame_case",
    "lame_exact",
    "mean_edge_length",
    "rate_rows",
    "run",
]

LAME_COLUMNS = (
    Column("element", "element"),
    Column("nu", "nu", ".2f"),
    Column("level", "k", "d"),
    Column("h", "h (m)", ".4f"),
    Column("cells", "cells", ","),
    Column("dofs", "DOFs", ","),
    Column("max_ur", "max u_r err", ".3e"),
    Column("l2_u", "L2 u err", ".3e"),
    Column("l2_sigma", "L2 sigma err", ".3e"),
    Column("hoop_mid", "hoop mid err", ".3e"),
    Column("solve_s", "mesh+solve (s)", ".2f"),
    Column("error_s", "errors (s)", ".2f"),
)

HERTZ_COLUMNS = (
    Column("h", "fine size h (m)", ".4g"),
    Column("dofs", "DOFs", ","),
    Column("cells_per_a", "cells per a", ".1f"),
    Column("contacts", "contact nodes", "d"),
    Column("radius_err", "radius err", "+.3e"),
    Column("pressure_err", "peak pressure err", "+.3e"),
    Column("force_err", "force err", "+.3e"),
    Column("solve_s", "mesh+solve (s)", ".1f"),
)

RATE_COLUMNS = (
    Column("study", "study"),
    Column("series", "series"),
    Column("error", "error"),
    Column("meshes", "meshes", "d"),
    Column("finest", "error at finest h", ".3e"),
    Column("rate", "fitted rate", ".2f"),
    Column("last_rate", "rate of the last two", ".2f"),
    Column("expected", "expected"),
    Column("note", "note"),
)

CSV_KEYS = (
    "study",
    "element",
    "nu",
    "level",
    "h",
    "cells",
    "dofs",
    "max_ur",
    "l2_u",
    "l2_sigma",
    "hoop_mid",
    "cells_per_a",
    "contacts",
    "iterations",
    "radius_err",
    "pressure_err",
    "force_err",
    "solve_s",
    "error_s",
    "load",
)


def run(quick: bool = False, out: str | Path | None = None) -> list[dict]:
    """Run the mesh convergence study and write ``convergence.{csv,md,png}``.

    Parameters
    ----------
    quick : bool
        Coarse meshes only (seconds).
    out : path, optional
        Results folder; ``benchmarks/results`` (``.../quick`` for quick runs) by default.

    Returns
    -------
    list of dict
        One row per mesh: ``study`` is ``"lame"`` or ``"hertz"``.
    """
    folder = results_dir(out, quick)
    info = machine_info()
    t_start = time.perf_counter()
    rows: list[dict] = []
    for nu in LAME_NU:
        for element, levels in LAME_LEVELS[quick].items():
            for level in levels:
                row = lame_case(element, level, nu) | {"load": load_average()}
                rows.append(row)
                print(
                    f"[convergence] lame {element} nu {nu:g} k {level}: {row['dofs']:>7,} DOFs, "
                    f"h {row['h']:.4f}, L2 u {row['l2_u']:.3e}, L2 sigma "
                    f"{row['l2_sigma']:.3e}, max u_r {row['max_ur']:.3e}, hoop "
                    f"{row['hoop_mid']:.3e} ({row['solve_s'] + row['error_s']:.1f} s)",
                    flush=True,
                )
                gc.collect()
    for h in HERTZ_SIZES[quick]:
        row = hertz_case(h) | {"load": load_average()}
        rows.append(row)
        print(
            f"[convergence] hertz h {h:g}: {row['dofs']:>7,} DOFs, radius "
            f"{row['radius_err']:+.3e}, peak {row['pressure_err']:+.3e}, force "
            f"{row['force_err']:+.3e} ({row['solve_s']:.1f} s)",
            flush=True,
        )
        gc.collect()
    seconds = time.perf_counter() - t_start
    rates = rate_rows(rows)
    write_csv(folder / "convergence.csv", rows, CSV_KEYS)
    lame = [r for r in rows if r["study"] == "lame"]
    hertz = [r for r in rows if r["study"] == "hertz"]
    expected = "\n".join(
        f"- {label}: {rate}; {why}" for _, label, rate, why in LAME_ERRORS + HERTZ_ERRORS
    )
    write_markdown(
        folder / "convergence.md",
        "Mesh convergence: Lame's thick sphere and Hertz's ball",
        info,
        [
            (
                "Lame's thick sphere (free body, internal pressure)",
                markdown_table(lame, LAME_COLUMNS),
            ),
            (
                "Hertz: a ball between two plates (octant, graded bricks)",
                markdown_table(hertz, HERTZ_COLUMNS),
            ),
            (
                "Fitted rates",
                markdown_table(rates, RATE_COLUMNS)
                + "\n\nRates are least-squares slopes of log |error| on log h over all the "
                "meshes of a series (and the slope between its two finest meshes). Expected "
                "for linear elements:\n\n" + expected,
            ),
            ("Notes", _notes(rows, seconds)),
        ],
    )
    _plot(folder / "convergence.png", rows, rates)
    return rows
