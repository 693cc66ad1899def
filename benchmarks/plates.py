"""A ball between plates on coarse meshes: node rows against weighted gaps, against Hertz.

``python -m benchmarks plates`` presses a free solid ball (R 20 mm, E 1 MPa, nu 0.45)
between a fixed table and a plate that moves down by d = 0.2 to 1 mm (each frame from
rest, the linear model), meshed as a scene meshes it (:func:`contact.objects.ball.
make_ball`): bricks of 6 and 3 mm, tetrahedra of 3 mm (with averaged nodal pressures).
Each press is solved with the plates' gaps measured at the ball's nodes and weighted over
its smoothed faces (:mod:`contact.solver.planemortar`), and its plate force compared with
Hertz's for each contact's half of the approach. On two meshes the table is a body, a
stiff block under the ball (:func:`block`): node rows both ways against one weighted
pair between the smoothed surfaces (:mod:`contact.solver.mortar`).

Goals (the contact-resolution issue): within 15 % of Hertz at 1 mm on 6 mm bricks, 5 % at
0.6 and 1 mm on 3 mm bricks and tetrahedra; the force monotone in the approach on every
mesh; a frame at most 1.5x the node rows' (the contact rows per pair are reported).
"""

from __future__ import annotations

import itertools
import time
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

import fem
from contact.cases.hertz_theory import effective_modulus
from contact.geometry.plane import Plane
from contact.objects.ball import BallSpec, make_ball
from contact.solver import solve_frame
from contact.solver.body import ElasticBody
from contact.solver.pairs import ContactPair

from ._common import (
    Column,
    load_average,
    machine_info,
    markdown_table,
    results_dir,
    write_csv,
    write_markdown,
)

__all__ = ["MESHES", "PRESSES", "ball", "block", "hertz", "picture", "run"]

R, E, NU = 0.02, 1.0e6, 0.45
#: The plate's travel (m), in order.
PRESSES = (0.2e-3, 0.4e-3, 0.6e-3, 0.8e-3, 1.0e-3)
#: The meshes: (label, element, size, on a block); full run and ``--quick``. On a block
#: the table is a body (a stiff block under the ball): its gaps by node rows both ways,
#: or by one weighted pair, the ball the slave (:mod:`contact.solver.mortar`).
MESHES: dict[bool, tuple[tuple[str, str, float, bool], ...]] = {
    False: (("bricks 6 mm", "hex", 0.006, False), ("bricks 3 mm", "hex", 0.003, False),
            ("tetrahedra 3 mm", "tet", 0.003, False),
            ("bricks 6 mm on a block", "hex", 0.006, True),
            ("bricks 3 mm on a block", "hex", 0.003, True)),
    True: (("bricks 6 mm", "hex", 0.006, False),),
}  # fmt: skip
#: The goals: mesh label -> (presses checked (m), bound on the relative error).
GOALS = {"bricks 6 mm": ((1.0e-3,), 0.15), "bricks 3 mm": ((0.6e-3, 1.0e-3), 0.05),
         "tetrahedra 3 mm": ((0.6e-3, 1.0e-3), 0.05),
         "bricks 6 mm on a block": ((1.0e-3,), 0.15),
         "bricks 3 mm on a block": ((0.6e-3, 1.0e-3), 0.05)}  # fmt: skip

COLUMNS = (
    Column("mesh", "mesh"),
    Column("gaps", "gaps"),
    Column("press_mm", "plate down (mm)", ".1f"),
    Column("force", "plate force (N)", ".4f"),
    Column("hertz", "Hertz (N)", ".4f"),
    Column("error", "error (%)", "+.1f"),
    Column("rows", "rows per plate", "d"),
    Column("lower", "rows on the table or block", "d"),
    Column("frame_s", "frame (s)", ".3f"),
)


def hertz(press: float) -> float:
    """Each contact's force (N) of the ball pressed by ``press`` in all (m)."""
    return 4 / 3 * effective_modulus(E, NU) * np.sqrt(R) * (press / 2) ** 1.5


def ball(element: str, size: float) -> ElasticBody:
    """The study's ball of ``element`` (``"hex"`` or ``"tet"``) and ``size``, meshed as a
    scene meshes it (:func:`contact.objects.ball.make_ball`), resting on the table."""
    spec = BallSpec(radius=R, kind="solid", element=element, mesh_size=size,
                    center=(0.0, 0.0, R), E=E, nu=NU, density=1000.0,
                    nodal_pressure=True if element == "tet" else None)  # fmt: skip
    made = make_ball(spec)
    return ElasticBody("ball", made.mesh, made.material, nodal_pressure=made.nodal_pressure)


def block(size: float) -> ElasticBody:
    """A 60 x 60 x 10 mm block of bricks of ``size`` under the ball, its bottom fixed,
    1000 times stiffer than the ball: the table as a body."""
    n = round(0.06 / size)
    mesh = fem.box_mesh((0.06, 0.06, 0.01), (n, n, 2), origin=(-0.03, -0.03, -0.01))
    fixed = fem.node_dofs(np.flatnonzero(np.isclose(mesh.points[:, 2], -0.01)), [0, 1, 2])
    return ElasticBody("block", mesh, fem.LinearElastic(1000 * E, 0.3), prescribed=fixed)


def _press(
    body: ElasticBody, press: float, weighted: bool, under: ElasticBody | None = None
) -> tuple[float, int, int, float]:
    plate = Plane((0, 0, 2 * R), (0, 0, -1), motion=(0, 0, -press), name="plate")
    planes, bodies = [plate], [body]
    pairs = [ContactPair(body, plate, mortar=weighted)]
    if under is None:
        planes.append(Plane((0, 0, 0), (0, 0, 1), name="table"))
        pairs.append(ContactPair(body, planes[-1], mortar=weighted))
    elif weighted:
        bodies.append(under)
        pairs.append(ContactPair(body, under, mortar=True))
    else:
        bodies.append(under)
        pairs += [ContactPair(body, under), ContactPair(under, body)]
    t0 = time.perf_counter()
    res = solve_frame(bodies, pairs, planes)
    took = time.perf_counter() - t0
    if not res.converged:
        return float("nan"), 0, 0, took
    names = np.asarray(res.contacts["pair"])
    rows = int(np.sum(names == "ball/plate"))
    lower = int(np.sum(names != "ball/plate"))
    return float(res.obstacle_forces["plate"][2]), rows, lower, took


def run(quick: bool = False, out: str | Path | None = None) -> list[dict]:
    """Run the study and write ``plates.{csv,md}``; one row per mesh, gaps and press."""
    folder = results_dir(out, quick)
    info = machine_info()
    rows: list[dict] = []
    for label, element, size, on_block in MESHES[quick]:
        for weighted in (False, True):
            # each its own bodies, factored once with its rows' contact zone marked: each
            # press pays its solve
            body = ball(element, size)
            under = block(size) if on_block else None
            # the first frame factors the bodies and integrates a coupling between them;
            # the later ones reuse both (the same surfaces)
            first = _press(body, PRESSES[-1], weighted, under)[-1]
            for press in PRESSES:
                force, n, lower, took = _press(body, press, weighted, under)
                rows.append({
                    "mesh": label, "gaps": "weighted" if weighted else "nodal",
                    "press_mm": 1e3 * press, "force": force, "hertz": hertz(press),
                    "error": 100 * (force / hertz(press) - 1), "rows": n, "lower": lower,
                    "frame_s": took, "first_s": first, "dofs": body.mesh.n_dofs,
                    "load": load_average(),
                })  # fmt: skip
        print(f"[plates] {label}: " + ", ".join(
            f"{r['gaps']} {r['press_mm']:.1f} mm {r['error']:+.1f} %"
            for r in rows if r["mesh"] == label and r["press_mm"] in (0.6, 1.0)
        ), flush=True)  # fmt: skip
    write_csv(folder / "plates.csv", rows,
              [c.key for c in COLUMNS] + ["first_s", "dofs", "load"])  # fmt: skip
    sections = [("Per mesh, gaps and press", markdown_table(rows, COLUMNS)),
                ("Goals", goals(rows))]  # fmt: skip
    write_markdown(folder / "plates.md", "A ball between plates: node rows and weighted gaps",
                   info, sections)  # fmt: skip
    picture(folder / "plates.png", rows)
    return rows


def _section(h: float, press: float) -> dict[str, NDArray[np.float64]]:
    """The ball's section near the table, in mm: facets of ``h``, smoothed, exact, weight.

    A 2-D cut of what :mod:`contact.solver.planemortar` integrates: the chords between
    nodes ``h`` apart on the circle (the facets), the same chords Phong-smoothed through
    the nodes' normals (``alpha = 1/2``), the circle, and the pole node's weight ``N_i``.
    """
    r = 1e3 * R
    step = 1e3 * h / r
    angles = step * np.arange(-3, 4)
    nodes = np.column_stack([r * np.sin(angles), r - r * np.cos(angles)])
    normals = np.column_stack([-np.sin(angles), np.cos(angles)])  # into the ball
    s = np.linspace(0.0, 1.0, 41)[:, None]
    flat, smooth = [], []
    for a in range(len(nodes) - 1):
        x0, x1, n0, n1 = nodes[a], nodes[a + 1], normals[a], normals[a + 1]
        f = (1 - s) * x0 + s * x1
        off = (1 - s) * ((f - x0) @ n0)[:, None] * n0 + s * ((f - x1) @ n1)[:, None] * n1
        flat.append(f)
        smooth.append(f - 0.5 * off)
    t = np.linspace(angles[0], angles[-1], 400)
    return {
        "nodes": nodes, "flat": np.concatenate(flat), "smooth": np.concatenate(smooth),
        "circle": np.column_stack([r * np.sin(t), r - r * np.cos(t)]),
        "weight": np.column_stack([nodes[2:5, 0], [0.0, 1.0, 0.0]]), "plane": 1e3 * press / 2,
    }  # fmt: skip


def picture(path: Path, rows: list[dict]) -> None:
    """The section the weighted gaps integrate over, and the plate force against the press."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 4.8))
    cut = _section(0.006, PRESSES[-1])
    left.plot(*cut["circle"].T, "k-", lw=1, label="the ball (R 20 mm)")
    left.plot(*cut["flat"].T, "C0--", label="6 mm facets: node rows, weighted gaps on them")
    left.plot(*cut["smooth"].T, "C1-", label="the facets smoothed (on the circle): weighted gaps")
    left.plot(*cut["nodes"].T, "C0o")
    left.axhline(cut["plane"], color="C2", label="the table, 0.5 mm into the ball's rest shape")
    w = cut["weight"]
    left.fill_between(w[:, 0], -0.6, -0.6 + 0.4 * w[:, 1], color="C3", alpha=0.3,
                      label="the pole node's weight N_i (its row averages the gap over it)")
    left.set_xlim(-12, 12)
    left.set_ylim(-0.7, 2.5)
    left.set_xlabel("mm")
    left.set_ylabel("height above the table (mm)")
    left.set_title("The ball's section at the table: facets lie inside the sphere")
    left.legend(fontsize="x-small", loc="upper center")
    presses = 1e3 * np.asarray(PRESSES)
    right.plot(presses, [hertz(p) for p in PRESSES], "k-", label="Hertz")
    for i, mesh in enumerate(dict.fromkeys(r["mesh"] for r in rows)):
        for gaps, style in (("nodal", "--"), ("weighted", "-")):
            f = [r["force"] for r in rows if r["mesh"] == mesh and r["gaps"] == gaps]
            right.plot(presses, f, style, marker="o", color=f"C{i}", label=f"{mesh}, {gaps}")
    right.set_xlabel("plate down (mm)")
    right.set_ylabel("plate force (N)")
    right.set_title("A ball between plates against Hertz")
    right.grid(True, alpha=0.3)
    right.legend(fontsize="x-small")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def goals(rows: list[dict]) -> str:
    """The goals table for the weighted gaps, with the node rows beside them."""
    lines = ["| goal | weighted | nodal | |", "|---|---|---|---|"]
    for label, (presses, bound) in GOALS.items():
        got = {g: [r for r in rows if r["mesh"] == label and r["gaps"] == g
                   and any(np.isclose(r["press_mm"], 1e3 * p) for p in presses)]
               for g in ("weighted", "nodal")}  # fmt: skip
        if not got["weighted"]:
            continue
        worst = {g: max(abs(r["error"]) for r in v) for g, v in got.items()}
        at = " and ".join(f"{1e3 * p:.1f}" for p in presses)
        met = worst["weighted"] <= 100 * bound
        lines.append(f"| {label}: within {100 * bound:.0f} % of Hertz at {at} mm | "
                     f"{worst['weighted']:.1f} % | {worst['nodal']:.1f} % | "
                     f"{'met' if met else 'MISSED'} |")  # fmt: skip
    for g in ("weighted", "nodal"):
        bad = sorted({r["mesh"] for r in rows if r["gaps"] == g} - _monotone(rows, g))
        lines.append(f"| the force monotone in the approach ({g}) | "
                     f"{'every mesh' if not bad else 'not on ' + ', '.join(bad)} | | "
                     f"{'met' if not bad else 'MISSED'} |")  # fmt: skip
    ratio = _ratio(rows, "frame_s")
    worst = max(ratio.values())
    lines.append(f"| a frame <= 1.5x the node rows' | "
                 f"{', '.join(f'{m} x{v:.2f}' for m, v in sorted(ratio.items()))} | | "
                 f"{'met' if worst <= 1.5 else 'MISSED'} |")  # fmt: skip
    first = _ratio(rows, "first_s")
    listed = ", ".join(f"{m} x{v:.2f}" for m, v in sorted(first.items()))
    lines.append(f"| the first frame (bodies factored, a coupling integrated) | {listed} | | |")
    return "\n".join(lines)


def _ratio(rows: list[dict], key: str) -> dict[str, float]:
    """Per mesh, the weighted rows' total ``key`` time over the node rows'."""
    return {
        m: sum(r[key] for r in rows if r["mesh"] == m and r["gaps"] == "weighted")
        / sum(r[key] for r in rows if r["mesh"] == m and r["gaps"] == "nodal")
        for m in {r["mesh"] for r in rows}
    }


def _monotone(rows: list[dict], gaps: str) -> set[str]:
    """The meshes whose plate force never falls as the plate goes down (``gaps``' rows)."""
    out = set()
    for m in {r["mesh"] for r in rows}:
        f = [r["force"] for r in rows if r["mesh"] == m and r["gaps"] == gaps]
        if all(np.isfinite(f)) and all(b >= a for a, b in itertools.pairwise(f)):
            out.add(m)
    return out
