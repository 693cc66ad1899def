"""The least grip that holds: its accuracy on the pads, its cost and its trend on the pinch.

``python -m benchmarks holding`` runs ``--least-grip``'s search
(:func:`contact.holding.leastgrip.least_grip`) from each scene's own run, as the command line
does, and counts what it costs:

- the pads (``examples/pads.toml``): two force-driven frictional pads, gravity along them;
  the least grip per pad against ``m g / (2 mu)`` (the goal: within 1 %);
- the hand's pinch (``examples/pinch.toml``, full run only): the index force-driven; its
  trials, frame solves and contact solves (each frame solve is a force-driven finger's
  search, several contact solves; the goal: about 12 contact solves of the frame), and
  the least grip with the ball's mass doubled (the goal: 1.8 to 2.2 times, the limit
  friction), with the linear model and with the ball and flesh neo-Hookean (free to
  turn as far as the grip takes the ball).
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Any

import contact.run.grasprun
import contact.solver.finite
from contact.holding.leastgrip import judge, least_grip
from contact.run import GraspRun
from contact.scene.read import load_scene

from ._common import (
    Column,
    machine_info,
    markdown_table,
    results_dir,
    with_models,
    write_csv,
    write_markdown,
)

__all__ = ["run"]

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
#: The pinch's contact solves that the goal allows for the whole search.
SOLVE_GOAL = 12

COLUMNS = (
    Column("scene", "scene"),
    Column("case", "case"),
    Column("trials", "trials", "d"),
    Column("frame_solves", "frame solves", "d"),
    Column("contact_solves", "contact solves", "d"),
    Column("seconds", "s", ".1f"),
    Column("scale", "least grip (scale)", ".4f"),
    Column("bracket", "bracket"),
    Column("forces", "per pad or finger (N)"),
    Column("limit", "limit"),
    Column("exact", "exact (N)", ".4f"),
    Column("error", "error", ".2%"),
)


def _search(scene: Any, name: str, case: str) -> dict[str, Any]:
    """The scene's own run, then the search from it, counting contact solves."""
    calls = [0]
    solve = contact.run.grasprun.solve_frame  # linear frames, and each Newton step's

    def counted(*args: Any, **kw: Any) -> Any:
        calls[0] += 1
        return solve(*args, **kw)

    contact.run.grasprun.solve_frame = counted
    contact.solver.finite.solve_frame = counted
    try:
        run = GraspRun(scene)
        times = list(scene.frames)
        own = [run.frame(t)[0] for t in times]
        before = calls[0]
        t0 = time.perf_counter()
        own_trial = judge(1.0, own, times, scene)
        first = dataclasses.replace(own_trial, solves=0)  # the scene's own run, reused
        found = least_grip(run, times, first=first)
        seconds = time.perf_counter() - t0
    finally:
        contact.run.grasprun.solve_frame = solve
        contact.solver.finite.solve_frame = solve
    lo, hi = found.lo, found.hi
    return {
        "scene": name,
        "case": case,
        "trials": found.steps,
        "frame_solves": found.solves,
        "contact_solves": calls[0] - before,
        "seconds": seconds,
        "scale": found.scale,
        "bracket": f"{lo:.4f} .. {hi:.4f}" if lo is not None and hi is not None else "-",
        "forces": ", ".join(f"{k} {v:.4g}" for k, v in found.forces.items()),
        "limit": found.limit or "-",
        "found": found.found,
    }


def _pads() -> dict[str, Any]:
    scene = load_scene(EXAMPLES / "pads.toml")
    row = _search(scene, "pads", "mu 0.5, gravity along the pads")
    run = GraspRun(scene)
    weight = float(-run.ball_body(scene.frames[0]).loads.reshape(-1, 3).sum(axis=0)[2])
    mu = scene.friction(scene.planes[0].name)
    exact = weight / (2 * mu)
    # the search holds every frame: the first frame's force decides (the ramp rises)
    first = scene.planes[0].force_at(scene.frames[0]) * row["scale"]
    row.update(exact=exact, error=abs(first - exact) / exact)
    return row


def _pinch(finite: bool) -> list[dict[str, Any]]:
    scene = load_scene(EXAMPLES / "pinch.toml")
    name = "hand pinch, neo-Hookean" if finite else "hand pinch"
    model = "neo-hookean" if finite else "linear"
    scene = with_models(scene, flesh=model, ball=model)
    rows = [_search(scene, name, "its own ball")]
    heavy = dataclasses.replace(
        scene, ball=dataclasses.replace(scene.ball, density=2.0 * scene.ball.density)
    )
    rows.append(_search(heavy, name, "the ball's mass doubled"))
    return rows


def _doubled(own: dict[str, Any], heavy: dict[str, Any]) -> str:
    """The goal line of a pinch's least grip with its ball's mass doubled."""
    if not own["scale"] or not heavy["scale"]:
        return f"- {own['scene']}, mass doubled: no least grip found: **missed**."
    ratio = heavy["scale"] / own["scale"]
    met = 1.8 <= ratio <= 2.2 and own["limit"] == heavy["limit"] == "friction"
    return (
        f"- {own['scene']}, mass doubled: least grip x{ratio:.3f}, limits "
        f"{own['limit']} and {heavy['limit']} (goal 1.8 to 2.2, friction): "
        f"{'met' if met else '**missed**'}."
    )


def run(quick: bool = False, out: str | None = None) -> list[dict[str, Any]]:
    """Run the study; write ``holding.csv`` and ``holding.md``; return the rows."""
    folder = results_dir(out, quick)
    rows = [_pads()] + ([] if quick else _pinch(False) + _pinch(True))
    keys = [c.key for c in COLUMNS] + ["found"]
    write_csv(folder / "holding.csv", rows, keys)
    pads = rows[0]
    goals = [
        f"- Pads: least grip per pad {pads['error']:.2%} off `m g / (2 mu)` (goal 1 %): "
        f"{'met' if pads['error'] <= 0.01 else '**missed**'}."
    ]
    if not quick:
        own = rows[1]
        goals.append(
            f"- Pinch: {own['contact_solves']} contact solves in {own['frame_solves']} frame "
            f"solves and {own['trials']} trials, {own['seconds']:.1f} s (goal about "
            f"{SOLVE_GOAL} contact solves): "
            f"{'met' if own['contact_solves'] <= SOLVE_GOAL else '**missed**'}."
        )
        goals += [_doubled(rows[1], rows[2]), _doubled(rows[3], rows[4])]
    sections = [
        ("Goals", "\n".join(goals)),
        ("Searches", markdown_table(rows, COLUMNS)),
        (
            "How",
            "Each search starts from the scene's own run (trial 1, not counted) as "
            "`--least-grip` does. A contact solve is one `solve_frame`: a force-driven "
            "finger's search takes several per frame solve, and a ball that rolls is "
            "placed anew and solved again.",
        ),
    ]
    write_markdown(folder / "holding.md", "The least grip that holds", machine_info(), sections)
    return rows
