"""The hand's pinch: thumb and index hold a free ball against its weight by friction."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import fem
from contact.grasp import main
from contact.run import GraspRun
from contact.scene import load_scene
from contact.solver.held import MAX_TURN
from tests.helpers import example

ROOT = Path(__file__).resolve().parents[1]
PINCH = ROOT / "examples" / "pinch.toml"


def _scene(tmp_path: Path, model: str | None) -> Path:
    path = tmp_path / "pinch.toml"
    path.write_text(example("pinch", model))
    return path


def test_the_linear_pinch_holds_its_ball_with_the_index_force_asked(tmp_path: Path) -> None:
    run = GraspRun(load_scene(_scene(tmp_path, "linear")))
    res, extra, _, bodies = run.frame(0.5)
    assert res.converged and res.held, res.stop_reason
    index = extra["auto_flexion"]["index_pip"]
    assert index["converged"] and abs(index["reached"] - 0.3) <= 0.02 * 0.3
    ball = bodies[0]
    # the ball in balance: weight and contact forces, in force and moment
    f = res.contact_force["ball"] + ball.loads.reshape(-1, 3)
    scale = np.abs(res.contact_force["ball"]).sum()
    assert np.abs(f.sum(axis=0)).max() <= 1e-9 * scale
    c = ball.mesh.points.mean(axis=0)
    assert np.abs(np.cross(ball.mesh.points - c, f).sum(axis=0)).max() <= 1e-9 * scale * 0.0125
    # friction carries the weight: the pinch axis is nearly horizontal
    weight = -ball.loads.reshape(-1, 3).sum(axis=0)[2]
    assert res.friction is not None and res.friction.max_cone_use <= 1 + 1e-12
    assert res.total_contact_force("ball")[2] == pytest.approx(weight, rel=1e-9)
    # what turn is left to the linear model is small: the ball placed anew where it rolled
    _, omega = fem.rigid_part(ball.mesh.points, res.displacement["ball"])
    assert np.linalg.norm(omega) <= MAX_TURN


@pytest.mark.slow
def test_the_shipped_pinch_holds_its_ball_at_both_forces(tmp_path: Path) -> None:
    # ball and flesh neo-Hookean: the index presses 0.3 N, then 0.6 N; the ball balances
    # on its deformed placement
    run = GraspRun(load_scene(_scene(tmp_path, None)))
    for t, force in ((0.5, 0.3), (1.0, 0.6)):
        res, extra, _, bodies = run.frame(t)
        assert res.converged and res.held, res.stop_reason
        index = extra["auto_flexion"]["index_pip"]
        assert index["converged"] and abs(index["reached"] - force) <= 0.02 * force
        ball = bodies[0]
        assert ball.finite
        f = res.contact_force["ball"] + ball.loads.reshape(-1, 3)
        scale = np.abs(res.contact_force["ball"]).sum()
        assert np.abs(f.sum(axis=0)).max() <= 1e-6 * scale
        assert res.friction is not None and res.friction.max_cone_use <= 1 + 1e-9


@pytest.mark.slow
def test_the_least_grip_grows_with_the_ball_s_mass(tmp_path: Path) -> None:
    found = {}
    for density in (1100.0, 2200.0):
        text = example("pinch").replace("density = 1100.0", f"density = {density}")
        out = tmp_path / str(density)
        text = text.replace('directory = "results/pinch"', f'directory = "{out.as_posix()}"')
        path = tmp_path / f"pinch_{density:g}.toml"
        path.write_text(text)
        # the heavier ball may slip at the scene's own grip (exit 1): the search goes on
        assert main([str(path), "--quiet", "--no-pictures", "--least-grip"]) in (0, 1)
        summary = json.loads((out / "summary.json").read_text())
        grip = summary["least_grip"]
        lo, hi = grip["bracket"]
        assert lo < hi == grip["scale"]
        found[density] = (grip["scale"], grip["found"], grip["limit"])
        # monotone in the grip: every trial above the answer held, none below it
        for tr in grip["trials"]:
            assert tr["holds"] == (tr["scale"] >= grip["scale"]), (density, tr)
    ratio = found[2200.0][0] / found[1100.0][0]
    # ball and flesh neo-Hookean, the ball turns freely: friction carries its weight, and
    # the least grip doubles with it (as the pads' does)
    assert 1.8 <= ratio <= 2.2, ratio
    assert all(f for _, f, _ in found.values()), found
    assert {lim for *_, lim in found.values()} == {"friction"}
