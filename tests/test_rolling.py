"""A free ball that rolls: its rigid part, its placement anew, the history re-expressed."""

from __future__ import annotations

import numpy as np
import pytest

from contact.run.rolling import turned_placement
from contact.solver.anchors import Anchors
from fem import rigid_part


@pytest.fixture
def points():
    rng = np.random.default_rng(3)
    return rng.normal(size=(200, 3)) * 0.01 + [0.1, -0.2, 0.05]


def test_the_rigid_part_of_a_small_motion_is_found(points):
    c = points.mean(axis=0)
    t, omega = np.array([1e-3, -2e-3, 5e-4]), np.array([0.02, -0.01, 0.03])
    u = t + np.cross(omega, points - c)
    t_fit, omega_fit = rigid_part(points, u)
    assert t_fit == pytest.approx(t, abs=1e-15)
    assert omega_fit == pytest.approx(omega, abs=1e-12)
    # a stretch along the axes of the points' own spread turns nothing
    spread = np.linalg.eigh((points - c).T @ (points - c))[1]
    stretch = (points - c) @ spread @ np.diag([1e-3, -5e-4, 2e-4]) @ spread.T
    assert rigid_part(points, stretch)[1] == pytest.approx(np.zeros(3), abs=1e-15)


def test_a_placement_anew_turns_by_the_finite_rotation(points):
    c = points.mean(axis=0)
    axis = np.array([1.0, 2.0, -2.0]) / 3.0
    angle = 0.4
    tf = turned_placement(points, [0.01, 0.0, 0.0], angle * axis)
    rot = tf[:3, :3]
    assert rot @ rot.T == pytest.approx(np.eye(3), abs=1e-14)
    assert np.linalg.det(rot) == pytest.approx(1.0)
    assert rot @ axis == pytest.approx(axis)  # about the axis
    assert np.arccos((np.trace(rot) - 1) / 2) == pytest.approx(angle)  # by the angle
    moved = points @ rot.T + tf[:3, 3]
    assert moved.mean(axis=0) == pytest.approx(c + np.array([0.01, 0.0, 0.0]))  # moved by t
    # distances kept: a rigid motion, not the linear one (which stretches by angle^2 / 2)
    d0 = np.linalg.norm(points - c, axis=1)
    assert np.linalg.norm(moved - moved.mean(axis=0), axis=1) == pytest.approx(d0)
    linear = points + np.cross(angle * axis, points - c)
    stretch = np.linalg.norm(linear - linear.mean(axis=0), axis=1) / d0
    assert stretch.max() > 1 + 0.9 * (np.sqrt(1 + angle**2) - 1)


class _Body:
    def __init__(self, name, points):
        self.name = name
        self.mesh = type("M", (), {"points": points, "n_points": len(points)})()


def test_the_history_is_where_the_nodes_were_from_a_new_placement(points):
    u = np.full_like(points, 1e-4)
    tf = turned_placement(points, [0.0, 0.002, 0.0], [0.0, 0.0, 0.3])
    anew = points @ tf[:3, :3].T + tf[:3, 3]
    anchors = Anchors(displacement={"ball": u}, reference={"ball": points.copy()})
    start = anchors.displaced([_Body("ball", anew)])["ball"]
    assert anew + start == pytest.approx(points + u)  # the same positions
    # no reference kept: as it was; another mesh (node count): left out
    assert Anchors(displacement={"ball": u}).displaced([_Body("ball", anew)])["ball"] is u
    assert anchors.displaced([_Body("ball", anew[:-1])]) == {}


ROLLED = """\
[scene]
gravity = [0.0, 0.0, -9.81]

[ball]
radius = 0.02
element = "hex"
mesh_size = 0.004
material = {{ E = 1.0e6, nu = 0.45, density = 1100.0 }}

[[plane]]
name = "table"
point = [0.0, 0.0, -0.02]
normal = [0.0, 0.0, 1.0]

[[plane]]
name = "wall"
point = [-0.014142, 0.0, 0.014142]
normal = [0.70711, 0.0, -0.70711]
offsets = [[0.0, 0.0, 0.0, 0.0], [1.0, 0.0002, 0.0, -0.0002]]
friction = 0.8

[frames]
times = [0.5, 1.0]

[output]
directory = "{out}"
pictures = false
"""


def test_a_ball_a_gripping_wall_rolls_on_a_frictionless_table(tmp_path) -> None:
    # the wall grips the ball (friction) and presses it down and sideways onto a table
    # that gives no friction: the ball turns, and every contact stays where it belongs
    from contact.run import GraspRun
    from contact.scene import load_scene

    path = tmp_path / "rolled.toml"
    path.write_text(ROLLED.format(out=(tmp_path / "out").as_posix()))
    run = GraspRun(load_scene(path))
    for t in (0.5, 1.0):
        res, _, _, bodies = run.frame(t)
        assert res.converged and res.held, res.stop_reason
        assert res.penetration_ratio <= 1e-3
        ball = bodies[0]
        f = res.contact_force["ball"] + ball.loads.reshape(-1, 3)
        assert np.abs(f.sum(axis=0)).max() <= 1e-9 * np.abs(res.contact_force["ball"]).sum()
