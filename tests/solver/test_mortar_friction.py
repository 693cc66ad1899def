"""Coulomb friction on weighted (mortar) rows between bodies: the frictional patch test of
two blocks with non-matching meshes, the incline and the pads (contact.solver.tangential)."""

import numpy as np
import pytest

import fem
from contact.solver import solve_frame
from contact.solver.body import ElasticBody
from contact.solver.pairs import ContactPair
from tests.helpers import roundoff, same_outcome

E, NU, P, MU = 1.0e5, 0.3, 1.0e3, 0.4
G, LAME = E / (2 * (1 + NU)), E * NU / ((1 + NU) * (1 - 2 * NU))
SIDE, H = 0.02, 0.01


def _face_areas(mesh: fem.Mesh, z: float) -> np.ndarray:
    """Each node's share of the boundary faces at height ``z`` (a uniform traction's)."""
    out = np.zeros(mesh.n_points)
    for kind, faces in mesh.boundary.faces.items():
        on = faces[np.isclose(mesh.points[faces, 2], z).all(axis=1)]
        x = mesh.points[on]
        if kind == "quad":
            area = np.linalg.norm(np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 1]), axis=1) / 2
        else:
            area = np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), axis=1) / 2
        k = on.shape[1]
        out += np.bincount(on.ravel(), np.repeat(area / k, k), minlength=mesh.n_points)
    return out


def _blocks(tau, mu, anchors=None, upper_slave=True, upper="hexahedron"):
    """An upper block pressed (P) and sheared (tau) on a lower one whose bottom is fixed.

    The upper is free, in uniaxial stress; the lower is confined laterally. Both carry
    sigma_zz = -P and sigma_xz = tau exactly where the contact does.
    """
    mat = fem.LinearElastic(E, NU)
    up = fem.box_mesh((SIDE, SIDE, H), (4, 4, 2), origin=(0, 0, H), element=upper)
    lo = fem.box_mesh((SIDE, SIDE, H), (3, 5, 2))
    eps = np.diag([NU * P / E, NU * P / E, -P / E])
    eps[0, 2] = tau / G
    f_up = ElasticBody("upper", up, mat).stiffness @ (up.points @ eps.T).ravel()
    f_up.reshape(-1, 3)[:] -= _face_areas(up, H)[:, None] * [-tau, 0.0, P]
    u_lo = np.zeros_like(lo.points)
    u_lo[:, 0], u_lo[:, 2] = tau / G * lo.points[:, 2], -P / (LAME + 2 * G) * lo.points[:, 2]
    f_lo = ElasticBody("lower", lo, mat).stiffness @ u_lo.ravel()
    f_lo.reshape(-1, 3)[:] -= _face_areas(lo, H)[:, None] * [tau, 0.0, -P]
    fixed = fem.node_dofs(np.flatnonzero(np.isclose(lo.points[:, 2], 0.0)), [0, 1, 2])
    a = ElasticBody("upper", up, mat, loads=f_up)
    b = ElasticBody("lower", lo, mat, loads=f_lo, prescribed=fixed)
    pair = ContactPair(a, b, mortar=True, friction=mu)
    if not upper_slave:
        pair = ContactPair(b, a, mortar=True, friction=mu)
    return solve_frame([a, b], [pair], [], anchors=anchors), (a, b)


def _stress_error(res, bodies, tau):
    err = 0.0
    for body in bodies:
        u = res.displacement[body.name].ravel()
        for s in fem.cell_stress(body.mesh, body.materials, u, at="gauss").values():
            carried = s[..., [2, 0, 1], [2, 2, 2]]  # sigma_zz, sigma_xz, sigma_yz
            err = max(err, float(np.abs(carried - [-P, tau, 0.0]).max()) / P)
    return err


@pytest.mark.parametrize(
    ("upper_slave", "upper"),
    [(True, "hexahedron"), (False, "hexahedron"), (True, "tetra"), (False, "tetra")],
)
def test_the_frictional_patch_between_blocks_sticks_uniformly_below_mu_p(upper_slave, upper):
    first, bodies = _blocks(0.0, 0.0, upper_slave=upper_slave, upper=upper)
    assert first.converged, first.stop_reason
    assert _stress_error(first, bodies, 0.0) < 1e-10
    for ratio in (0.5, 0.9, 1.02):
        tau = ratio * MU * P
        res, bodies = _blocks(tau, MU, first.anchors, upper_slave, upper)
        if ratio > 1:
            assert not res.converged and res.held is False
            assert res.stop_reason.startswith("not held: upper slips along (1.000, 0.000, ")
            continue
        assert res.converged and res.held, res.stop_reason
        assert _stress_error(res, bodies, tau) < 1e-10  # measured 5e-14 .. 2e-13
        assert res.friction.slip == 0
        assert res.friction.max_cone_use == pytest.approx(ratio, rel=1e-8)
        f = res.contact_force["upper"]
        assert f.sum(axis=0) == pytest.approx([-tau * SIDE**2, 0.0, P * SIDE**2], abs=1e-12)
        assert np.abs(f.sum(axis=0) + res.contact_force["lower"].sum(axis=0)).max() < 1e-14


def _incline(theta_deg, mu):
    """A free block on a fixed one (non-matching meshes), gravity tilted by ``theta``."""
    theta = np.radians(theta_deg)
    mat = fem.LinearElastic(E, NU, 1000.0)
    up = fem.box_mesh((SIDE, SIDE, H), (4, 4, 2), origin=(0, 0, H))
    lo = fem.box_mesh((1.5 * SIDE, 1.5 * SIDE, H), (5, 3, 2), origin=(-SIDE / 4, -SIDE / 4, 0))
    g = 9.81 * np.array([np.sin(theta), 0.0, -np.cos(theta)])
    block = ElasticBody("block", up, mat, loads=fem.gravity_load(up, mat, g))
    fixed = fem.node_dofs(np.flatnonzero(np.isclose(lo.points[:, 2], 0.0)), [0, 1, 2])
    base = ElasticBody("base", lo, mat, prescribed=fixed)
    pair = ContactPair(block, base, mortar=True, friction=mu)
    return solve_frame([block, base], [pair], [])


def test_a_block_on_a_block_sticks_iff_tan_theta_is_at_most_mu():
    limit = np.degrees(np.arctan(MU))
    held = _incline(0.97 * limit, MU)
    assert held.converged and held.held, held.stop_reason
    weight = 1000.0 * SIDE**2 * H * 9.81
    f = held.contact_force["block"].sum(axis=0)
    theta = np.radians(0.97 * limit)
    assert f == pytest.approx(weight * np.array([-np.sin(theta), 0, np.cos(theta)]), rel=1e-9)
    assert held.friction.max_cone_use <= 1 + 1e-9
    slid = _incline(1.03 * limit, MU)
    assert not slid.converged and slid.held is False
    assert slid.stop_reason.startswith("not held: block slips along (")


@pytest.mark.parametrize("factor", [0.97, 1.03])
def test_the_weighted_incline_between_bodies_does_not_depend_on_round_off(factor):
    theta = factor * np.degrees(np.arctan(MU))
    ref = _incline(theta, MU)
    for seed in range(2):
        with roundoff(seed):
            same_outcome(ref, _incline(theta, MU))


R = 0.02
_BALL = fem.ball_mesh(R, divisions=8, layers=4)


def _pads(weight, press=5e-4):
    """A free ball squeezed between two pads (blocks fixed at their backs), its weight down."""
    soft = fem.LinearElastic(1.0e6, 0.45, 1000.0)
    g = fem.gravity_load(_BALL, soft, (0.0, 0.0, -1.0))
    ball = ElasticBody("ball", _BALL, soft, loads=g / -g[2::3].sum() * weight)
    bodies, pairs = [ball], []
    for name, side in (("left", -1.0), ("right", 1.0)):
        x0 = side * (R - press) if side < 0 else R - press
        origin = (x0 - 0.005 if side < 0 else x0, -0.012, -0.012)
        mesh = fem.box_mesh((0.005, 0.024, 0.024), (2, 6, 6), origin=origin)
        back = np.isclose(mesh.points[:, 0], origin[0] + (0.0 if side < 0 else 0.005))
        pad = ElasticBody(name, mesh, fem.LinearElastic(5.0e6, 0.3),
                          prescribed=fem.node_dofs(np.flatnonzero(back), [0, 1, 2]))  # fmt: skip
        bodies.append(pad)
        pairs.append(ContactPair(ball, pad, mortar=True, friction=0.5))
    return solve_frame(bodies, pairs, [])


def test_two_pads_hold_a_ball_up_to_twice_mu_n_and_drop_it_past():
    first = _pads(0.0)
    assert first.converged and first.held, first.stop_reason
    squeeze = abs(first.contact_force["left"].sum(axis=0)[0])
    assert squeeze > 0
    for factor in (0.95, 1.05):
        weight = factor * 2 * 0.5 * squeeze
        res = _pads(weight)
        if factor < 1:
            assert res.converged and res.held, res.stop_reason
            ball = res.contact_force["ball"].sum(axis=0)
            assert ball == pytest.approx([0.0, 0.0, weight], abs=1e-10 * weight)
            pads = res.contact_force["left"].sum(axis=0) + res.contact_force["right"].sum(axis=0)
            assert np.abs(ball + pads).max() <= 1e-10 * weight
            assert res.contact_force["left"].sum(axis=0)[2] == pytest.approx(-weight / 2, rel=1e-6)
        else:
            assert not res.converged and res.held is False
            assert res.stop_reason.startswith("not held: ball slips along (")
