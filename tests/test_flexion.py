"""A finger's force against its flexion: the hand meets a ball by weighted gaps.

``benchmarks/flexion.py`` sweeps a finger by 0.05 deg steps through first touch. Here a
few steps: the index pressing the finger-press ball (the fingertips hand; the fine one,
slow) and pinching a ball held in place (the coarse hand, slow): by weighted gaps the force
starts near where node rows' does and grows in steady increments, no node entering makes
it jump.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from benchmarks.flexion import BEFORE, configured, sweep
from contact.objects.placed import body_pairs
from contact.run.grasprun import GraspRun
from contact.scene import load_scene
from contact.solver.body import ElasticBody

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def _press(gaps: str, steps: int, name: str = "finger_press", hand: str = "fine"):
    scene = configured(load_scene(EXAMPLES / f"{name}.toml"), hand, gaps)
    out, touch = sweep(scene, steps, fixed=name == "pinch")
    return np.array([s["force"] for s in out]), touch


def test_the_hand_meets_an_object_by_one_weighted_pair_where_gaps_ask() -> None:
    import fem

    mesh = fem.box_mesh((0.01, 0.01, 0.01), (2, 2, 2))
    soft, stiff = fem.LinearElastic(1e4, 0.3), fem.LinearElastic(1e6, 0.3)
    ball = ElasticBody("ball", mesh, stiff)
    fine = fem.box_mesh((0.01, 0.01, 0.01), (4, 4, 4), origin=(0.0, 0.0, 0.01))
    hand = ElasticBody("hand", fine, soft)
    mu = lambda a, b: 0.5  # noqa: E731
    nodal = body_pairs([ball], hand, mu, "nodal")
    assert [(p.slave.name, p.master.name, p.mortar) for p in nodal] == [
        ("ball", "hand", False), ("hand", "ball", False)]  # fmt: skip
    (pair,) = body_pairs([ball], hand, mu, "weighted")
    assert (pair.slave.name, pair.master.name, pair.mortar, pair.friction) == (
        "hand", "ball", True, 0.5)  # fmt: skip


@pytest.mark.slow
def test_the_coarse_pinch_by_weighted_gaps_starts_at_touch_and_grows_steadily() -> None:
    force, _ = _press("weighted", 8, "pinch", "coarse")
    on = np.flatnonzero(force > 0)[0]
    assert BEFORE - 1 <= on <= BEFORE + 1, on
    d = np.diff(force[on:])
    assert (d > 0).all() and d.max() <= 1.5 * np.median(d), d


@pytest.mark.parametrize(
    "hand", ["fingertips", pytest.param("fine", marks=pytest.mark.slow)]
)
def test_weighted_gaps_on_a_fine_fingertip_grow_the_force_without_jumps(hand: str) -> None:
    force, _ = _press("weighted", 8, hand=hand)
    on = np.flatnonzero(force > 0)[0]
    # a weighted gap closes once the press passes the mean overlap over a node's faces:
    # within 0.2 deg (about 0.2 mm) of first touch by the fingertip's nodes
    assert BEFORE - 1 <= on <= BEFORE + 4, on
    d = np.diff(force[on:])
    assert (d > 0).all()
    # steady growth (a Hertz-like force's steps grow slowly): none twice the median
    assert d.max() <= 2.0 * np.median(d), d


@pytest.mark.slow
def test_weighted_and_node_rows_agree_on_the_fine_hand() -> None:
    weighted, touch = _press("weighted", 12)
    nodal, touch_n = _press("nodal", 12)
    assert touch == touch_n
    on_w, on_n = np.flatnonzero(weighted > 0)[0], np.flatnonzero(nodal > 0)[0]
    assert 0 <= on_w - on_n <= 4
    assert weighted[-1] == pytest.approx(nodal[-1], rel=0.2)


def _pinch(eps: float) -> tuple[bool, bool | None, float]:
    scene = configured(load_scene(EXAMPLES / "pinch.toml"), "coarse", "weighted")
    ball = scene.ball
    assert ball is not None
    moved = tuple(x * (1 + eps) for x in ball.center)
    placed = dataclasses.replace(ball, center=moved, mesh_size=0.004)  # a coarser ball: quick
    run = GraspRun(dataclasses.replace(scene, ball=placed))
    res, extra, _, _ = run.frame(0.5)
    return res.converged, res.held, extra["auto_flexion"]["index_pip"]["reached"]


def test_the_pinch_by_weighted_gaps_holds_at_its_force_and_round_off_leaves_it() -> None:
    # the free ball pinched by the thumb and the force-driven index (0.3 N), skin friction
    # 0.8, by one weighted pair; the ball placed 1e-15 apart gives the same verdict
    converged, held, reached = _pinch(0.0)
    assert converged and held and reached == pytest.approx(0.3, rel=0.02)
    twin = _pinch(1e-15)
    assert twin[:2] == (converged, held) and twin[2] == pytest.approx(reached, rel=1e-8)


@pytest.mark.slow
def test_the_fingertip_press_example_gives_the_finger_press_verdicts(tmp_path) -> None:
    """The shipped press resolved on the fingertip (fingertips hand, weighted gaps) holds
    where the coarse one does, every frame converged and realistic, and its index force
    grows with the press, near the coarse hand's (1 mm into the ball: 0.18 against 0.20 N;
    the coarse fingertip is the stiffer)."""
    import json

    from contact.grasp import main

    out = {}
    for name in ("finger_press", "fingertip_press"):
        folder = tmp_path / name
        assert main([str(EXAMPLES / f"{name}.toml"), "--no-pictures", "--quiet", "--out",
                     str(folder)]) == 0  # fmt: skip
        out[name] = json.loads((folder / "summary.json").read_text())["frames"]
    for coarse, tips in zip(out["finger_press"], out["fingertip_press"], strict=True):
        assert tips["converged"] and tips["held"] and tips["verdict"] == coarse["verdict"]
    force = [f["fingers"]["index"]["normal"] for f in out["fingertip_press"]]
    coarse = [f["fingers"]["index"]["normal"] for f in out["finger_press"]]
    assert force[0] == 0.0 < force[1] < force[2]
    assert force[2] == pytest.approx(coarse[2], rel=0.25)
