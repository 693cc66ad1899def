"""A neo-Hookean ball pressed to d/R = 0.2 converges with refinement at its observed order.

A free ball (R 20 mm, E 1 MPa, nu 0.45, bricks) squeezed between two frictionless plates,
frames at d/R 0.05 to 0.2, on three nested cubed-sphere meshes, each twice as fine as the
last (:func:`benchmarks.finite.ball`). The plate force must grow monotonically towards its
limit at an observed order near one (a contact edge's pressure, not a smooth field, sets
it) and the finest mesh must lie within a few percent of the Richardson extrapolation.
"""

import pytest

import fem
from benchmarks.finite import ball, finite_presses, linear_presses, order

MAT = fem.LinearElastic(1.0e6, 0.45)


def test_order_of_a_monotone_sequence_and_its_extrapolation():
    p, limit = order([1.0, 1.5, 1.75])
    assert p == pytest.approx(1.0) and limit == pytest.approx(2.0)
    assert order([1.0, 1.5, 1.4]) is None  # not monotone
    assert order([1.0, 1.5, 2.1]) is None  # not converging
    assert order([1.0, 1.5]) is None


@pytest.mark.slow
def test_the_pressed_ball_converges_at_its_observed_order():
    meshes = [ball(n) for n in (4, 8, 16)]
    # each raises where a frame does not converge
    finite = [finite_presses(m, MAT)[1] for m in meshes]
    linear = [linear_presses(m, MAT) for m in meshes]
    for forces in (finite, linear):
        found = order(forces)
        assert found is not None, forces  # monotone and converging
        p, limit = found
        assert 0.8 < p < 2.0, (p, forces)
        assert abs(forces[-1] / limit - 1) < 0.1, (limit, forces)
    # both models press the same ball: their limits agree to within the strain's effect
    assert order(finite)[1] == pytest.approx(order(linear)[1], rel=0.05)
