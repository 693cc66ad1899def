"""A block between two rigid frictionless plates against uniaxial compression, F = E A d / H.

Linear elements reproduce the uniform strain exactly, so every conforming mesh with flat
plate faces gives the force to round-off: the 1 % of the proof is met by ten orders of
magnitude, and the tolerance here is 1e-9 (see :mod:`contact.cases.block`).
"""

import numpy as np
import pytest

from contact.cases.block import block_check, block_mesh
from contact.errors import ContactError

EXACT = 1e-9  # round-off of a few hundred nodes' solve


@pytest.fixture(scope="module")
def tetwild_mesh():
    """One unstructured mesh of the unit cube (pytetwild: not deterministic)."""
    return block_mesh(kind="tetwild", size=0.25)


def _exact(check, tol=EXACT):
    assert check.result.converged
    assert abs(check.error) <= tol
    # the base carries the same force, nothing else holds the block
    assert check.base_force == pytest.approx(check.force, rel=tol)
    assert check.support_force <= tol * check.force
    # lateral faces are free: no force across the plates' planes
    for f in check.result.obstacle_forces.values():
        assert np.abs(f[:2]).max() <= tol * check.force


@pytest.mark.parametrize("kind", ["hex", "tet"])
@pytest.mark.parametrize("hold", ["free", "rollers"])
def test_structured_cube_is_exact(kind, hold):
    check = block_check(kind=kind, hold=hold, size=0.2, strain=0.01)
    _exact(check)
    assert check.exact == pytest.approx(0.01)  # E A d / H, unit cube and modulus


def test_a_box_of_another_shape_and_nearly_incompressible():
    """F does not depend on nu: frictionless plates leave the lateral expansion free."""
    check = block_check((1.0, 2.0, 0.5), E=3.0, nu=0.45, kind="hex", size=0.25, strain=0.02)
    _exact(check)
    assert check.exact == pytest.approx(3.0 * 2.0 * 0.01 / 0.5)
    u = check.result.displacement
    lateral = u[:, 0].max() - u[:, 0].min()  # Poisson expansion of the 1 m side
    assert lateral == pytest.approx(0.45 * 0.02 * 1.0, rel=1e-9)


@pytest.mark.parametrize("hold", ["free", "rollers"])
def test_unstructured_tetrahedra(tetwild_mesh, hold):
    """Plate faces triangulated by pytetwild, with no grid: still exact."""
    _exact(block_check(hold=hold, mesh=tetwild_mesh))


def test_held_rotation_of_a_free_body_on_an_irregular_mesh(tetwild_mesh):
    """The library's default for a free ball holds the node-weighted rotation at zero.

    A uniform strain about the block's centre has such a part on an irregular mesh, so a
    small moment holds it: not exact, but within the proof's 1 %.
    """
    check = block_check(mesh=tetwild_mesh, hold_rotation=True)
    assert check.result.converged
    assert abs(check.error) <= 1e-2
    assert check.base_force == pytest.approx(check.force, rel=EXACT)


def test_bad_arguments():
    with pytest.raises(ContactError, match="hold must be one of"):
        block_check(hold="glued")
    with pytest.raises(ContactError, match="strain must lie"):
        block_check(strain=0.5)
    with pytest.raises(ContactError, match="mesh kind must be one of"):
        block_mesh(kind="wedge", size=0.5)
