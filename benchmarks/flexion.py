"""A finger's force against its flexion through first touch: node rows and weighted gaps.

``python -m benchmarks flexion`` bends one joint of a shipped scene in steps of
:data:`STEP` from just before its fingertip touches the object (the scene's last
automatic flexion, pressed 0 mm) to well past it, each step one frame solved as the
scene solves it (the history carried), and records the finger's normal contact force:
the sum over its skin nodes, as the force-driven fingers measure it
(:func:`contact.holding.fingertargets.finger_forces`). Scenes: ``finger_press`` (the
index MCP presses a ball on a table) and ``pinch`` (the index PIP presses the ball the
thumb touches, the ball held in place: a free ball falls until the pinch holds it, and a
sweep by angle then measures its fall, not the contact). Each with the coarse, the
fingertips and the fine hand, meeting the object by node rows both ways and by one
weighted pair (``[solver] gaps``). The flesh and the ball are
linear here: each step is one linear frame, and what is measured is the contact's
discretisation, not the material.

Goal (the contact-resolution issue): no step larger than 5 % of the force at the end of
the sweep. Beside it, the largest step against the median step after touch: a force
that grows by jumps as nodes enter shows a large ratio whatever the sweep's length.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np

from contact.hand.autoflex import auto_flex, mesh_distance
from contact.hand.fingers import node_parts
from contact.run.grasprun import GraspRun
from contact.run.rolling import solve_rolled
from contact.scene import Scene, load_scene

from ._common import (
    Column,
    load_average,
    machine_info,
    markdown_table,
    results_dir,
    write_csv,
    write_markdown,
)

__all__ = ["GOAL", "STEP", "configured", "run", "sweep", "touch_angle"]

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
#: The flexion step (degrees) and the sweep's steps past first touch; ``--quick``: fewer.
STEP = 0.05
STEPS = {False: 36, True: 2}
#: Steps before first touch.
BEFORE = 4
#: The largest step, as a fraction of the force at the end of the sweep.
GOAL = 0.05
#: (scene, hand resolution) of the full run and of ``--quick``.
CASES = {
    False: (("finger_press", "coarse"), ("finger_press", "fingertips"), ("finger_press", "fine"),
            ("pinch", "coarse"), ("pinch", "fingertips"), ("pinch", "fine")),
    True: (("pinch", "coarse"),),
}  # fmt: skip
#: The scenes whose ball is held in place.
HELD = ("pinch",)

COLUMNS = (
    Column("scene", "scene"),
    Column("hand", "hand"),
    Column("gaps", "gaps"),
    Column("touch", "first touch (deg)", ".2f"),
    Column("first", "first force (deg)", ".2f"),
    Column("end_force", "force at the end (N)", ".4f"),
    Column("largest", "largest step (%)", ".1f"),
    Column("jump", "largest / median step", ".2f"),
    Column("rows", "hand rows at the end", "d"),
    Column("unsettled", "frames not converged", "d"),
    Column("frame_s", "frame (s)", ".2f"),
    Column("met", "goal"),
)


def configured(scene: Scene, resolution: str, gaps: str) -> Scene:
    """``scene`` with the hand at ``resolution``, its gaps ``gaps``, everything linear."""
    hand = scene.hand
    assert hand is not None
    flesh = dataclasses.replace(hand.flesh, model="linear")
    hand = dataclasses.replace(hand, resolution=resolution, flesh=flesh)
    ball = scene.ball and dataclasses.replace(scene.ball, model="linear")
    contact = dataclasses.replace(scene.solver.contact, gaps=gaps)
    solver = dataclasses.replace(scene.solver, contact=contact)
    return dataclasses.replace(scene, hand=hand, ball=ball, solver=solver)


def touch_angle(run: GraspRun, t: float) -> tuple[str, str, float, dict[str, float]]:
    """The scene's last automatic flexion at ``t``: its joint, finger, the angle of first
    touch (pressed 0 mm) and the angles it starts from."""
    assert run.hand is not None and run.scene.hand is not None
    run.angles(t)
    flex = [af for af in run.scene.hand.auto_flexion if af.applies(t)][-1]
    base = run.keyframes.pose(t)  # type: ignore[union-attr]
    for af in run.scene.hand.auto_flexion:
        if af.applies(t) and af is not flex:
            base[af.joint] = run.auto_flexed[af.joint]["angle"]
    res = auto_flex(run.hand, flex.point, mesh_distance(run.object_surfaces(t)), flex.joint,
                    angles=base, press=0.0, epsilon=1e-6,
                    first_contact=flex.first_contact)  # fmt: skip
    return flex.joint, str(flex.point), float(res.angle), dict(res.angles)


def sweep(scene: Scene, steps: int, fixed: bool = False) -> tuple[list[dict], float]:
    """The finger's force at each step of its joint through first touch; the touch angle.

    ``fixed``: the scene's objects held in place (rigid).
    """
    t = scene.frames[-1]
    run = GraspRun(scene)
    for o in run.objects:
        o.fixed = o.fixed or fixed
    joint, finger, touch, angles = touch_angle(run, t)
    assert run.hand is not None
    part = run.hand.part_names.index(finger)
    parts = node_parts(run.hand.flesh, len(run.hand.part_names))
    out = []
    for k in range(-BEFORE, steps + 1):
        pose = {**angles, joint: touch + STEP * k}
        t0 = time.perf_counter()
        res = solve_rolled(run, t, pose, None)[0]
        took = time.perf_counter() - t0
        fields = res.contact_fields.get("hand")
        force = 0.0 if fields is None else float(fields["normal_force"][parts == part].sum())
        names = np.asarray(res.contacts.get("pair", []), dtype=str)
        rows = int(sum("hand" in n for n in names))
        out.append({"angle": pose[joint], "force": force, "rows": rows, "frame_s": took,
                    "stop": res.stop_reason})  # fmt: skip
    return out, touch


def summary(steps: list[dict], touch: float) -> dict:
    """The sweep's figures: first force, end force, largest step (% of the end), jump, and
    how many frames did not converge (a free ball that touches nothing yet is not held)."""
    f = np.array([s["force"] for s in steps])
    a = np.array([s["angle"] for s in steps])
    d = np.abs(np.diff(f))
    on = np.flatnonzero(f > 0)
    grown = d[on[0] :] if on.size else d
    median = float(np.median(grown[grown > 0])) if (grown > 0).any() else 0.0
    largest = 100 * d.max() / f[-1] if f[-1] > 0 else float("nan")
    return {
        "touch": touch, "first": float(a[on[0]]) if on.size else float("nan"),
        "end_force": float(f[-1]), "largest": largest,
        "jump": float(d.max() / median) if median > 0 else float("nan"),
        "rows": steps[-1]["rows"], "frame_s": float(np.mean([s["frame_s"] for s in steps])),
        "unsettled": sum(s["stop"] != "converged" for s in steps),
        "met": "met" if largest <= 100 * GOAL else "MISSED",
    }  # fmt: skip


def run(quick: bool = False, out: str | Path | None = None) -> list[dict]:
    """Run the sweeps and write ``flexion.{csv,md,png}``; one row per sweep."""
    folder = results_dir(out, quick)
    info = machine_info()
    rows, curves = [], []
    for name, resolution in CASES[quick]:
        scene = load_scene(EXAMPLES / f"{name}.toml")
        for gaps in ("nodal", "weighted"):
            setup = configured(scene, resolution, gaps)
            steps, touch = sweep(setup, STEPS[quick], name in HELD)
            row = {"scene": name, "hand": resolution, "gaps": gaps, **summary(steps, touch),
                   "load": load_average()}  # fmt: skip
            rows.append(row)
            curves += [{"scene": name, "hand": resolution, "gaps": gaps, **s} for s in steps]
            print(f"[flexion] {name} {resolution} {gaps}: end {row['end_force']:.3f} N, "
                  f"largest step {row['largest']:.1f} %, jump x{row['jump']:.1f}",
                  flush=True)  # fmt: skip
    write_csv(folder / "flexion.csv", curves,
              ["scene", "hand", "gaps", "angle", "force", "rows", "frame_s", "stop"])  # fmt: skip
    note = (f"Steps of {STEP} deg from {BEFORE} steps before first touch; flesh and ball "
            f"linear. Goal: no step above {100 * GOAL:.0f} % of the end force. A frame not "
            "converged counts its force as solved (the stop of each is in the CSV).")  # fmt: skip
    sections = [("Per scene, hand and gaps", note + "\n\n" + markdown_table(rows, COLUMNS))]
    write_markdown(folder / "flexion.md", "A finger's force against its flexion", info,
                   sections)  # fmt: skip
    picture(folder / "flexion.png", curves)
    return rows


def picture(path: Path, curves: list[dict]) -> None:
    """The finger's force against its flexion, one panel per scene."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = list(dict.fromkeys(c["scene"] for c in curves))
    fig, axes = plt.subplots(1, len(scenes), figsize=(6 * len(scenes), 4.5), squeeze=False)
    for ax, name in zip(axes[0], scenes):
        keys = dict.fromkeys((c["hand"], c["gaps"]) for c in curves if c["scene"] == name)
        for i, (hand, gaps) in enumerate(keys):
            pts = [c for c in curves if (c["scene"], c["hand"], c["gaps"]) == (name, hand, gaps)]
            ax.plot([c["angle"] for c in pts], [c["force"] for c in pts],
                    "-" if gaps == "weighted" else "--", marker=".", color=f"C{i // 2}",
                    label=f"{hand} hand, {gaps}")  # fmt: skip
        ax.set_xlabel("flexion of the swept joint (deg)")
        ax.set_ylabel("finger's normal force (N)")
        ax.set_title(name)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
