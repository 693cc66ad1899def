"""Coulomb friction against Cattaneo-Mindlin and Mindlin-Deresiewicz.

A hemisphere (R = 1 m, E = 1 Pa, nu = 0.45: Dundurs' beta = 0.09, the normal and
tangential problems nearly uncoupled), its equator face held, is squeezed on a rigid table
at mu = 0 (frame 1: Hertz, a of about 0.1 R), then sheared by moving the table along x with
mu = 0.5, carrying the anchors (frames 2, 3). The stick radius comes from the nodes'
stick/slip status, the residual shift after unloading from the table's shift where the
tangential load is back to 0 (see :mod:`contact.cases.cattaneo`).

The fast tests use 4 cells across a (a/R = 0.1); their tolerances are what that mesh
gives (the status edge is quantised by the node spacing h: within h/2; the residual shift
carries about +6 % of finite size, a/R = 0.1 against Mindlin's half-space). The slow ones
take 10 cells across a at a/R = 0.05 and hold the 5 % of the issue: 384k DOFs, about
13 GB and ten minutes on two cores. Measured figures: docs/algorithm.md, "Friction".
"""

import math

import numpy as np
import pytest

from contact.cases.cattaneo import (
    cattaneo_check,
    mindlin_deresiewicz_check,
    squeezed_hemisphere,
)
from contact.cases.mindlin_theory import dundurs_beta, mindlin_sphere_on_plane
from contact.errors import ContactError
from tests.helpers import roundoff, same_outcome

COARSE = 0.025  # a / h of about 4 at a / R = 0.1 (depth 0.01)
FINE, FINE_DEPTH = 0.005, 0.0025  # a / h of about 10 at a / R = 0.05


# --- analytic side ----------------------------------------------------------------------


def test_mindlin_formulas():
    th = mindlin_sphere_on_plane(2.0, 0.4, 0.5, 3.0, 0.3)
    a, mup = th.hertz.contact_radius, 0.4 * 2.0
    assert th.limit == pytest.approx(mup, rel=1e-14)
    assert th.stick_radius(0.0) == pytest.approx(a, rel=1e-14)
    assert th.stick_radius(0.5 * mup) == pytest.approx(a * 0.5 ** (1 / 3), rel=1e-14)
    # the traction carries Q, and its second moment is the one traction_radius states
    r = np.linspace(0.0, a, 200001)
    for load in (0.3 * mup, 0.6 * mup, mup):
        q = th.traction(r, load)
        total = np.trapezoid(2 * np.pi * r * q, r)
        assert total == pytest.approx(load, rel=1e-6)
        spread = math.sqrt(2.5 * np.trapezoid(2 * np.pi * r**3 * q, r) / total)
        assert spread == pytest.approx(th.traction_radius(load), rel=1e-6)
    # full slip: mu p; the stick compliance of a circular patch, (2 - nu) / (8 G a)
    assert np.allclose(th.traction(r, mup), 0.4 * th.hertz.pressure(r))
    g = 3.0 / 2.6
    eps = 1e-7 * mup
    assert th.shift(eps) / eps == pytest.approx((2 - 0.3) / (8 * g * a), rel=1e-6)
    assert th.shift(mup) == pytest.approx(th.compliance, rel=1e-14)
    # unloading starts at the peak; the residual for Q* = mu P is K (2^(1/3) - 1)
    assert th.unloading_shift(0.7 * mup, 0.7 * mup) == pytest.approx(th.shift(0.7 * mup))
    assert th.residual_shift(mup) == pytest.approx(th.compliance * (2 ** (1 / 3) - 1))
    assert th.unloading_stick_radius(0.0, 0.9 * mup) == pytest.approx(a * 0.55 ** (1 / 3))
    assert dundurs_beta(0.5) == 0.0 and dundurs_beta(0.45) == pytest.approx(0.1 / 1.1)
    with pytest.raises(ContactError, match="mu P"):
        th.stick_radius(1.1 * mup)
    with pytest.raises(ContactError, match="positive friction"):
        mindlin_sphere_on_plane(2.0, 0.0, 0.5, 3.0, 0.3)


# --- the hemisphere ---------------------------------------------------------------------


@pytest.fixture(scope="module")
def coarse():
    """About 52k DOFs, 4 cells across a; a few seconds."""
    return squeezed_hemisphere(fine_size=COARSE)


def _hold_cattaneo(model, ratio, tol):
    check = cattaneo_check(model, ratio)
    zone, th = check.zone, check.theory
    c = th.stick_radius(zone.load)
    assert zone.load == pytest.approx(ratio * th.limit, rel=1e-3)
    # the squeeze stays: the tangential load moves the normal force by Dundurs' coupling only
    assert zone.force == pytest.approx(model.theory.hertz.force, rel=1e-3)
    # the stick zone, from the status and from the stick nodes' area
    assert abs(zone.stick_radius - c) <= tol(c)
    assert abs(zone.stick_radius_area - c) <= tol(c)
    # the friction solve: converged to its tolerance, the cone held
    fr = check.result.friction
    assert fr.residual <= fr.tolerance and fr.max_cone_use <= 1 + 1e-9
    assert fr.stick == zone.stick and fr.slip == zone.slip
    return check


@pytest.mark.parametrize("ratio", [0.3, 0.6])
def test_cattaneo_stick_radius_within_half_a_cell(coarse, ratio):
    check = _hold_cattaneo(coarse, ratio, lambda c: 0.5 * COARSE)
    # the tangential traction spread as Mindlin's q(r), in the integral sense
    assert abs(check.traction_error) <= 0.03


def test_the_stick_zone_does_not_depend_on_round_off(coarse):
    ref = cattaneo_check(coarse, 0.6)
    for seed in range(3):
        with roundoff(seed):
            check = cattaneo_check(coarse, 0.6)
        assert (check.zone.stick, check.zone.slip) == (ref.zone.stick, ref.zone.slip)
        assert check.shift == pytest.approx(ref.shift, rel=1e-9)
        same_outcome(ref.result, check.result)


def test_mindlin_deresiewicz_residual_shift_coarse(coarse):
    md = mindlin_deresiewicz_check(coarse, 0.9)
    th = md.theory
    assert md.peak_zone.load == pytest.approx(0.9 * th.limit, rel=1e-3)
    assert abs(md.end_zone.load) <= 1e-4 * th.limit
    # the hemisphere's own shear is a good part of the shift at the peak, none of the residual
    assert md.peak_shift > 1.1 * th.shift(md.peak_zone.load)
    assert abs(md.residual_error) <= 0.08
    # what stuck since the peak: the unloading's stick radius
    c = md.end_stick_ratio_theory * th.hertz.contact_radius
    assert abs(md.end_zone.stick_radius - c) <= 0.5 * COARSE


# --- 10 cells across a: the 5 % ---------------------------------------------------


@pytest.fixture(scope="module")
def fine():
    """About 384k DOFs, 10 cells across a, a / R = 0.05; minutes and about 13 GB."""
    return squeezed_hemisphere(fine_size=FINE, depth=FINE_DEPTH)


@pytest.mark.slow
@pytest.mark.parametrize("ratio", [0.3, 0.6])
def test_cattaneo_stick_radius_within_5_percent(fine, ratio):
    check = _hold_cattaneo(fine, ratio, lambda c: 0.05 * c)
    assert abs(check.stick_error) <= 0.05
    assert abs(check.traction_error) <= 0.02


@pytest.mark.slow
def test_mindlin_deresiewicz_residual_shift_within_5_percent(fine):
    md = mindlin_deresiewicz_check(fine, 0.9)
    assert abs(md.residual_error) <= 0.05
    assert abs(md.end_stick_ratio / md.end_stick_ratio_theory - 1) <= 0.05
