"""A free ball squeezed between a fixed table and a force-driven plate, twisted about their
axis (Lubkin's problem): held below the moment its cones can carry, reported as a turn
with the moment it leaves past it."""

import numpy as np
import pytest

import fem
from contact.geometry.plane import Plane
from contact.solver import ContactSettings, solve_frame
from contact.solver.body import ElasticBody
from contact.solver.pairs import ContactPair

R, E, NU, MU, P = 0.02, 1.0e5, 0.45, 0.5, 1.0
MESH = fem.ball_mesh(R, R / 8)
MAT = fem.LinearElastic(E, NU, 1000.0)


def _twist(moment):
    x = MESH.points
    t = np.cross([0.0, 0.0, 1.0], x - x.mean(axis=0))  # about z: sum x cross f = moment
    loads = (moment * t / (t**2).sum()).ravel() + fem.gravity_load(MESH, MAT, (0, 0, -9.81))
    ball = ElasticBody("ball", MESH, MAT, loads=loads)
    table = Plane((0, 0, -R), (0, 0, 1), name="table")
    plate = Plane((0, 0, R), (0, 0, -1), force=P, name="plate")
    pairs = [ContactPair(ball, table, friction=MU), ContactPair(ball, plate, friction=MU)]
    return solve_frame([ball], pairs, [table, plate], ContactSettings())


def _cones(res):
    """``sum mu N r`` of the frame's contacts (N m), about the ball's axis."""
    c = res.contacts
    x = MESH.points - MESH.points.mean(axis=0)
    return MU * float((c["force"] * np.linalg.norm(x[c["node"], :2], axis=1)).sum())


@pytest.fixture(scope="module")
def limit():
    return _cones(_twist(1e-9))


def test_a_twist_below_the_cones_is_held(limit):
    res = _twist(0.5 * limit)
    assert res.converged and res.held, res.stop_reason


@pytest.mark.parametrize("factor", [1.05, 1.2])
def test_a_twist_past_the_cones_turns_the_ball_by_what_they_leave(limit, factor):
    moment = factor * limit
    res = _twist(moment)
    assert not res.converged and res.held is False
    assert res.stop_reason.startswith("not held: ball turns about (0.000, 0.000, 1.000)")
    assert res.slip["turns"] and res.slip["direction"] == pytest.approx([0, 0, 1], abs=1e-9)
    # what the cones carry at the end against the turn (the report's from the softest
    # spring's solve, these from the last), and what is left of the moment
    available = _cones(res)
    assert res.slip["available"] == pytest.approx(available, rel=1e-2)
    assert res.slip["not_carried"] == pytest.approx(moment - available, rel=0.05)
