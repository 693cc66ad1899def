"""A scene's neo-Hookean bodies: the ``model`` key, the run's finite frames and their results.

The index of finger_press pressing a little into a ball gives the linear forces, its
bones carrying what its skin takes. A free ball squeezed by two force-driven frictional
pads is solved linear and neo-Hookean from the same scene: at a small squeeze the two
agree; at a large one the finite run converges by Newton, is held, writes Cauchy stress
and log strain, and gives no strain warning. A hollow ball's pressure becomes a
follower load that is the linear pressure load at rest.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import meshio
import numpy as np
import pytest

from contact.errors import SceneError
from contact.grasp import main
from contact.objects.ball import BallSpec, make_ball
from contact.objects.placed import from_ball
from contact.run import GraspRun
from contact.scene import load_scene
from fem.follower import follower_pressure
from tests.helpers import example

ROOT = Path(__file__).resolve().parents[1]

PADS = """\
[scene]
gravity = [0.0, 0.0, {g}]

[ball]
radius = 0.02
element = "hex"
mesh_size = 0.005
material = {{ E = 1.0e6, nu = 0.45, density = 1100.0{model} }}

[[plane]]
name = "left"
point = [-0.0202, 0.0, 0.0]
normal = [1.0, 0.0, 0.0]
force = [[0.0, {force}]]
friction = 0.5

[[plane]]
name = "right"
point = [0.0202, 0.0, 0.0]
normal = [-1.0, 0.0, 0.0]
force = [[0.0, {force}]]
friction = 0.5

[frames]
times = [0.0, 1.0]

[output]
directory = "{out}"
pictures = false
"""


def _scene(tmp_path: Path, force: float, finite: bool, name: str, g: float = -9.81) -> Path:
    model = ', model = "neo-hookean"' if finite else ""
    path = tmp_path / f"{name}.toml"
    out = tmp_path / name
    path.write_text(PADS.format(model=model, force=force, out=out.as_posix(), g=g))
    return path


def test_the_model_key_is_read_and_checked(tmp_path: Path) -> None:
    sc = load_scene(_scene(tmp_path, 1.0, True, "a"))
    assert sc.ball.model == "neo-hookean"
    bad = tmp_path / "bad.toml"
    bad.write_text(_scene(tmp_path, 1.0, True, "b").read_text().replace("neo-hookean", "rubber"))
    with pytest.raises(SceneError, match=r"ball\.material\.model"):
        load_scene(bad)


def test_a_small_squeeze_is_the_linear_one(tmp_path: Path) -> None:
    # 0.05 N a pad, no weight: a strain of a few 1e-3, where the law is the linear model
    moved = {}
    for finite in (False, True):
        run = GraspRun(load_scene(_scene(tmp_path, 0.05, finite, f"s{finite}", g=0.0)))
        res, extra, _, bodies = run.frame(0.0)
        assert res.converged and res.held is not False, res.stop_reason
        assert ("newton" in extra) == finite and bodies[0].finite == finite
        moved[finite] = res.plane_positions["left"][0]
    assert moved[True] == pytest.approx(moved[False], rel=0.01)


def test_a_hard_squeeze_runs_at_finite_strain(tmp_path: Path, caplog) -> None:
    # 6 N a pad squeezes the soft ball past 10 % strain
    scene = _scene(tmp_path, 6.0, True, "hard")
    with caplog.at_level(logging.WARNING):
        assert main([str(scene)]) == 0
    assert "strain" not in caplog.text  # the warning is the linear model's
    summary = json.loads((tmp_path / "hard" / "summary.json").read_text())
    for frame in summary["frames"]:
        assert frame["newton"]["converged"] and frame["newton"]["steps"] <= 12
        assert frame["held"] is True
    strain = summary["frames"][-1]["max_strain"]["ball"]
    assert 0.1 < strain < 0.5
    vtu = meshio.read(tmp_path / "hard" / "ball_0001.vtu")
    logs = vtu.cell_data["max_log_strain"][0]
    assert logs.max() == pytest.approx(strain)
    # the pads' squeeze is carried by the ball's Cauchy stress: compressive along x
    sigma = vtu.cell_data["stress"][0]
    assert np.median(sigma[:, 0]) < 0


def test_a_hollow_balls_pressure_follows_its_cavity() -> None:
    spec = BallSpec(0.02, kind="hollow", thickness=0.008, pressure=2e4, mesh_size=0.004,
                    model="neo-hookean")  # fmt: skip
    ball = make_ball(spec)
    obj = from_ball(ball, None)
    assert obj.finite and not obj.rolls and not obj.loads.any()
    faces, p = obj.follower
    f = follower_pressure(ball.mesh, faces, p, np.zeros(ball.mesh.n_dofs))[0]
    assert np.abs(f - ball.loads).max() <= 1e-9 * np.abs(ball.loads).max()
    linear = from_ball(make_ball(BallSpec(0.02, kind="hollow", thickness=0.008, pressure=2e4,
                                          mesh_size=0.004)), None)  # fmt: skip
    assert linear.follower is None and not linear.finite and linear.rolls


def test_a_finite_finger_press_is_the_linear_one_at_a_small_press(tmp_path: Path) -> None:
    # the index presses 0.05 mm into a ball in a frictionless bowl: flesh and ball
    # neo-Hookean give the linear forces; the bones carry what the skin takes. The law's
    # volume is the nodes' averaged one: the linear flesh's likewise (plain linear
    # tetrahedra at nu 0.45 lock, and press 16 % harder here)
    text = example("finger_press", "linear").replace("press = 0.0005 ", "press = 0.00005")
    flesh = 'flesh = { E = 5.0e4, nu = 0.45, model = "linear" }'
    assert flesh in text
    text = text.replace(flesh, flesh + "\nnodal_pressure = true")
    text = text.replace('"results/finger_press"', f'"{tmp_path.as_posix()}"')
    forces = {}
    for finite in (False, True):
        scene = text
        if finite:
            scene = scene.replace('model = "linear"', 'model = "neo-hookean"')
            model = ', model = "neo-hookean" }'
            scene = scene.replace("density = 1100.0 }", "density = 1100.0" + model)
        path = tmp_path / f"press_{finite}.toml"
        path.write_text(scene)
        run = GraspRun(load_scene(path))
        res, _, _, bodies = run.frame(0.5)
        assert res.converged, res.stop_reason
        assert [b.finite for b in bodies] == [finite, finite]
        skin = res.contact_force["hand"].sum(axis=0)
        bones = sum(np.asarray(f) for f in res.support_forces["hand"].values())
        assert np.abs(skin + bones).max() <= 1e-6 * np.linalg.norm(skin)
        forces[finite] = skin
    assert np.linalg.norm(forces[True] - forces[False]) <= 0.03 * np.linalg.norm(forces[False])


def test_a_round_off_change_leaves_the_finite_verdict(tmp_path: Path) -> None:
    # the hard squeeze with the pads' force changed by 1e-15 relative: the same verdict,
    # the same Newton outcome, the same squeeze
    seen = []
    for k, force in enumerate((6.0, 6.0 * (1 + 1e-15), 6.0 * (1 - 1e-15))):
        run = GraspRun(load_scene(_scene(tmp_path, force, True, f"r{k}")))
        res, extra, _, _ = run.frame(0.0)
        seen.append((res.held, res.converged, extra["newton"]["converged"]))
        seen[-1] += (res.plane_positions["left"][0],)
    assert all(s[:3] == (True, True, True) for s in seen)
    assert max(abs(s[3] - seen[0][3]) for s in seen) <= 1e-8 * abs(seen[0][3])


def _with_neo_hookean_flesh(tmp_path: Path, name: str, frames: list[str]) -> list[dict]:
    """The shipped example ``name`` (its flesh neo-Hookean) run at ``frames``: their records."""
    text = example(name)
    assert 'flesh = { E = 5.0e4, nu = 0.45, density = 1000.0, model = "neo-hookean" }' in text
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    out = tmp_path / "out"
    args = [str(path), "--out", str(out), "--frames", *frames, "--no-pictures", "--quiet"]
    assert main(args) == 0
    return json.loads((out / "summary.json").read_text())["frames"]


def test_the_readme_hand_closes_its_neo_hookean_flesh_on_the_ball(tmp_path: Path) -> None:
    # every finger and the thumb close 1 mm into the hollow ball (automatic flexion): with
    # neo-Hookean flesh each carries part of the grip, as with linear flesh, and Newton
    # settles the frame in one go (anchors re-met in every step had it creep, stall, cut
    # the frame and let the ball roll off three fingers)
    closed = _with_neo_hookean_flesh(tmp_path, "grasp", ["0", "1", "2"])[2]
    assert closed["converged"] and closed["held"] and closed["verdict"]["realistic"]
    assert closed["newton"]["steps"] <= 20
    fingers = closed["fingers"]
    assert all(fingers[f]["normal"] > 0.05 for f in ("thumb", "index", "middle", "ring", "little"))


@pytest.mark.slow
def test_the_bowl_closes_its_neo_hookean_hand_on_the_ball(tmp_path: Path) -> None:
    # frictionless: once a contact flips, Newton's next step searches where the last left
    # the free ball, so a contact with the bowl it closed stays a candidate (from rest the
    # tolerance took it one step and dropped it the next, and Newton stalled at 1e-4)
    closed = _with_neo_hookean_flesh(tmp_path, "bowl", ["2"])[0]
    assert closed["converged"] and closed["held"] and closed["verdict"]["realistic"]
    assert closed["newton"]["steps"] <= 20
