"""Coulomb friction against exact answers: the law itself, two pads holding a ball against
its weight, a frictional patch test, a block on an incline."""

from pathlib import Path

import numpy as np
import pytest

import fem
from contact.errors import ContactError
from contact.geometry.plane import Plane
from contact.run import GraspRun
from contact.scene import load_scene
from contact.solver import ContactSettings, solve_frame
from contact.solver.body import ElasticBody
from contact.solver.friction import SLIP, STICK, solve_friction
from contact.solver.pairs import ContactPair
from contact.solver.tangential import tangent_basis
from tests.helpers import example, roundoff, same_outcome

ROOT = Path(__file__).resolve().parents[2]

R, E, NU, RHO = 0.02, 1.0e5, 0.45, 1000.0
NU_PATCH = 0.3


# ---------------------------------------------------------------------- the law


def _random_problem(rng, k, r=0):
    m = 3 * k
    a = rng.standard_normal((m, m + 20))
    w = a @ a.T / m + 0.05 * np.eye(m)
    g = rng.standard_normal((m, r))
    rhs = rng.standard_normal(m)
    c = g.T @ np.abs(rng.standard_normal(m)) * 0.1 if r else np.zeros(0)
    tangent = np.column_stack([k + 2 * np.arange(k), k + 2 * np.arange(k) + 1])
    return w, g, rhs, c, tangent


@pytest.mark.parametrize("seed", range(6))
def test_the_solve_meets_coulombs_law(seed):
    rng = np.random.default_rng(seed)
    k = 30
    w, g, rhs, c, tangent = _random_problem(rng, k, r=3 if seed % 2 else 0)
    mu = rng.uniform(0.1, 1.5, k)
    res = solve_friction(w, g, rhs, c, mu=mu, tangent=tangent)
    assert res.solved and res.residual <= 1e-9
    lam, y = res.lam, res.y
    scale = np.abs(lam).max()
    n, gap = lam[:k], y[:k]
    t, s = lam[tangent], y[tangent]
    assert n.min() >= -1e-12 * scale and gap.min() >= -1e-9 * np.abs(y).max()
    assert np.abs(n * gap).max() <= 1e-9 * scale * np.abs(y).max()
    # the cone, stick where inside it, slip opposed to the force on it
    size = np.linalg.norm(t, axis=1)
    assert (size - mu * n).max() <= 1e-8 * scale
    stick, slip = res.status == STICK, res.status == SLIP
    assert np.abs(s[stick]).max(initial=0.0) <= 1e-9 * np.abs(y).max()
    moving = slip & (np.linalg.norm(s, axis=1) > 1e-9 * np.abs(y).max())
    assert np.allclose(size[moving], mu[moving] * n[moving], rtol=1e-8)
    cos = np.einsum("ij,ij->i", t[moving], s[moving]) / (
        size[moving] * np.linalg.norm(s[moving], axis=1)
    )
    assert np.allclose(cos, -1.0, atol=1e-8)
    if g.shape[1]:
        assert np.abs(g.T @ lam - c).max() <= 1e-9 * scale


def test_a_point_sticks_below_the_cone_and_slides_on_it():
    w, g, c = np.eye(3) / 1000.0, np.zeros((3, 0)), np.zeros(0)
    tangent = np.array([[1, 2]])
    stuck = solve_friction(w, g, np.array([0.002, 1e-4, 0.0]), c, mu=np.array([0.5]),
                           tangent=tangent)
    assert stuck.status[0] == STICK and np.allclose(stuck.lam, [2.0, 0.1, 0.0])
    slid = solve_friction(w, g, np.array([0.002, 0.003, -0.004]), c, mu=np.array([0.5]),
                          tangent=tangent)
    assert slid.status[0] == SLIP and np.allclose(slid.lam, [2.0, 0.6, -0.8])


def test_the_tangent_basis_is_orthonormal_and_the_same_for_the_same_normal():
    rng = np.random.default_rng(1)
    n = rng.standard_normal((50, 3))
    n = np.vstack([n / np.linalg.norm(n, axis=1)[:, None], np.eye(3), -np.eye(3)])
    t1, t2 = tangent_basis(n)
    for a, b in ((t1, t2), (t1, n), (t2, n)):
        assert np.abs(np.einsum("ij,ij->i", a, b)).max() < 1e-14
    assert np.allclose(np.linalg.norm(t1, axis=1), 1) and np.allclose(np.cross(t1, t2), n)
    again = tangent_basis(n.copy())
    assert np.array_equal(again[0], t1) and np.array_equal(again[1], t2)


# ---------------------------------------------------------------------- two pads


_PADS_MESH = fem.ball_mesh(R, R / 6)


def _pads(weight, mu=0.5, press=5e-4):
    mesh = _PADS_MESH
    mat = fem.LinearElastic(E, NU, RHO)
    g = fem.gravity_load(mesh, mat, (0.0, 0.0, -1.0))
    loads = g / -g[2::3].sum() * weight
    ball = ElasticBody("ball", mesh, mat, loads=loads)
    left = Plane((-R, 0, 0), (1, 0, 0), motion=(press, 0, 0), name="left")
    right = Plane((R, 0, 0), (-1, 0, 0), motion=(-press, 0, 0), name="right")
    pairs = [ContactPair(ball, left, friction=mu), ContactPair(ball, right, friction=mu)]
    return solve_frame([ball], pairs, [left, right], ContactSettings()), loads


@pytest.fixture(scope="module")
def squeeze():
    """The pads' normal force without weight."""
    res, _ = _pads(0.0)
    assert res.converged, res.stop_reason
    return float(np.linalg.norm(res.obstacle_forces["left"]))


@pytest.mark.parametrize("factor", [0.95, 0.995])
def test_two_pads_hold_a_ball_up_to_twice_mu_n(squeeze, factor):
    mu = 0.5
    weight = factor * 2 * mu * squeeze
    res, loads = _pads(weight, mu)
    assert res.converged and res.held, res.stop_reason
    n = abs(res.obstacle_forces["left"][0])
    assert weight <= 2 * mu * n
    for pad in ("left", "right"):
        # each pad carries half the weight, along gravity
        assert res.obstacle_forces[pad][2] == pytest.approx(-weight / 2, rel=1e-9)
        assert res.friction.tangential_force[pad][2] == pytest.approx(-weight / 2, rel=1e-9)
    # the ball in balance, the cone held, the motion along gravity only elastic
    ball = res.contact_force["ball"].sum(axis=0) + loads.reshape(-1, 3).sum(axis=0)
    assert np.abs(ball).max() <= 1e-10 * weight
    f = res.contact_force["ball"] + loads.reshape(-1, 3)
    moment = np.cross(_PADS_MESH.points, f).sum(axis=0)
    assert np.abs(moment).max() <= 1e-10 * weight * R
    assert res.friction.max_cone_use <= 1 + 1e-9
    assert res.friction.residual <= res.friction.tolerance
    # (Mindlin's tangential compliance of the pads' patches: a fraction of a millimetre)
    assert np.abs(res.displacement["ball"][:, 2]).max() < 0.05 * R
    # action and reaction between the ball and the pads
    total = res.contact_force["ball"].sum(axis=0) + sum(res.obstacle_forces.values())
    assert np.abs(total).max() <= 1e-10 * weight


@pytest.mark.parametrize("factor", [1.005, 1.05])
def test_two_pads_drop_a_ball_heavier_than_twice_mu_n(squeeze, factor):
    res, _ = _pads(factor * 2 * 0.5 * squeeze)
    assert not res.converged and res.held is False
    assert res.stop_reason.startswith("not held: ball slips along (")
    assert "-1.000)" in res.stop_reason  # along gravity


# ---------------------------------------------------------------------- round-off


@pytest.mark.parametrize("factor", [0.0, 0.95, 1.05])
def test_the_pads_verdict_and_motion_do_not_depend_on_round_off(squeeze, factor):
    # unloaded, the ball is held at one node a pad: nothing holds its turn about the pads'
    # axis and nothing asks for it; it must not turn by whatever the round-off says
    weight = factor * 2 * 0.5 * squeeze
    ref, _ = _pads(weight)
    _, omega = fem.rigid_part(_PADS_MESH.points, ref.displacement["ball"])
    if factor < 1:
        assert ref.converged and ref.held, ref.stop_reason
        assert abs(omega[0]) <= 1e-12
    for seed in range(3):
        with roundoff(seed):
            res, _ = _pads(weight)
        same_outcome(ref, res)


# ---------------------------------------------------------------------- patch test


def _block_loads(body, strain, floor_traction):
    """Nodal loads of the uniform strain ``strain`` on every face but the bottom.

    ``K u`` of the linear field is the consistent load of its stress on every face; the
    bottom face's share (``floor_traction`` times each node's tributary area, a uniform
    traction on bilinear quadrilaterals) is what the floor must give.
    """
    x = body.mesh.points
    f = body.stiffness @ (x @ strain.T).ravel()
    bottom = np.flatnonzero(np.isclose(x[:, 2], 0.0))
    area = _bottom_areas(x, bottom)
    f.reshape(-1, 3)[bottom] -= area[:, None] * np.asarray(floor_traction)
    return f


def _bottom_areas(x, bottom):
    """Tributary areas of the bottom nodes of a regular grid."""
    xs, ys = np.unique(x[bottom, 0]), np.unique(x[bottom, 1])
    wx = np.diff(xs)
    wy = np.diff(ys)
    ax = np.zeros(xs.size)
    ay = np.zeros(ys.size)
    ax[:-1] += wx / 2
    ax[1:] += wx / 2
    ay[:-1] += wy / 2
    ay[1:] += wy / 2
    ix = np.searchsorted(xs, x[bottom, 0])
    iy = np.searchsorted(ys, x[bottom, 1])
    return ax[ix] * ay[iy]


def _block(loads, mu, anchors=None):
    mesh = fem.box_mesh((0.02, 0.02, 0.01), (4, 4, 2))
    mat = fem.LinearElastic(E, NU_PATCH)
    body = ElasticBody("block", mesh, mat)
    body = ElasticBody("block", mesh, mat, loads=loads(body))
    floor = Plane((0, 0, 0), (0, 0, 1), name="floor")
    pair = ContactPair(body, floor, friction=mu)
    return solve_frame([body], [pair], [floor], ContactSettings(), anchors=anchors), body


def test_a_frictional_patch_sticks_uniformly_below_mu_p_and_slides_above():
    p, mu = 1.0e3, 0.4
    # uniaxial compression, lateral faces free: pressed at mu = 0 first
    eps_p = np.diag([NU_PATCH * p / E, NU_PATCH * p / E, -p / E])
    first, _ = _block(lambda b: _block_loads(b, eps_p, (0, 0, p)), 0.0)
    assert first.converged, first.stop_reason
    for ratio in (0.5, 0.9):
        tau = ratio * mu * p
        gamma = tau / (E / (2 * (1 + NU_PATCH)))
        shear = eps_p.copy()
        shear[0, 2] = gamma  # u_x = gamma z: the bottom does not move
        res, body = _block(
            lambda b, s=shear, q=tau: _block_loads(b, s, (-q, 0, p)), mu, first.anchors
        )
        assert res.converged and res.held, res.stop_reason
        bottom = np.flatnonzero(np.isclose(body.mesh.points[:, 2], 0.0))
        area = 0.02 * 0.02
        f = res.contact_force["block"][bottom]
        assert f[:, 2].sum() == pytest.approx(p * area, rel=1e-9)
        assert f[:, 0].sum() == pytest.approx(-tau * area, rel=1e-9)
        # uniform traction: the tangential force per node is tau times its normal force / p
        assert np.allclose(f[:, 0], -tau / p * f[:, 2], rtol=1e-8, atol=1e-12 * tau * area)
        assert res.friction.slip == 0 and res.friction.stick == bottom.size
        assert res.friction.max_cone_use == pytest.approx(ratio, rel=1e-8)
    shear = eps_p.copy()
    shear[0, 2] = 1.02 * mu * p / (E / (2 * (1 + NU_PATCH)))  # the same, past mu p
    tau = 1.02 * mu * p
    res, _ = _block(lambda b: _block_loads(b, shear, (-tau, 0, p)), mu, first.anchors)
    assert not res.converged and res.held is False
    assert res.stop_reason.startswith("not held: block slips along (1.000, ")


@pytest.mark.parametrize("ratio", [0.9, 1.02])
def test_the_frictional_patch_does_not_depend_on_round_off(ratio):
    p, mu = 1.0e3, 0.4
    eps_p = np.diag([NU_PATCH * p / E, NU_PATCH * p / E, -p / E])
    first, _ = _block(lambda b: _block_loads(b, eps_p, (0, 0, p)), 0.0)
    tau = ratio * mu * p
    shear = eps_p.copy()
    shear[0, 2] = tau / (E / (2 * (1 + NU_PATCH)))

    def solve():
        return _block(lambda b: _block_loads(b, shear, (-tau, 0, p)), mu, first.anchors)[0]

    ref = solve()
    for seed in range(3):
        with roundoff(seed):
            same_outcome(ref, solve())


def test_without_friction_anchors_change_nothing():
    # mu = 0: the frictionless path, whatever the anchors of an earlier frame say
    p = 1.0e3
    eps_p = np.diag([NU_PATCH * p / E, NU_PATCH * p / E, -p / E])
    first, _ = _block(lambda b: _block_loads(b, eps_p, (0, 0, p)), 0.0)
    again, _ = _block(lambda b: _block_loads(b, eps_p, (0, 0, p)), 0.0, first.anchors)
    assert first.friction is None and again.friction is None
    assert np.array_equal(first.contact_force["block"], again.contact_force["block"])
    assert len(first.anchors) == first.contacts["node"].size


# ---------------------------------------------------------------------- incline


def _incline(theta_deg, mu):
    theta = np.radians(theta_deg)
    mesh = fem.box_mesh((0.02, 0.02, 0.01), (4, 4, 2))
    mat = fem.LinearElastic(E, 0.3, RHO)
    # the block rests on a plane tilted about y; gravity tilted instead of the mesh
    g = 9.81 * np.array([np.sin(theta), 0.0, -np.cos(theta)])
    body = ElasticBody("block", mesh, mat, loads=fem.gravity_load(mesh, mat, g))
    floor = Plane((0, 0, 0), (0, 0, 1), name="incline")
    pair = ContactPair(body, floor, friction=mu)
    return solve_frame([body], [pair], [floor], ContactSettings())


def test_a_block_on_an_incline_sticks_iff_tan_theta_is_at_most_mu():
    mu = 0.3
    limit = np.degrees(np.arctan(mu))
    held = _incline(0.97 * limit, mu)
    assert held.converged and held.held, held.stop_reason
    weight = np.linalg.norm(held.obstacle_forces["incline"])
    assert held.friction.tangential_force["incline"][0] == pytest.approx(
        weight * np.sin(np.radians(0.97 * limit)), rel=1e-9
    )
    slid = _incline(1.03 * limit, mu)
    assert not slid.converged and slid.held is False
    assert slid.stop_reason.startswith("not held: block slips along (")
    # the block is left where its contacts hold it, not where a search for a balance
    # that does not exist stopped (hundreds of kilometres down the slope)
    assert np.abs(slid.displacement["block"]).max() <= 1e-3 * 0.02


@pytest.mark.parametrize("factor", [0.97, 1.03])
def test_the_incline_does_not_depend_on_round_off(factor):
    mu = 0.3
    theta = factor * np.degrees(np.arctan(mu))
    ref = _incline(theta, mu)
    for seed in range(3):
        with roundoff(seed):
            same_outcome(ref, _incline(theta, mu))


# ---------------------------------------------------------------------- the seed loop


def test_the_seed_loop_refuses_friction():
    mesh = fem.box_mesh((0.02, 0.02, 0.01), (2, 2, 1))
    body = ElasticBody("block", mesh, fem.LinearElastic(E, 0.3),
                       prescribed=np.arange(3 * 4))
    floor = Plane((0, 0, 0), (0, 0, 1), name="floor")
    with pytest.raises(ContactError, match="seed loop takes no friction"):
        solve_frame([body], [ContactPair(body, floor, friction=0.2)], [floor],
                    ContactSettings(algorithm="seed"))


# ---------------------------------------------------------------------- the hand


def _moment(points, forces, about):
    return np.cross(points - about, forces).sum(axis=0)


def test_a_frictional_hand_holds_the_example_ball_in_balance(tmp_path):
    # the bowl example with skin friction 0.5 and linear flesh: two-way rows between skin
    # and ball, a frictionless bowl; every frame held, the ball in balance in force and
    # moment
    text = example("bowl", "linear").replace("[hand]\n", "[hand]\nfriction = 0.5\n", 1)
    path = tmp_path / "bowl.toml"
    path.write_text(text)
    run = GraspRun(load_scene(path))
    for t in (0.0, 0.5, 1.0):
        res, _, _, bodies = run.frame(t)
        assert res.converged and res.held, (t, res.stop_reason)
        assert res.friction.residual <= 1e-12 and res.friction.max_cone_use <= 1 + 1e-12
        assert res.friction.stick + res.friction.slip > 0
        ball = bodies[0]
        f = res.contact_force["ball"] + ball.loads.reshape(-1, 3)
        scale = np.abs(res.contact_force["ball"]).sum()
        size = np.ptp(ball.mesh.points, axis=0).max() / 2
        assert np.abs(f.sum(axis=0)).max() <= 1e-10 * scale
        # moments about the centre, on the reference placement (linear kinematics)
        centre = ball.mesh.points.mean(axis=0)
        moment = np.cross(ball.mesh.points - centre, f).sum(axis=0)
        assert np.abs(moment).max() <= 1e-10 * scale * size
        # action and reaction: ball, hand and planes sum to zero
        total = (
            res.contact_force["ball"].sum(axis=0)
            + res.contact_force["hand"].sum(axis=0)
            + sum(res.obstacle_forces.values())
        )
        assert np.abs(total).max() <= 1e-10 * scale
