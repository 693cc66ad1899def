"""Finite strain in contact: Newton steps, cost and memory against the linear frame.

A free neo-Hookean ball (R = 20 mm, E = 1 MPa, nu = 0.45, bricks) squeezed between two
rigid frictionless plates, each advancing by d / 2, frames at d / R = 0.05, 0.1, 0.15
and 0.2 (each from the last), on three nested meshes (:func:`contact.solver.finite.
solve_finite_frame`); the same presses solved linear, each frame from rest
(:func:`contact.solver.solve_frame`). Per mesh: Newton steps per frame, time and peak
memory of the finite frames over the linear ones, the plate force at d / R = 0.2 of both
models and its observed order of convergence over the meshes.

The meshes are cubed spheres (:func:`fem.ball_mesh`) whose divisions and layers double
from one to the next: each refines the last by two and keeps a node at each pole, where
the plates first touch. Sizes that are not nested alternate between a node and a facet at
the pole (odd divisions), and the plate force then goes up and down with the size.

Goals (the finite-strain issue): at most 8 Newton steps a frame and within +-30 % over
three refinements; a finite frame at most 3x the linear one; the run's peak resident
memory at most 1.5x the linear run's (each run's rise above its start is given too). The
full run also times the README example's closing frame in both models
(:mod:`benchmarks.finite_example`).
"""

from __future__ import annotations

import gc
import math
import time
from pathlib import Path

import numpy as np

import fem
from contact.geometry.plane import Plane
from contact.solver import ContactSettings, solve_frame
from contact.solver.body import ElasticBody
from contact.solver.finite import FiniteBody, solve_finite_frame
from contact.solver.pairs import ContactPair

from ._common import (
    Column,
    PeakMemory,
    load_average,
    machine_info,
    markdown_table,
    results_dir,
    write_csv,
    write_markdown,
)
from .finite_example import COLUMNS as EXAMPLE_COLUMNS
from .finite_example import example_rows, example_section

__all__ = [
    "PRESSES",
    "SIZES",
    "ball",
    "finite_presses",
    "linear_presses",
    "order",
    "plates",
    "run",
    "surface_edge",
]

R, E, NU = 0.02, 1.0e6, 0.45
#: d / R of the frames, in order.
PRESSES = (0.05, 0.1, 0.15, 0.2)
#: The meshes' divisions (:func:`fem.ball_mesh`, layers half as many): full run and
#: ``--quick``; each doubles the last.
SIZES: dict[bool, tuple[int, ...]] = {False: (4, 8, 16), True: (4, 8)}

COLUMNS = (
    Column("divisions", "divisions", "d"),
    Column("h_over_R", "surface edge / R", ".3f"),
    Column("dofs", "DOFs", ","),
    Column("steps", "Newton steps per frame", ""),
    Column("steps_max", "most", "d"),
    Column("force_finite", "force at d/R 0.2, finite (N)", ".4f"),
    Column("force_linear", "linear (N)", ".4f"),
    Column("finite_s", "finite frames (s)", ".2f"),
    Column("linear_s", "linear frames (s)", ".2f"),
    Column("time_ratio", "time finite / linear", ".2f"),
    Column("memory_ratio", "peak RSS finite / linear", ".2f"),
    Column("finite_mib", "finite: above the start (MiB)", ".0f"),
    Column("linear_mib", "linear: above the start (MiB)", ".0f"),
)


def plates(d: float) -> list[Plane]:
    """The table and the plate, each advanced by ``d R / 2``."""
    return [
        Plane((0, 0, -R), (0, 0, 1), motion=(0, 0, d * R / 2), name="table"),
        Plane((0, 0, R), (0, 0, -1), motion=(0, 0, -d * R / 2), name="plate"),
    ]


def finite_presses(
    mesh: fem.Mesh, mat: fem.LinearElastic, clock: dict[str, float] | None = None
) -> tuple[list[int], float]:
    """The neo-Hookean ball pressed through :data:`PRESSES`, each frame from the last:
    its Newton steps per frame and the last plate force (N); ``clock`` adds the timings."""
    body = FiniteBody("ball", mesh, mat)
    start, steps, force = None, [], math.nan
    for d in PRESSES:
        planes = plates(d)
        out = solve_finite_frame([body], [ContactPair(body, p) for p in planes], planes,
                                 start=start)
        if not out.converged:
            raise RuntimeError(f"finite frame at d/R {d}: {out.stop_reason}")
        steps.append(out.steps)
        for k, v in out.timings.items():
            if clock is not None:
                clock[k] = clock.get(k, 0.0) + v
        start = {"ball": out.displacement["ball"]}
        force = float(out.result.obstacle_forces["plate"][2])
    return steps, force


def linear_presses(mesh: fem.Mesh, mat: fem.LinearElastic) -> float:
    """The linear ball pressed to each of :data:`PRESSES` from rest: the last plate force (N)."""
    force = math.nan
    for d in PRESSES:
        body = ElasticBody("ball", mesh, mat)
        planes = plates(d)
        res = solve_frame([body], [ContactPair(body, p) for p in planes], planes,
                          ContactSettings())
        if not res.converged:
            raise RuntimeError(f"linear frame at d/R {d}: {res.stop_reason}")
        force = float(res.obstacle_forces["plate"][2])
    return force


def run(quick: bool = False, out: str | Path | None = None) -> list[dict]:
    """Run the study and write ``finite.{csv,md}``; one row per mesh."""
    folder = results_dir(out, quick)
    info = machine_info()
    mat = fem.LinearElastic(E, NU)
    rows: list[dict] = []
    # warm both paths (imports, compiled kernels) so that neither run pays them
    warm = ball(SIZES[quick][0])
    linear_presses(warm, mat)
    finite_presses(warm, mat)
    for n in SIZES[quick]:
        mesh = ball(n)
        gc.collect()
        with PeakMemory() as mem_lin:
            t0 = time.perf_counter()
            f_lin = linear_presses(mesh, mat)
            t_lin = time.perf_counter() - t0
        gc.collect()
        with PeakMemory() as mem_fin:
            t0 = time.perf_counter()
            clock: dict[str, float] = {}
            steps, f_fin = finite_presses(mesh, mat, clock)
            t_fin = time.perf_counter() - t0
        rows.append({
            "divisions": n, "h_over_R": surface_edge(mesh) / R, "dofs": mesh.n_dofs,
            "steps": " ".join(map(str, steps)),
            "steps_max": max(steps), "steps_mean": float(np.mean(steps)),
            "force_finite": f_fin, "force_linear": f_lin, "finite_s": t_fin,
            "linear_s": t_lin, "time_ratio": t_fin / t_lin,
            "memory_ratio": mem_fin.peak / mem_lin.peak,
            "finite_mib": mem_fin.increment / 2**20, "linear_mib": mem_lin.increment / 2**20,
            "load": load_average(),
            **{f"{k.replace(' ', '_')}_s": v for k, v in clock.items()},
        })  # fmt: skip
        print(f"[finite] {mesh.n_dofs:>7,} DOFs: steps {steps}, force {f_fin:.4f} N "
              f"(linear {f_lin:.4f}), time x{t_fin / t_lin:.2f}", flush=True)
    write_csv(folder / "finite.csv", rows, [c.key for c in COLUMNS] + ["steps_mean", "load"])
    sections = [("Per mesh", markdown_table(rows, COLUMNS)), ("Goals", _goals(rows))]
    if not quick:  # a minute: the full run's
        example = example_rows()
        write_csv(folder / "finite_example.csv", example, [c.key for c in EXAMPLE_COLUMNS])
        table = markdown_table(example, EXAMPLE_COLUMNS)
        sections.append(("The README example", table + "\n\n" + example_section(example)))
        for row in example[1:]:
            if row["frame_s"] is None or example[0]["frame_s"] is None:
                print(f"[finite] README example: {row['model']}: {row.get('error')}", flush=True)
                continue
            print(f"[finite] README example t = 1: {row['model']} / linear "
                  f"x{row['frame_s'] / example[0]['frame_s']:.1f}", flush=True)
    write_markdown(
        folder / "finite.md",
        "Finite strain: a free ball squeezed to d/R 0.2 between plates",
        info,
        sections,
    )
    return rows


def ball(divisions: int) -> fem.Mesh:
    """The study's ball: ``divisions`` cells along its core's edges, half as many layers."""
    return fem.ball_mesh(R, divisions=divisions, layers=max(divisions // 2, 1))


def surface_edge(mesh: fem.Mesh) -> float:
    """The mean edge length of ``mesh``'s boundary faces (m)."""
    edges = [np.linalg.norm(mesh.points[f] - mesh.points[np.roll(f, 1, axis=1)], axis=-1)
             for f in mesh.boundary.faces.values()]  # fmt: skip
    return float(np.concatenate([e.ravel() for e in edges]).mean())


def order(forces: list[float], ratio: float = 2.0) -> tuple[float, float] | None:
    """Observed order of three solutions on meshes each refined by ``ratio``, and the
    Richardson extrapolation of the finest (None where they do not converge monotonically)."""
    if len(forces) < 3:
        return None
    e1, e2 = forces[1] - forces[0], forces[2] - forces[1]
    if e1 == 0 or e2 == 0 or e1 / e2 <= 1:
        return None
    p = math.log(e1 / e2) / math.log(ratio)
    return p, forces[2] + e2 / (ratio**p - 1)


def _goals(rows: list[dict]) -> str:
    """The goals table: met or MISSED, with the figures."""
    most = max(r["steps_max"] for r in rows)
    means = [r["steps_mean"] for r in rows]
    # each mesh's mean steps against the mean over the meshes
    spread = max(abs(m / np.mean(means) - 1) for m in means)
    ratio = max(r["time_ratio"] for r in rows)
    memory = max(r["memory_ratio"] for r in rows)
    orders = {k: order([r[f"force_{k}"] for r in rows]) for k in ("finite", "linear")}
    lines = [
        "| goal | measured | |",
        "|---|---:|---|",
        f"| Newton steps per frame <= 8 | {most} | {'met' if most <= 8 else 'MISSED'} |",
        f"| mean steps within +-30 % over the meshes | {100 * spread:.0f} % off their mean "
        f"({' / '.join(f'{m:.2f}' for m in means)}) | {'met' if spread <= 0.3 else 'MISSED'} |",
        f"| finite frame <= 3x linear | {ratio:.2f}x | {'met' if ratio <= 3 else 'MISSED'} |",
        f"| peak RSS <= 1.5x linear | {memory:.2f}x | "
        f"{'met' if memory <= 1.5 else 'MISSED'} |",
        "",
        "Observed order of the plate force over the meshes (each twice as fine as the last): "
        + "; ".join(
            f"{k} -" if o is None
            else f"{k} {o[0]:.2f}, extrapolated {o[1]:.3f} N (the finest "
            f"{100 * abs(rows[-1][f'force_{k}'] / o[1] - 1):.1f} % off)"
            for k, o in orders.items()
        )
        + ". A free ball takes the full tangent until its steps shrink at a linear rate (its"
        " turn moves its forces), then the material one with Anderson mixing; each Newton"
        " step is a whole linear frame (assembly of the tangent, factorisation, contact"
        " solve).",
        "",
        "Where the finite frames' time goes (s): "
        + "; ".join(
            f"{r['dofs']:,} DOFs: linearising {r.get('linearise_s', 0):.2f}, linear frames "
            f"{r.get('linear_frames_s', 0):.2f}, checks {r.get('checks_s', 0):.2f}"
            for r in rows
        )
        + ". Each step is a linearisation (the tangent's assembly and the body's solver"
        " set up anew) and a whole linear frame: fewer steps (a free body's turn in the"
        " full tangent) and cheaper ones (the ordering, the zone and the solver's set-up"
        " kept from step to step) are what is left.",
    ]
    return "\n".join(lines)
