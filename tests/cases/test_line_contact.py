"""A long cylinder between two rigid frictionless plates against the Hertz line contact.

Cylinder R = 1 m, E = 1 Pa, nu = 0.3, plane strain (a quarter slab, rollers on its end
faces, see :mod:`contact.cases.line_contact`). The plates approach by 0.02 R in total,
which gives b / R = 0.076 (small: the theory's regime). The proof: the force per length
at that approach within 3 % of
``delta = (2 P' / (pi E*)) (2 ln(4 R / b) - 1)`` on a resolved mesh (b / h about 8).
"""

import math

import numpy as np
import pytest
from scipy.integrate import quad

from contact.cases.line_contact import (
    cylinder_between_plates,
    line_contact_check,
    quarter_cylinder_mesh,
)
from contact.errors import ContactError

R, E, NU, DELTA = 1.0, 1.0, 0.3, 0.02


@pytest.fixture(scope="module")
def resolved():
    """About 1.4k nodes, b / h = 7.6; about a second."""
    return line_contact_check(R, E, NU, approach=DELTA, fine_size=0.01)


# --- analytic side ----------------------------------------------------------------------


def test_formulas_and_their_inverse():
    es = E / (1 - NU**2)
    s = cylinder_between_plates(R, E, NU, force=0.004)
    assert s.modulus == pytest.approx(es, rel=1e-14)
    assert s.half_width == pytest.approx(math.sqrt(4 * 0.004 * R / (math.pi * es)), rel=1e-14)
    assert s.peak_pressure == pytest.approx(2 * 0.004 / (math.pi * s.half_width), rel=1e-14)
    expected = 2 * 0.004 / (math.pi * es) * (2 * math.log(4 * R / s.half_width) - 1)
    assert s.approach == pytest.approx(expected, rel=1e-14)
    back = cylinder_between_plates(R, E, NU, approach=s.approach)
    assert back.force == pytest.approx(0.004, rel=1e-12)
    with pytest.raises(ContactError, match="exactly one of"):
        cylinder_between_plates(R, E, NU)
    with pytest.raises(ContactError, match="approach must give b < R"):
        cylinder_between_plates(R, E, NU, approach=1.0)


def test_approach_from_the_stress_on_the_loaded_diameter():
    """The closed form against the integral of the plane-strain strain along the diameter.

    Stress on the diameter: the Hertz half-plane fields of both contacts (McEwen 1949)
    and the disc's uniform tension P' / (pi R) (two Flamant forces on a disc); the
    integrals are done numerically here, the closed form drops terms of order (b/R)^2.
    """
    s = cylinder_between_plates(R, E, NU, force=1e-4)  # b / R = 0.011
    b, p0, force = s.half_width, s.peak_pressure, s.force

    def syy(d):
        return -p0 * b / math.hypot(b, d)

    def sxx(d):
        return -p0 / b * ((b * b + 2 * d * d) / math.hypot(b, d) - 2 * d)

    def eyy(y):  # plane strain; depths below the top and above the bottom contact
        tension = force / (math.pi * R)
        sy = syy(R - y) + syy(R + y) + tension
        sx = sxx(R - y) + sxx(R + y) + tension
        return ((1 - NU**2) * sy - NU * (1 + NU) * sx) / E

    shortening = -quad(eyy, -R, R, points=[-R + b, R - b], limit=200, epsabs=1e-14)[0]
    assert shortening == pytest.approx(s.approach, rel=1e-4)


# --- the FE model -----------------------------------------------------------------------


def test_quarter_cylinder_mesh():
    m = quarter_cylinder_mesh(R, 0.05, 0.2, layers=2)
    p = m.points
    assert p[:, 0].min() == pytest.approx(0.0, abs=1e-12)
    assert p[:, 1].min() == pytest.approx(0.0, abs=1e-12)
    assert np.linalg.norm(p[:, :2], axis=1).max() == pytest.approx(R, rel=1e-12)
    assert p[:, 2].max() == pytest.approx(0.1)
    assert m.volume == pytest.approx(0.25 * math.pi * R**2 * 0.1, rel=1e-2)  # chords of the arc
    # graded toward the contact line (0, R, z): the fine size there, coarse away
    near = np.linalg.norm(p[:, :2] - [0.0, R], axis=1)
    edges = np.sort(np.abs(np.diff(p[near < 0.1, 0])))
    assert edges[edges > 1e-9].min() == pytest.approx(0.05, rel=0.2)


def test_force_per_length_within_3_percent(resolved):
    c = resolved
    assert c.result.converged
    assert c.theory.half_width / R == pytest.approx(0.076, abs=1e-3)
    assert abs(c.error) <= 0.03  # the proof
    assert abs(c.error) <= 5e-3  # what the resolved mesh gives, with a margin
    assert abs(c.half_width_error) <= 0.01
    # the contact sits on the plate, pushes, and stays near the line (0, R)
    x = c.mesh.points[c.result.contact_nodes]
    assert x[:, 0].max() <= 1.5 * c.theory.half_width
    assert (c.result.contact_force[c.result.contact_nodes, 1] < 0).all()  # pushed down
    assert c.result.max_penetration <= 1e-3 * DELTA


def test_plane_strain_does_not_depend_on_the_slab(resolved):
    """Three layers with interior nodes free along z: the same force, no axial motion."""
    c = line_contact_check(R, E, NU, approach=DELTA, fine_size=0.01, layers=3)
    assert c.force == pytest.approx(resolved.force, rel=1e-3)
    assert np.abs(c.result.displacement[:, 2]).max() <= 1e-9 * DELTA


@pytest.mark.slow
@pytest.mark.parametrize("approach", [0.01, 0.02])
def test_mesh_convergence(approach):
    """Three resolutions: the coarsest has b / h of 2.5 to 4, the finest 10 to 15."""
    errors = [
        line_contact_check(R, E, NU, approach=approach, fine_size=h).error
        for h in (0.02, 0.01, 0.005)
    ]
    assert abs(errors[0]) <= 0.03
    assert max(abs(e) for e in errors[1:]) <= 2e-3
