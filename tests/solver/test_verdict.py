"""Honest verdicts: a free ball that no contact holds is "not held", a result and not bad
input; a ball placed inside a plane or the skin at the start is warned of."""

import json
import logging

import numpy as np
import pytest

import fem
from contact.geometry.plane import Plane
from contact.grasp import run
from contact.run import GraspRun
from contact.scene.read import load_scene
from contact.solver import ContactSettings, solve_frame
from contact.solver.body import ElasticBody
from contact.solver.pairs import ContactPair

R = 0.02
G = 9.81


def falling_ball(center=(0.0, 0.0, R)):
    """A small free ball under gravity along -z."""
    mesh = fem.ball_mesh(R, divisions=4, layers=2, center=center)
    mat = fem.LinearElastic(1e5, 0.3, density=1000.0)
    return ElasticBody("ball", mesh, mat, loads=fem.gravity_load(mesh, mat))


def weight(ball):
    return ball.loads.reshape(-1, 3).sum(axis=0)


def along(reason):
    """The direction ``(x, y, z)`` a stop reason names."""
    text = reason.split("along (")[1].split(")")[0]
    return np.array([float(v) for v in text.split(",")])


def test_a_ball_on_a_tilted_frictionless_table_slides_down_and_is_not_held():
    a = np.radians(15.0)
    n = np.array([np.sin(a), 0.0, np.cos(a)])  # the table rises towards -x
    ball = falling_ball(tuple(R * n))  # touching the table at the origin
    table = Plane([0, 0, 0], n, name="table")
    res = solve_frame([ball], [ContactPair(ball, table)], [table], ContactSettings())
    assert not res.converged
    assert res.held is False
    assert res.stop_reason.startswith("not held: ball moves along (")
    w = weight(ball)
    downhill = w - (w @ n) * n
    assert along(res.stop_reason) @ (downhill / np.linalg.norm(downhill)) > 0.99
    # the load carried by no contact: the weight's part along the slope
    carried = float(res.stop_reason.split("): ")[1].split(" N")[0])
    assert carried == pytest.approx(np.linalg.norm(downhill), rel=1e-3)
    # the last state is kept: the table carries the weight's normal part, the ball stays
    table_force = res.obstacle_forces["table"]
    assert -table_force @ n == pytest.approx(-(w @ n), rel=1e-3)
    assert np.isfinite(res.displacement["ball"]).all()
    assert np.abs(res.displacement["ball"]).max() < 0.1 * R


def test_a_ball_with_nothing_under_it_falls_and_is_not_held():
    ball = falling_ball()
    res = solve_frame([ball], [], [], ContactSettings())
    assert not res.converged and res.held is False
    assert res.stop_reason.startswith("not held: ball moves along (")
    assert along(res.stop_reason) == pytest.approx([0.0, 0.0, -1.0], abs=1e-3)
    assert f"{np.linalg.norm(weight(ball)):.4g} N" in res.stop_reason
    # a table far below: the same
    far = Plane([0, 0, -1.0], [0, 0, 1], name="table")
    res = solve_frame([ball], [ContactPair(ball, far)], [far], ContactSettings())
    assert res.stop_reason.startswith("not held: ball moves along (")


def test_the_seed_loop_says_the_same():
    ball = falling_ball()
    far = Plane([0, 0, -1.0], [0, 0, 1], name="table")
    res = solve_frame([ball], [ContactPair(ball, far)], [far], ContactSettings(algorithm="seed"))
    assert not res.converged and res.held is False
    assert res.stop_reason.startswith("not held: ball moves along (")
    assert along(res.stop_reason) == pytest.approx([0.0, 0.0, -1.0], abs=1e-3)


def test_a_ball_one_plane_pushes_with_nothing_behind_touches_nothing():
    # no gravity: the plane, moved 1 mm into the ball, pushes it away until it opens
    mesh = fem.ball_mesh(R, divisions=4, layers=2, center=(0, 0, R))
    ball = ElasticBody("ball", mesh, fem.LinearElastic(1e5, 0.3))
    plane = Plane([0, 0, 0], [0, 0, 1], motion=[0, 0, 0.001], name="pusher")
    for algorithm in ("contact-space", "seed"):
        res = solve_frame(
            [ball], [ContactPair(ball, plane)], [plane], ContactSettings(algorithm=algorithm)
        )
        assert not res.converged and res.held is False, algorithm
        assert res.stop_reason.startswith("not held: ball touches nothing (moved 1 mm along (")
        assert along(res.stop_reason) == pytest.approx([0.0, 0.0, 1.0], abs=1e-3)
        # round-off of the press's force scale (E R d = 2 N)
        assert np.abs(res.total_contact_force("ball")).max() <= 1e-12


def test_a_ball_two_plates_touch_before_they_press_is_left_alone():
    # nothing loads it and it does not move: resting on its contacts at zero force
    mesh = fem.ball_mesh(R, divisions=4, layers=2, center=(0, 0, R))
    ball = ElasticBody("ball", mesh, fem.LinearElastic(1e5, 0.3))
    table = Plane([0, 0, 0], [0, 0, 1], name="table")
    plate = Plane([0, 0, 2 * R], [0, 0, -1], name="plate")
    pairs = [ContactPair(ball, table), ContactPair(ball, plate)]
    res = solve_frame([ball], pairs, [table, plate], ContactSettings())
    assert res.converged, res.stop_reason


SCENE = """
[scene]
name = "verdict"
{gravity}

[ball]
radius = 0.02
kind = "solid"
element = "hex"
mesh_size = 0.008
center = [0.0, 0.0, {z}]
material = {{ E = 1.0e5, nu = 0.3, density = 1000.0 }}

{planes}

[frames]
times = [0.5, 1.0]

[solver]
algorithm = "contact-space"
"""
TABLE = """
[[plane]]
name = "table"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
"""
PLATE = """
[[plane]]
name = "plate"
point = [0.0, 0.0, 0.04]
normal = [0.0, 0.0, -1.0]
offsets = [[0.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, -0.001]]
"""


def scene_file(tmp_path, z=0.02, gravity=True, planes=TABLE):
    path = tmp_path / "scene.toml"
    g = "gravity = [0.0, 0.0, -9.81]" if gravity else ""
    path.write_text(SCENE.format(gravity=g, z=z, planes=planes))
    return path


def test_the_command_line_writes_a_ball_that_falls_and_exits_1(tmp_path):
    out = tmp_path / "out"
    status = run(scene_file(tmp_path, planes=""), out=out, pictures=False, quiet=True)
    assert status == 1  # a result, not bad input (2)
    summary = json.loads((out / "summary.json").read_text())
    for frame in summary["frames"]:
        assert not frame["verdict"]["realistic"]
        assert "not held: ball moves along (0.000, 0.000, -1.000)" in frame["stop_reason"]


def test_a_ball_placed_inside_a_plane_is_warned_of(tmp_path, caplog):
    # the ball's centre 1 mm too low: its bottom starts 1 mm inside the table
    run_ = GraspRun(load_scene(scene_file(tmp_path, z=0.019, gravity=False)))
    with caplog.at_level(logging.WARNING, logger="contact.run"):
        run_.frame(0.5)
        run_.frame(1.0)
    lines = [r.getMessage() for r in caplog.records if "overlap" in r.getMessage()]
    assert len(lines) == 1  # at the scene's start only
    assert lines[0].startswith("t = 0.5: ball/table overlap at the start: node ")
    assert " of ball is 1 mm inside table" in lines[0]


def test_a_plate_the_scene_moves_into_the_ball_is_not_warned_of(tmp_path, caplog):
    run_ = GraspRun(load_scene(scene_file(tmp_path, gravity=False, planes=TABLE + PLATE)))
    with caplog.at_level(logging.WARNING, logger="contact.run"):
        res, *_ = run_.frame(0.5)
    assert res.converged, res.stop_reason
    assert not [r for r in caplog.records if "overlap" in r.getMessage()]
