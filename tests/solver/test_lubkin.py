"""Lubkin's twist: a free ball squeezed between two plates holds a moment about their axis
up to ``2 (3 pi / 16) mu P a`` (each Hertz contact's full slip), by node rows and by
weighted gaps alike. Slow: the patch (a = 5 mm) needs the 16-division ball (51k DOFs)."""

import numpy as np
import pytest

import fem
from contact.cases.hertz_theory import effective_modulus
from contact.geometry.plane import Plane
from contact.solver import solve_frame
from contact.solver.body import ElasticBody
from contact.solver.pairs import ContactPair

pytestmark = pytest.mark.slow

R, E, NU, MU, PRESS = 0.02, 1.0e5, 0.45, 0.1, 2.4e-3
MESH = fem.ball_mesh(R, divisions=16, layers=8)
MAT = fem.LinearElastic(E, NU, 1000.0)


def _twist(moment: float, weighted: bool):
    """The ball between a table and a plate pressed down ``PRESS``, twisted about z."""
    x = MESH.points
    t = np.cross([0.0, 0.0, 1.0], x - x.mean(axis=0))  # sum x cross f = moment about z
    ball = ElasticBody("ball", MESH, MAT, loads=(moment * t / (t**2).sum()).ravel())
    table = Plane((0, 0, -R), (0, 0, 1), name="table")
    plate = Plane((0, 0, R), (0, 0, -1), motion=(0, 0, -PRESS), name="plate")
    pairs = [ContactPair(ball, p, friction=MU, mortar=weighted) for p in (table, plate)]
    return solve_frame([ball], pairs, [table, plate])


@pytest.mark.parametrize("weighted", [False, True])
def test_a_squeezed_ball_holds_a_twist_up_to_lubkins_moment(weighted):
    squeezed = _twist(0.0, weighted)
    assert squeezed.converged, squeezed.stop_reason
    p = abs(squeezed.obstacle_forces["plate"][2])
    a = (3 * p * R / (4 * effective_modulus(E, NU))) ** (1 / 3)  # Hertz's radius at P
    lubkin = 2 * (3 * np.pi / 16) * MU * p * a
    held = _twist(0.9 * lubkin, weighted)
    assert held.converged and held.held, held.stop_reason
    # the friction carries the moment: the plates' tangential forces turn it back
    assert held.friction.slip > 0  # Lubkin's annulus slips, the core sticks
    turned = _twist(1.1 * lubkin, weighted)
    assert not turned.converged and turned.held is False
    assert turned.stop_reason.startswith("not held: ball turns about (0.000, 0.000, 1.000)")
