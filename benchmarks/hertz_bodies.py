"""Hertz between two deformable bodies: errors and iterations of both algorithms.

Two quarter-model scenes of :mod:`contact.cases.hertz_bodies`: a sphere (R1 = 1 m) pressed onto
an elastic block 20 contact radii wide and deep, and two spheres (R1 = 1 m on R2 = 2 m,
1/R = 1/R1 + 1/R2), interference 0.01 R (a/R about 0.1), nu = 0.3, the top sphere's
modulus ``ratio`` times the other body's, ratios 0.01 to 100, on three meshes (cell size
at the contact). Errors against Hertz (1/E* = sum (1 - nu^2)/E) for the solver's own
force, from the top sphere's nodal forces (and the other body's).

Iterations (contact-set updates) of contact space with node-to-surface pairs both ways
(the scene's pairs) and one way (the top sphere's nodes only), and of the seed's
Dirichlet-Neumann loop (the top sphere the Dirichlet body; no relaxation and Aitken's),
with its stop reason where it does not converge. Times: assembly and factorisation of both
bodies, and the contact solve of the frame (contact space, both ways).
"""

from __future__ import annotations

import gc
import time
from pathlib import Path

import fem
from contact.cases.hertz_bodies import hertz_bodies_check, hertz_scene
from contact.solver import ContactSettings, solve_frame
from contact.solver.results import FrameResult

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

__all__ = ["RADII", "RATIOS", "SIZES", "run"]

#: Top and bottom sphere radii (m) of the two-spheres scene.
RADII = (1.0, 2.0)

#: E1 / E2: full run and ``--quick``.
RATIOS: dict[bool, tuple[float, ...]] = {
    False: (0.01, 0.1, 1.0, 10.0, 100.0),
    True: (0.01, 100.0),
}

#: Cell sizes at the contact (m): full run and ``--quick``.
SIZES: dict[bool, tuple[float, ...]] = {
    False: (0.03, 0.02, 0.015),
    True: (0.04,),
}

#: The seed loop's variants: (pairs both ways, relaxation).
SEEDS = ((True, "none"), (True, "aitken"), (False, "none"), (False, "aitken"))

COLUMNS = (
    Column("scene", "scene"),
    Column("ratio", "E1/E2", "g"),
    Column("fine_size", "fine size (m)", ".3g"),
    Column("dofs", "DOFs", ","),
    Column("cells_per_a", "cells per a", ".1f"),
    Column("radius_err_pct", "radius err (%)", "+.2f"),
    Column("pressure_err_pct", "peak pressure err (%)", "+.2f"),
    Column("radius_err_other_pct", "other body: radius err (%)", "+.2f"),
    Column("pressure_err_other_pct", "other body: peak pressure err (%)", "+.2f"),
    Column("penetration_ratio", "penetration / cell", ".1e"),
    Column("body_s", "assemble+factor (s)", ".2f"),
    Column("contact_s", "contact solve (s)", ".2f"),
)

ITERATION_COLUMNS = (
    Column("scene", "scene"),
    Column("ratio", "E1/E2", "g"),
    Column("fine_size", "fine size (m)", ".3g"),
    Column("cs_iterations", "contact space, both ways", "d"),
    Column("cs_one_way_iterations", "contact space, one way", "d"),
    Column("seed_both_none", "seed both ways, none"),
    Column("seed_both_aitken", "seed both ways, Aitken"),
    Column("seed_one_none", "seed one way, none"),
    Column("seed_one_aitken", "seed one way, Aitken"),
    Column("seed_s", "seed one way Aitken (s)", ".2f"),
)


def _seed_cell(res: FrameResult) -> str:
    """``"4"`` when converged, else ``"50 (iteration limit)"``."""
    return str(res.iterations) if res.converged else f"{res.iterations} ({res.stop_reason})"


def run(quick: bool = False, out: str | Path | None = None) -> list[dict]:
    """Run the two-body Hertz study and write ``hertz_bodies.{csv,md,png}``.

    Parameters
    ----------
    quick : bool
        Two ratios on one coarse mesh (seconds).
    out : path, optional
        Results folder; ``benchmarks/results`` (``.../quick`` for quick runs) by default.

    Returns
    -------
    list of dict
        One row per scene, ratio and mesh.
    """
    folder = results_dir(out, quick)
    info = machine_info()
    rows: list[dict] = []
    for name in ("sphere-block", "two-spheres"):
        for ratio in RATIOS[quick]:
            for h in SIZES[quick]:
                t0 = time.perf_counter()
                sc = hertz_scene(name, ratio, fine_size=h, radii=RADII)
                chk = hertz_bodies_check(sc)
                res = chk.result
                hz = chk.hertz
                one = hertz_scene(name, ratio, fine_size=h, radii=RADII, both_directions=False)
                one_res = solve_frame(list(one.bodies), list(one.pairs))
                row = {
                    "scene": name,
                    "ratio": ratio,
                    "fine_size": h,
                    "dofs": sc.dofs,
                    "cells_per_a": hz.contact_radius / h,
                    "a_over_R": hz.contact_radius / hz.radius,
                    "radius_err_pct": 100 * chk.radius_error,
                    "pressure_err_pct": 100 * chk.pressure_error,
                    "radius_err_other_pct": 100 * chk.radius_error_other,
                    "pressure_err_other_pct": 100 * chk.pressure_error_other,
                    "action_reaction": chk.action_reaction,
                    "penetration_ratio": res.penetration_ratio,
                    "contacts": len(res.contacts["node"]),
                    "cs_iterations": res.iterations,
                    "cs_converged": res.converged,
                    "cs_one_way_iterations": one_res.iterations,
                    "mesh_s": sc.seconds["mesh"],
                    "body_s": sc.seconds["body"],
                    "contact_s": chk.seconds["contact"],
                    "geometry_s": res.timings.get("geometry", 0.0),
                    "rows_s": res.timings.get("contact solve", 0.0),
                }
                for both, relaxation in SEEDS:
                    s = sc if both else one
                    t = time.perf_counter()
                    key = f"seed_{'both' if both else 'one'}_{relaxation}"
                    try:
                        seed = solve_frame(
                            list(s.bodies),
                            list(s.pairs),
                            (),
                            ContactSettings(algorithm="seed", relaxation=relaxation),
                        )
                    except fem.SolverError:
                        # the Dirichlet body's rows dependent (pairs both ways): raised
                        # from its constrained solve instead of a non-converged result
                        row[key] = "raised SolverError"
                        row[key + "_iterations"] = None
                        row[key + "_converged"] = False
                        continue
                    row[key] = _seed_cell(seed)
                    row[key + "_iterations"] = seed.iterations
                    row[key + "_converged"] = seed.converged
                    if not both and relaxation == "aitken":
                        row["seed_s"] = time.perf_counter() - t
                row["load"] = load_average()
                rows.append(row)
                print(
                    f"[hertz_bodies] {name} E1/E2 {ratio:g}, {row['dofs']:,} DOFs: radius "
                    f"{row['radius_err_pct']:+.2f} %, peak pressure "
                    f"{row['pressure_err_pct']:+.2f} %, contact space {res.iterations}, seed "
                    f"{row['seed_one_none']} / {row['seed_one_aitken']} "
                    f"({time.perf_counter() - t0:.0f} s)",
                    flush=True,
                )
                del sc, chk, one, res, one_res
                gc.collect()
    keys = [c.key for c in COLUMNS] + [
        c.key for c in ITERATION_COLUMNS if c.key not in {"scene", "ratio", "fine_size"}
    ]
    keys += [
        "a_over_R",
        "action_reaction",
        "contacts",
        "cs_converged",
        "mesh_s",
        "geometry_s",
        "rows_s",
        "load",
    ]
    write_csv(folder / "hertz_bodies.csv", rows, keys)
    write_markdown(
        folder / "hertz_bodies.md",
        "Hertz: two deformable bodies (quarter models, graded hex meshes)",
        info,
        [
            (
                "Errors against Hertz for the solver's own force (contact space, pairs both ways)",
                markdown_table(rows, COLUMNS),
            ),
            (
                "Iterations (contact-set updates); the seed loop's stop reason when it fails",
                markdown_table(rows, ITERATION_COLUMNS),
            ),
        ],
    )
    series = {}
    for name in ("sphere-block", "two-spheres"):
        for h in SIZES[quick]:
            sel = [r for r in rows if r["scene"] == name and r["fine_size"] == h]
            x = [r["ratio"] for r in sel]
            series[f"{name} h={h:g}: contact space"] = (x, [r["cs_iterations"] for r in sel])
        sel = [r for r in rows if r["scene"] == name and r["fine_size"] == SIZES[quick][0]]
        series[f"{name} h={SIZES[quick][0]:g}: seed one way, Aitken (converged)"] = (
            [r["ratio"] for r in sel],
            [
                r["seed_one_aitken_iterations"] if r["seed_one_aitken_converged"] else None
                for r in sel
            ],
        )
    plot_loglog(
        folder / "hertz_bodies.png",
        series,
        title="Hertz, two bodies: iterations against the modulus ratio",
        xlabel="E1 / E2 (top sphere / other body)",
        ylabel="contact-set updates",
    )
    return rows
