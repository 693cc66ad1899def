"""The error a Newton step leaves, from its rate (contact.solver.newtonrate.StepErrors).

A finite frame stops where the error its last step leaves is round-off of the body's
size: the step itself, or less where two consecutive plain steps contract (a geometric
series). The promise is checked against the same frame taken to round-off.
"""

import numpy as np
import pytest

import fem
from contact.geometry.plane import Plane
from contact.solver import finite
from contact.solver.finite import FiniteBody, solve_finite_frame
from contact.solver.newtonrate import CONTRACTS, Flips, StepErrors
from contact.solver.pairs import ContactPair


def test_a_contracting_pair_of_steps_leaves_the_rest_of_its_series():
    errors = StepErrors()
    assert errors.left("b", 1, 1e-3, plain=True) == 1e-3  # no rate yet
    assert errors.left("b", 2, 2e-4, plain=True) == pytest.approx(2e-4 * 0.2 / 0.8)
    # quadratic: far less than the step
    assert errors.left("b", 3, 4e-8, plain=True) == pytest.approx(4e-8 * 2e-4 / (1 - 2e-4))


@pytest.mark.parametrize(
    ("steps", "why"),
    [
        ([(1, 1e-3, True), (2, (CONTRACTS + 0.1) * 1e-3, True)], "slower than CONTRACTS"),
        ([(1, 1e-3, True), (3, 1e-5, True)], "not consecutive"),
        ([(1, 1e-3, False), (2, 1e-5, True)], "after a damped step"),
        ([(1, 1e-3, True), (2, 1e-5, False)], "a damped step"),
        ([(1, 0.0, True), (2, 1e-5, True)], "after no step"),
    ],
)
def test_otherwise_the_step_itself_is_the_error(steps, why):
    errors = StepErrors()
    for step, move, plain in steps:
        last = errors.left("b", step, move, plain)
    assert last == steps[-1][1], why


def test_steps_that_close_other_contacts_are_not_plain():
    flips = Flips()
    flips.add({"pair": ["ball/plate"], "node": [3]})
    assert not flips.steady
    flips.add({"pair": ["ball/plate"], "node": [3]})
    assert flips.steady
    flips.add({"pair": ["ball/plate", "ball/plate"], "node": [3, 4]})
    assert not flips.steady


def test_the_frame_it_stops_is_within_its_tolerance_of_the_converged_one(monkeypatch):
    # weighted rows on a curved body converge at a linear rate in a finite frame (their
    # smoothed bulge is measured anew at each placement): a ball squeezed between plates
    r = 0.02
    body = FiniteBody("ball", fem.ball_mesh(r, r / 4), fem.LinearElastic(1e6, 0.45))
    planes = [
        Plane((0, 0, -r), (0, 0, 1), motion=(0, 0, 0.05 * r), name="table"),
        Plane((0, 0, r), (0, 0, -1), motion=(0, 0, -0.05 * r), name="plate"),
    ]
    pairs = [ContactPair(body, p, mortar=True) for p in planes]
    out = solve_finite_frame([body], pairs, planes)
    assert out.converged and out.steps >= 4  # a linear rate
    tol = finite.STEP_TOL
    with monkeypatch.context() as m:
        m.setattr(finite, "STEP_TOL", 1e-14)
        ref = solve_finite_frame([body], pairs, planes)
    assert ref.converged and ref.steps > out.steps
    size = float(np.ptp(body.mesh.points, axis=0).max())
    err = np.abs(out.displacement["ball"] - ref.displacement["ball"]).max() / size
    assert err <= tol
    # the last step alone would have asked for one more to show it small
    monkeypatch.setattr(StepErrors, "left", lambda self, name, step, move, plain: move)
    assert solve_finite_frame([body], pairs, planes).steps == out.steps + 1
