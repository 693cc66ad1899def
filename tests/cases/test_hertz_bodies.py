"""Hertz verification of the contact iteration between two deformable bodies.

Two quarter-model scenes (see :mod:`contact.cases.hertz_bodies`): a sphere (R1 = 1 m) pressed
onto an elastic block (20 contact radii wide and deep), and two spheres (R1 = 1 m on
R2 = 2 m, effective radius 1/R = 1/R1 + 1/R2 = 2/3 m), each a graded quarter hemisphere
held in z on its flat equator face, the block on its base. The interference is 0.01 R
(a/R about 0.1). Materials are compressible (nu = 0.3: HEX8 locks near 0.5); the top
sphere has E1 = ratio * E2. Hertz with 1/E* = (1-nu^2)/E1 + (1-nu^2)/E2 and the solver's
own total force F; radius and peak pressure measured from the top sphere's nodal contact
forces (and, as a second measure, the other body's), as in :mod:`contact.cases.hertz`.

Both algorithms: contact space (the default) and the seed's Dirichlet-Neumann loop with
the top sphere as the Dirichlet body. The seed loop is not expected to converge
everywhere: what is asserted is that it says so (``converged`` False with a stop reason)
and that where it does converge it agrees with contact space.
"""

import functools
import math

import numpy as np
import pytest

import fem
from contact.cases.hertz import effective_modulus, hertz_sphere_on_plane
from contact.cases.hertz_bodies import (
    graded_box_mesh,
    hemisphere_mesh,
    hertz_bodies_check,
    hertz_scene,
    hertz_two_bodies,
)
from contact.errors import ContactError
from contact.solver import ContactSettings, solve_frame

RADII = (1.0, 2.0)
#: Test-sized meshes: cell size at the contact (about 3.4 and 2.7 cells across a).
H_TEST = 0.03
#: Three refinements (slow): about 2x the DOFs per step.
H_REFINED = (0.03, 0.02, 0.015)
SCENES = ("sphere-block", "two-spheres")


@functools.cache
def scene(name, ratio, h=H_TEST, both=True, radii=RADII):
    return hertz_scene(name, ratio, fine_size=h, radii=radii, both_directions=both)


@functools.cache
def check(name, ratio, h=H_TEST, both=True, radii=RADII):
    return hertz_bodies_check(scene(name, ratio, h, both, radii))


def within_30_percent(counts):
    """The counts fit in a band of +-30 % about a central value (their mid-range)."""
    mid = 0.5 * (max(counts) + min(counts))
    return all(abs(n - mid) <= 0.3 * mid for n in counts)


def check_balance(chk, rtol=1e-10):
    """Every body in equilibrium at its free DOFs; action equals reaction."""
    res = chk.result
    scale = max(np.abs(res.contact_force[b.name]).max() for b in chk.scene.bodies)
    for b in chk.scene.bodies:
        r = b.stiffness @ res.displacement[b.name].ravel() - res.contact_force[b.name].ravel()
        assert np.abs(r[~b.fixed_dofs]).max() <= rtol * scale, b.name
        # the supports carry the contact force: the held z DOFs react to all of it
        fz = res.total_contact_force(b.name)[2]
        assert r[2::3][b.fixed_dofs[2::3]].sum() == pytest.approx(-fz, rel=1e-9)
    assert chk.action_reaction <= rtol
    top, other = (res.total_contact_force(b.name) for b in chk.scene.bodies)
    assert np.abs(top + other).max() <= rtol * np.abs(top).max()
    assert top[2] > 0 > other[2]
    # the two bodies' patches carry the same force
    assert chk.patch_other.force == pytest.approx(chk.patch.force, rel=1e-10)


# --- analytic side and meshes ------------------------------------------------------------


def test_hertz_two_bodies_formulas():
    # a rigid flat: the sphere-on-plane solution
    one = hertz_two_bodies(2.0, 0.5, math.inf, 3.0, 0.25, math.inf, 0.0)
    ref = hertz_sphere_on_plane(2.0, 0.5, 3.0, 0.25)
    for key in ("radius", "modulus", "contact_radius", "peak_pressure", "approach"):
        assert getattr(one, key) == pytest.approx(getattr(ref, key), rel=1e-14)
    # two spheres: 1/R = 1/R1 + 1/R2, 1/E* = sum (1 - nu^2)/E, symmetric in the bodies
    two = hertz_two_bodies(2.0, 1.0, 2.0, 1.0, 0.3, 100.0, 0.2)
    assert two.radius == pytest.approx(2.0 / 3.0, rel=1e-14)
    assert 1 / two.modulus == pytest.approx((1 - 0.09) / 1.0 + (1 - 0.04) / 100.0, rel=1e-14)
    assert two.modulus == pytest.approx(effective_modulus(1.0, 0.3, 100.0, 0.2), rel=1e-14)
    swap = hertz_two_bodies(2.0, 2.0, 1.0, 100.0, 0.2, 1.0, 0.3)
    assert swap.contact_radius == pytest.approx(two.contact_radius, rel=1e-14)
    a = (3 * 2.0 * two.radius / (4 * two.modulus)) ** (1 / 3)
    assert two.contact_radius == pytest.approx(a, rel=1e-14)
    assert two.peak_pressure == pytest.approx(3 * 2.0 / (2 * math.pi * a**2), rel=1e-14)
    with pytest.raises(ContactError, match="one finite"):
        hertz_two_bodies(1.0, math.inf, math.inf, 1.0, 0.3, 1.0, 0.3)
    with pytest.raises(ContactError, match="positive force"):
        hertz_two_bodies(-1.0, 1.0, 1.0, 1.0, 0.3, 1.0, 0.3)


def test_graded_box_mesh():
    m = graded_box_mesh((2.0, 1.5, 1.0), 0.05, 0.2, coarse_size=0.3)
    lo, hi = m.points.min(axis=0), m.points.max(axis=0)
    assert np.allclose(lo, [0, 0, -1.0]) and np.allclose(hi, [2.0, 1.5, 0.0])
    assert m.volume == pytest.approx(3.0, rel=1e-12)
    xs = np.unique(m.points[:, 0])
    dx = np.diff(xs)
    assert np.allclose(dx[:4], 0.05)  # fine at the contact point
    assert dx.max() <= 0.3 + 1e-12 and np.all(np.diff(dx) >= -1e-12)  # growing outward
    zs = np.unique(m.points[:, 2])
    assert np.allclose(np.diff(zs)[-4:], 0.05)  # fine under the top face


@pytest.mark.parametrize("pole", ["down", "up"])
def test_hemisphere_mesh(pole):
    m = hemisphere_mesh(2.0, 0.05, 0.2, pole=pole, tip=(0.0, 0.0, -0.1))
    s = 1.0 if pole == "down" else -1.0
    center = np.array([0.0, 0.0, -0.1 + s * 2.0])
    assert (m.points[:, :2] >= -1e-12).all()
    assert (s * (m.points[:, 2] - center[2]) <= 1e-12).all()  # the pole's side of the equator
    r = np.linalg.norm(m.points - center, axis=1)
    assert r.max() == pytest.approx(2.0, rel=1e-12)
    tip = np.argmin(s * m.points[:, 2])
    assert np.allclose(m.points[tip], [0.0, 0.0, -0.1])
    # a quarter of a hemisphere, faceted: pi R^3 / 6 less a little
    assert m.volume == pytest.approx(math.pi * 8 / 6, rel=0.02)
    with pytest.raises(ContactError, match="pole"):
        hemisphere_mesh(1.0, 0.05, 0.2, pole="side")


def test_scene_models():
    sc = scene("sphere-block", 1.0)
    top, block = sc.bodies
    assert sc.depth == pytest.approx(0.01)
    assert [p.name for p in sc.pairs] == ["top/block", "block/top"]
    # the block is 20 contact radii (0.1) wide and deep, graded towards the origin
    assert np.allclose(np.ptp(block.mesh.points, axis=0), [2.0, 2.0, 2.0])
    # contact faces: the sphere's curved faces only, the block's top only
    c = np.array([0.0, 0.0, 1.0 - sc.depth])
    on = top.contact_nodes
    assert np.allclose(np.linalg.norm(top.mesh.points[on] - c, axis=1), 1.0)
    assert np.allclose(block.mesh.points[block.contact_nodes, 2], 0.0)
    # held: normal DOFs on x = 0, y = 0, z on the equator face / the base
    for b, zp in ((top, 1.0 - sc.depth), (block, -2.0)):
        p = b.mesh.points
        fixed = b.fixed_dofs.reshape(-1, 3)
        assert np.array_equal(fixed[:, 0], np.isclose(p[:, 0], 0.0))
        assert np.array_equal(fixed[:, 1], np.isclose(p[:, 1], 0.0))
        assert np.array_equal(fixed[:, 2], np.isclose(p[:, 2], zp))
    two = scene("two-spheres", 1.0)
    assert two.depth == pytest.approx(0.01 * 2 / 3)
    assert [b.name for b in two.bodies] == ["top", "bottom"]
    with pytest.raises(ContactError, match="scene must be one of"):
        hertz_scene("cube", 1.0, fine_size=0.03)


# --- against Hertz -------------------------------------------------------------------------


@pytest.mark.parametrize("name", SCENES)
@pytest.mark.parametrize("ratio", [0.01, 1.0, 100.0])
def test_against_hertz(name, ratio):
    """Radius within 3 %, peak pressure within 5 % on test meshes, at E1/E2 = 0.01..100."""
    chk = check(name, ratio)
    res = chk.result
    assert res.converged and res.stop_reason == "converged"
    assert res.iterations <= 10
    assert res.penetration_ratio <= 1e-3
    assert (res.contacts["force"] >= 0).all()
    check_balance(chk)
    assert 0.09 < chk.hertz.contact_radius / chk.hertz.radius < 0.11
    # measured (h = 0.03, top / other body): radius -1.0..-2.6 %, peak pressure -0.2..+3.1 %
    for a_err, p_err in (
        (chk.radius_error, chk.pressure_error),
        (chk.radius_error_other, chk.pressure_error_other),
    ):
        assert abs(a_err) < 0.03
        assert abs(p_err) < 0.05


def test_equal_spheres_mirror():
    """Equal radii: E1/E2 = 100 is E1/E2 = 0.01 upside down (force scaled by 100)."""
    soft, stiff = (check("two-spheres", r, radii=(1.0, 1.0)) for r in (0.01, 100.0))
    assert stiff.patch.force == pytest.approx(100 * soft.patch.force, rel=1e-6)
    assert stiff.patch.contact_radius == pytest.approx(soft.patch_other.contact_radius, rel=1e-6)
    p_soft = soft.patch_other.peak_pressure
    assert stiff.patch.peak_pressure == pytest.approx(100 * p_soft, rel=1e-6)
    assert stiff.result.iterations == soft.result.iterations


def test_one_way_pairs_agree():
    """Only the top sphere's nodes as slaves: the same Hertz answer within the mesh error."""
    for name in SCENES:
        one, two = check(name, 1.0, both=False), check(name, 1.0)
        assert one.result.converged and one.result.iterations <= 10
        check_balance(one)
        assert one.patch.force == pytest.approx(two.patch.force, rel=0.01)
        assert abs(one.radius_error) < 0.03 and abs(one.pressure_error) < 0.05


# --- the seed loop -------------------------------------------------------------------------


def test_seed_loop_converges_with_a_soft_dirichlet_sphere(monkeypatch):
    """One-way pairs, the Dirichlet (top) sphere 100x softer: contact space's answer."""
    import contact.solver.contactset as contactset

    near = check("sphere-block", 0.01, both=False)
    # with the rows taken where the nodes are first found inside, as the seed loop takes
    # them (contact space's first set also holds the nodes near contact, linearised at
    # rest: 4e-5 apart)
    monkeypatch.setattr(contactset, "NEAR", 0.0)
    ref = hertz_bodies_check(scene("sphere-block", 0.01, both=False))
    sc = scene("sphere-block", 0.01, both=False)
    chk = hertz_bodies_check(sc, ContactSettings(algorithm="seed", tolerance=1e-9))
    assert chk.result.converged and chk.result.iterations <= 10
    assert chk.patch.force == pytest.approx(ref.patch.force, rel=1e-6)
    assert chk.patch.contact_radius == pytest.approx(ref.patch.contact_radius, rel=1e-6)
    assert chk.patch.force == pytest.approx(near.patch.force, rel=1e-3)


@pytest.mark.parametrize("both", [False, True])
def test_seed_loop_reports_failure(both):
    """A stiff Dirichlet sphere (one-way pairs), or pairs both ways (any ratio): not converged.

    Pairs in both directions prescribe, in the seed's step 3, more rows on the Dirichlet
    body than it has contact DOFs (its compliance on the rows is singular): the first
    iterate is far off and the loop stops as diverged.
    """
    ratio = 100.0 if not both else 1.0
    sc = scene("sphere-block", ratio, both=both)
    for relaxation in ("none", "aitken"):
        res = solve_frame(
            list(sc.bodies),
            list(sc.pairs),
            (),
            ContactSettings(algorithm="seed", relaxation=relaxation, max_iterations=20),
        )
        assert not res.converged
        reasons = ("diverged", "iteration limit", "cycling", "singular contact rows")
        assert res.stop_reason.startswith(reasons), res.stop_reason
        assert len(res.history) == res.iterations >= 1
        if both:  # measured: diverged at the first iteration, whatever the relaxation
            assert res.stop_reason.startswith("diverged: ")


# --- slow: the full sweep ------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("name", SCENES)
def test_ratio_sweep_and_refinements(name):
    """E1/E2 = 0.01..100 on three meshes: Hertz everywhere, contact-space counts <= 10 and
    within +-30 % over the refinements; the seed loop's counts and stop reasons recorded."""
    record = {}
    for ratio in (0.01, 0.1, 1.0, 10.0, 100.0):
        its = []
        for h in H_REFINED:
            chk = hertz_bodies_check(scene.__wrapped__(name, ratio, h))
            res = chk.result
            assert res.converged and res.iterations <= 10
            assert res.penetration_ratio <= 1e-3
            check_balance(chk)
            assert abs(chk.radius_error) < 0.03 and abs(chk.pressure_error) < 0.05
            its.append(res.iterations)
        assert within_30_percent(its), (ratio, its)
        record[ratio] = its
        # the seed loop, one-way and both ways, on the test-sized mesh
        for both in (False, True):
            sc = scene.__wrapped__(name, ratio, H_TEST, both)
            ref = hertz_bodies_check(sc)
            for relaxation in ("none", "aitken"):
                settings = ContactSettings(algorithm="seed", relaxation=relaxation, tolerance=1e-9)
                try:
                    res = solve_frame(list(sc.bodies), list(sc.pairs), (), settings)
                except fem.SolverError as exc:
                    # known limitation (pairs both ways): the Dirichlet body's rows are
                    # dependent and its constrained solve raises instead of reporting
                    assert both and "dependent" in str(exc)
                    record[(ratio, both, relaxation)] = (None, "raised SolverError")
                    continue
                record[(ratio, both, relaxation)] = (res.iterations, res.stop_reason)
                if res.converged:
                    # rows are taken where a node is first found inside, at different
                    # iterates in the two algorithms: measured within 0.2 %
                    f = res.total_contact_force("top")[2]
                    assert f == pytest.approx(ref.result.total_contact_force("top")[2], rel=1e-2)
                else:
                    # the same limitation, reported as a stop reason when the seed's step
                    # 3 meets dependent rows after its first iteration (two spheres meshed
                    # alike touch node to node at their poles, one-way pairs too)
                    heads = ("diverged: ", "iteration limit", "cycling")
                    heads += ("singular contact rows on top",)
                    assert res.stop_reason.startswith(heads), res.stop_reason
    print(name, record)
