"""A neo-Hookean ball pressed to d/R = 0.2 converges with refinement at its observed order.

A free ball (R 20 mm, E 1 MPa, nu 0.45, bricks) squeezed between two frictionless plates,
frames at d/R 0.05 to 0.2, on three nested cubed-sphere meshes, each twice as fine as the
last (:func:`benchmarks.finite.ball`). The plate force must grow monotonically towards its
limit at an observed order near one (a contact edge's pressure, not a smooth field, sets
it) and the finest mesh must lie within a few percent of the Richardson extrapolation.
"""

import numpy as np
import pytest

import fem
from benchmarks.finite import PRESSES, R, ball, order
from contact.geometry.plane import Plane
from contact.solver import solve_frame
from contact.solver.body import ElasticBody
from contact.solver.finite import FiniteBody, solve_finite_frame
from contact.solver.pairs import ContactPair

MAT = fem.LinearElastic(1.0e6, 0.45)


def _planes(d: float) -> list[Plane]:
    return [
        Plane((0, 0, -R), (0, 0, 1), motion=(0, 0, d * R / 2), name="table"),
        Plane((0, 0, R), (0, 0, -1), motion=(0, 0, -d * R / 2), name="plate"),
    ]


def _finite_force(mesh: fem.Mesh) -> float:
    body = FiniteBody("ball", mesh, MAT)
    start, force = None, np.nan
    for d in PRESSES:
        planes = _planes(d)
        out = solve_finite_frame([body], [ContactPair(body, p) for p in planes], planes,
                                 start=start)  # fmt: skip
        assert out.converged, out.stop_reason
        start = {"ball": out.displacement["ball"]}
        force = float(out.result.obstacle_forces["plate"][2])
    return force


def _linear_force(mesh: fem.Mesh) -> float:
    planes = _planes(PRESSES[-1])
    body = ElasticBody("ball", mesh, MAT)
    res = solve_frame([body], [ContactPair(body, p) for p in planes], planes)
    assert res.converged
    return float(res.obstacle_forces["plate"][2])


def test_order_of_a_monotone_sequence_and_its_extrapolation():
    p, limit = order([1.0, 1.5, 1.75])
    assert p == pytest.approx(1.0) and limit == pytest.approx(2.0)
    assert order([1.0, 1.5, 1.4]) is None  # not monotone
    assert order([1.0, 1.5, 2.1]) is None  # not converging
    assert order([1.0, 1.5]) is None


@pytest.mark.slow
def test_the_pressed_ball_converges_at_its_observed_order():
    meshes = [ball(n) for n in (4, 8, 16)]
    finite = [_finite_force(m) for m in meshes]
    linear = [_linear_force(m) for m in meshes]
    for forces in (finite, linear):
        found = order(forces)
        assert found is not None, forces  # monotone and converging
        p, limit = found
        assert 0.8 < p < 2.0, (p, forces)
        assert abs(forces[-1] / limit - 1) < 0.1, (limit, forces)
    # both models press the same ball: their limits agree to within the strain's effect
    assert order(finite)[1] == pytest.approx(order(linear)[1], rel=0.05)
