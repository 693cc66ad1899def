"""Finite-strain frames: Newton's method around the contact-space solve, against the same
problem solved by finite-strain Newton with the contact written as prescribed values."""

import numpy as np
import pytest

import fem
from contact.geometry.plane import Plane
from contact.solver import ContactSettings, finite, solve_frame
from contact.solver.body import ElasticBody
from contact.solver.finite import FiniteBody, solve_finite_frame
from contact.solver.pairs import ContactPair
from tests.helpers import uniaxial_stress

E, NU, H = 1.0e6, 0.45, 0.01
MAT = fem.LinearElastic(E, NU)


def _bonded(kind):
    mesh = fem.box_mesh((H, H, H), (3, 3, 3))
    if kind == "tetra":
        mesh = fem.hex_to_tet(mesh)
    bottom = np.flatnonzero(np.isclose(mesh.points[:, 2], 0.0))
    return mesh, (3 * bottom[:, None] + np.arange(3)).ravel()


def _plate(press):
    return Plane((0, 0, H), (0, 0, -1), motion=(0, 0, -press * H), name="plate")


@pytest.mark.parametrize(("kind", "strain"), [("hexahedron", 0.2), ("tetra", 0.15)])
def test_a_bonded_block_pressed_by_a_frictionless_plate(kind, strain):
    # the plate is frictionless: its contact is the top's u_z prescribed, u_x and u_y free
    mesh, base = _bonded(kind)
    body = FiniteBody("block", mesh, MAT, prescribed=base)
    start = None
    for press in np.linspace(0.05, strain, round(strain / 0.05)):
        plate = _plate(press)
        out = solve_finite_frame([body], [ContactPair(body, plate)], [plate], start=start)
        assert out.converged and out.steps <= 6, out.stop_reason
        start = {"block": out.displacement["block"]}
    top = np.flatnonzero(np.isclose(mesh.points[:, 2], H))
    ref = fem.solve_finite_strain(
        mesh, MAT, prescribed=np.concatenate([base, 3 * top + 2]),
        values=np.concatenate([np.zeros(base.size), np.full(top.size, -strain * H)]),
        increments=round(strain / 0.05),
    )  # fmt: skip
    assert ref.converged
    assert np.abs(out.displacement["block"] - ref.u).max() <= 1e-9 * H
    force = out.result.obstacle_forces["plate"][2]
    assert force == pytest.approx(-ref.reactions[3 * top + 2].sum(), rel=1e-9)
    assert out.residual <= 1e-8


def test_a_body_that_carries_nothing_is_in_balance_against_the_frames_forces():
    # a second block, started a micron off its rest, touches nothing: it relaxes to rest
    # with no force of its own, and Newton measures what is left against the frame's
    mesh, base = _bonded("hexahedron")
    pressed = FiniteBody("block", mesh, MAT, prescribed=base)
    aside = fem.Mesh(mesh.points + np.array([3 * H, 0.0, 0.0]), mesh.cells, mesh.regions)
    idle = FiniteBody("idle", aside, MAT, prescribed=base)
    start = {"idle": 1e-4 * H * np.sin(np.arange(mesh.n_dofs, dtype=float))}
    start["idle"][base] = 0.0
    plate = _plate(0.05)
    out = solve_finite_frame([pressed, idle], [ContactPair(pressed, plate)], [plate], start=start)
    assert out.converged and out.steps <= 6, out.stop_reason
    assert np.abs(out.displacement["idle"]).max() <= 1e-9 * H


def test_at_small_strain_it_is_the_linear_frame():
    mesh, base = _bonded("hexahedron")
    press = 1e-6
    plate = _plate(press)
    fin = FiniteBody("block", mesh, MAT, prescribed=base)
    out = solve_finite_frame([fin], [ContactPair(fin, plate)], [plate])
    lin = ElasticBody("block", mesh, MAT, prescribed=base)
    ref = solve_frame([lin], [ContactPair(lin, plate)], [plate], ContactSettings())
    u = ref.displacement["block"]
    assert np.abs(out.displacement["block"] - u).max() <= 1e-5 * np.abs(u).max()


@pytest.mark.parametrize("kind", ["hexahedron", "tetra"])
def test_a_free_block_between_frictionless_plates_to_30_percent_is_exact(kind):
    # nothing but the plates holds it: uniaxial stress, about its centroid sideways
    mesh = fem.box_mesh((H, H, H), (3, 3, 3))
    if kind == "tetra":
        mesh = fem.hex_to_tet(mesh)
    lam, mu = MAT.lame
    body = FiniteBody("block", mesh, MAT)
    start = None
    x = mesh.points
    c = x.mean(axis=0)
    for press in (0.1, 0.2, 0.3):
        table = Plane((0, 0, 0), (0, 0, 1), name="table")
        plate = _plate(press)
        out = solve_finite_frame(
            [body], [ContactPair(body, table), ContactPair(body, plate)], [table, plate],
            start=start,
        )  # fmt: skip
        assert out.converged and out.steps <= 6, out.stop_reason
        start = {"block": out.displacement["block"]}
        axial = 1 - press
        side, p33 = uniaxial_stress(lam, mu, axial)
        exact = np.column_stack([(x[:, :2] - c[:2]) * (side - 1), x[:, 2] * (axial - 1)])
        assert np.abs(out.displacement["block"] - exact).max() <= 1e-10 * H
        assert out.result.obstacle_forces["plate"][2] == pytest.approx(-p33 * H * H, rel=1e-8)


def test_a_free_ball_pressed_to_a_fifth_of_its_radius():
    r = 0.02
    mesh = fem.ball_mesh(r, r / 5)
    body = FiniteBody("ball", mesh, MAT)
    start = None
    for d in (0.05, 0.1, 0.2):
        table = Plane((0, 0, -r), (0, 0, 1), motion=(0, 0, d * r / 2), name="table")
        plate = Plane((0, 0, r), (0, 0, -1), motion=(0, 0, -d * r / 2), name="plate")
        out = solve_finite_frame(
            [body], [ContactPair(body, table), ContactPair(body, plate)], [table, plate],
            start=start,
        )  # fmt: skip
        # a squeezed free body's full-tangent steps slow to a linear rate; the material
        # tangent with Anderson mixing takes over: Newton's own rate is not reached
        assert out.converged and out.steps <= 12, out.stop_reason
        start = {"ball": out.displacement["ball"]}
        f = out.result.obstacle_forces
        assert f["table"] == pytest.approx(-f["plate"], rel=1e-8, abs=1e-10 * abs(f["plate"][2]))
    assert out.result.max_penetration <= 0.01 * r


def test_a_free_ball_rolled_45_degrees_between_a_table_and_a_moving_plate():
    # mu 1: the plate carries the ball's top along, the table holds its bottom: it rolls
    # s / 2r, r its centre's height over the table (R less half the squeeze)
    r = 0.02
    press = 0.05 * r
    mesh = fem.ball_mesh(r, r / 5)
    body = FiniteBody("ball", mesh, MAT)
    start, anchors = None, None
    travel = 2 * r * np.pi / 4
    for s in np.linspace(0.0, travel, 6):
        table = Plane((0, 0, -r), (0, 0, 1), name="table")
        plate = Plane((0, 0, r), (0, 0, -1), motion=(s, 0, -press), name="plate")
        pairs = [ContactPair(body, table, friction=1.0), ContactPair(body, plate, friction=1.0)]
        out = solve_finite_frame([body], pairs, [table, plate], start=start, anchors=anchors)
        assert out.converged and out.result.held and out.steps <= 8, out.stop_reason
        start, anchors = {"ball": out.displacement["ball"]}, out.result.anchors
    # the turn of the ball's nodes (Kabsch), about y
    x0 = mesh.points - mesh.points.mean(axis=0)
    x1 = mesh.points + out.displacement["ball"]
    u, _, vt = np.linalg.svd((x1 - x1.mean(axis=0)).T @ x0)
    turn = u @ vt
    angle = np.degrees(np.arctan2(turn[0, 2], turn[0, 0]))
    centre = r - press / 2
    assert angle == pytest.approx(np.degrees(travel / (2 * centre)), rel=0.02)
    assert abs(turn[1, 1] - 1) <= 1e-6  # about y only


@pytest.mark.parametrize("factor", [0.9, 1.1])
def test_force_driven_pads_hold_a_finite_ball_up_to_twice_mu_p(factor):
    # two pads pressing 3 N each squeeze a soft ball by about an eighth of its radius
    r, mu, p = 0.02, 0.5, 3.0
    mesh = fem.ball_mesh(r, r / 5)
    mat = fem.LinearElastic(1.0e5, NU, 1000.0)
    g = fem.gravity_load(mesh, mat, (0, 0, -9.81))
    weight = factor * 2 * mu * p
    body = FiniteBody("ball", mesh, mat, loads=g / -g[2::3].sum() * weight)
    left = Plane((-r, 0, 0), (1, 0, 0), force=p, name="left")
    right = Plane((r, 0, 0), (-1, 0, 0), force=p, name="right")
    pairs = [ContactPair(body, left, friction=mu), ContactPair(body, right, friction=mu)]
    out = solve_finite_frame([body], pairs, [left, right])
    res = out.result
    if factor < 1:
        assert out.converged and res.held and out.steps <= 15, out.stop_reason
        for pad in ("left", "right"):
            assert abs(res.obstacle_forces[pad][0]) == pytest.approx(p, rel=1e-8)
            assert res.obstacle_forces[pad][2] == pytest.approx(-weight / 2, rel=1e-8)
    else:
        assert not out.converged and res.held is False
        assert res.stop_reason.startswith("not held: ball slips along (0.000, 0.000, -1.000)")
        assert res.slip["not_carried"] == pytest.approx(weight - 2 * mu * p, rel=0.01)


def _offset_weight(weight: float = 0.2, scale: float = 1.0):
    """A ball pinched by force-driven pads (1 N, mu 0.8), a weight hung off its centre."""
    r, mu, p = 0.02, 0.8, 1.0
    mesh = fem.ball_mesh(r, r / 5)
    loads = np.zeros(mesh.n_dofs)
    loads[3 * int(np.argmax(mesh.points[:, 1])) + 2] = -weight * scale
    body = FiniteBody("ball", mesh, fem.LinearElastic(1.0e5, NU), loads=loads)
    left = Plane((-r, 0, 0), (1, 0, 0), force=p, name="left")
    right = Plane((r, 0, 0), (-1, 0, 0), force=p, name="right")
    pairs = [ContactPair(body, left, friction=mu), ContactPair(body, right, friction=mu)]
    return mesh, loads, solve_finite_frame([body], pairs, [left, right])


def test_a_pinched_ball_turns_under_an_offset_weight_in_a_few_newton_steps():
    # a weight hung off the centre of a ball pinched by force-driven pads turns it about
    # the pads' axis until friction holds the moment: the free-body solve borders the
    # ball's compliance with its turn stiffness, and Newton converges quadratically
    r, weight = 0.02, 0.2
    mesh, loads, out = _offset_weight(weight)
    assert out.converged and out.result.held and out.steps <= 6, (out.steps, out.stop_reason)
    # the deformed ball in balance of forces and of moments, its contacts' forces included
    x = mesh.points + out.displacement["ball"]
    f = np.asarray(out.result.contact_force["ball"]).reshape(-1, 3) + loads.reshape(-1, 3)
    assert np.abs(f.sum(axis=0)).max() <= 1e-7 * weight
    assert np.abs(np.cross(x, f).sum(axis=0)).max() <= 1e-7 * weight * r
    _, omega = fem.rigid_part(mesh.points, out.displacement["ball"])
    assert np.degrees(abs(omega[0])) > 5 and np.degrees(np.abs(omega[1:])).max() < 0.5


def test_a_pinched_ball_its_weight_turns_past_friction_swings_until_friction_holds_it():
    # twice the weight: at its placement friction's moment about the pads' axis cannot
    # hold its arm (the linear frame says not held), but turning shortens the arm. The
    # ball is followed, its steps damped, until the cones hold it at their limit
    r, weight = 0.02, 0.4
    mesh, loads, out = _offset_weight(weight)
    res = out.result
    assert out.converged and res.held and out.steps <= 20, (out.steps, out.stop_reason)
    x = mesh.points + out.displacement["ball"]
    f = np.asarray(res.contact_force["ball"]).reshape(-1, 3) + loads.reshape(-1, 3)
    assert np.abs(f.sum(axis=0)).max() <= 1e-7 * weight
    assert np.abs(np.cross(x, f).sum(axis=0)).max() <= 1e-7 * weight * r
    _, omega = fem.rigid_part(mesh.points, out.displacement["ball"])
    assert np.degrees(abs(omega[0])) > 15 and np.degrees(np.abs(omega[1:])).max() < 1
    # every contact slides at its cone: the turn went as far as friction let it
    assert res.friction.stick == 0 and res.friction.max_cone_use == pytest.approx(1, abs=1e-8)


@pytest.mark.parametrize("weight", [0.2, pytest.param(0.4, marks=pytest.mark.slow)])
def test_a_round_off_change_of_the_offset_weight_leaves_the_turned_ball_as_it_was(weight):
    _, _, out = _offset_weight(weight)
    _, _, again = _offset_weight(weight, scale=1.0 + 1e-15)
    # the verdict and the balance found; the path to it may differ by a damped retry
    assert (again.converged, again.result.held) == (out.converged, out.result.held) == (
        True, True
    )
    assert abs(again.steps - out.steps) <= 3
    u, v = out.displacement["ball"], again.displacement["ball"]
    assert np.abs(u - v).max() <= 1e-9 * np.abs(u).max()


def test_at_a_small_load_a_free_ball_between_plates_is_the_linear_one():
    # Hertz's regime: the finite model's force and displacements are the linear model's
    r, d = 0.02, 1e-3
    mesh = fem.ball_mesh(r, r / 6)  # a node at each pole
    planes = [
        Plane((0, 0, -r), (0, 0, 1), motion=(0, 0, d * r), name="table"),
        Plane((0, 0, r), (0, 0, -1), motion=(0, 0, -d * r), name="plate"),
    ]
    fin = FiniteBody("ball", mesh, MAT)
    out = solve_finite_frame([fin], [ContactPair(fin, pl) for pl in planes], planes)
    lin = ElasticBody("ball", mesh, MAT)
    ref = solve_frame([lin], [ContactPair(lin, pl) for pl in planes], planes)
    assert out.converged and ref.converged
    f, f_lin = out.result.obstacle_forces["plate"][2], ref.obstacle_forces["plate"][2]
    # they part as the squeeze's own size, d / R = 1e-3
    assert f == pytest.approx(f_lin, rel=1e-3)
    u, u_lin = out.displacement["ball"], ref.displacement["ball"]
    assert np.abs(u - u_lin).max() <= 1e-3 * np.abs(u_lin).max()


@pytest.mark.parametrize("angle", [0.05, 0.6])
def test_a_free_bodys_turn_is_taken_as_a_finite_rotation(angle):
    # the linearised step omega x r stretches a body by |omega|^2 / 2; the step taken
    # turns it rigidly (no strain), by at most MAX_TURN
    mesh = fem.box_mesh((H, 2 * H, H), (2, 2, 2))
    body = FiniteBody("block", mesh, MAT)
    u = np.zeros(mesh.n_dofs)
    c = mesh.points.mean(axis=0)
    omega = angle * np.array([1.0, 2.0, 2.0]) / 3.0
    move = np.array([1e-3, 0.0, -2e-3])
    du = (move + np.cross(omega, mesh.points - c)).ravel()
    step, short = finite._turned(body, u, du)
    assert short == (angle > finite.MAX_TURN)
    strain = fem.log_strain(mesh, step)
    assert max(np.abs(e).max() for e in strain.values()) <= 1e-12
    taken = min(angle, finite.MAX_TURN)
    x = mesh.points + step.reshape(-1, 3)
    turn = np.linalg.svd((x - x.mean(axis=0)).T @ (mesh.points - c))
    rot = turn[0] @ turn[2]
    assert np.arccos((np.trace(rot) - 1) / 2) == pytest.approx(taken, rel=1e-9)
    assert x.mean(axis=0) - c == pytest.approx(move * taken / angle, abs=1e-12)
    # a small turn is the linearised step to second order
    if angle < finite.MAX_TURN:
        assert np.abs(step - du).max() <= angle**2 * H


def test_a_newton_cut_short_says_nothing_of_holding(monkeypatch):
    # a free ball rolled by a plate: held where Newton converges; where its steps run out
    # or a later tangent cannot be factored, the frame is not converged and held is None,
    # not the last linear step's verdict
    r = 0.02
    body = FiniteBody("ball", fem.ball_mesh(r, r / 5), MAT)
    table = Plane((0, 0, -r), (0, 0, 1), name="table")
    plate = Plane((0, 0, r), (0, 0, -1), motion=(0.3 * r, 0, -0.05 * r), name="plate")
    pairs = [ContactPair(body, table, friction=1.0), ContactPair(body, plate, friction=1.0)]
    out = solve_finite_frame([body], pairs, [table, plate])
    assert out.converged and out.frame_result().held is True and out.steps >= 2
    short = solve_finite_frame([body], pairs, [table, plate], max_steps=1)
    assert not short.converged and short.result.held is True
    assert short.frame_result().held is None and not short.frame_result().converged
    solve, calls = finite.solve_frame, []

    def failing(*args, **kwargs):
        calls.append(1)
        if len(calls) >= 2:
            raise fem.SolverError("could not factor the matrix")
        return solve(*args, **kwargs)

    monkeypatch.setattr(finite, "solve_frame", failing)
    failed = solve_finite_frame([body], pairs, [table, plate])
    assert "could not be factored" in failed.stop_reason
    assert failed.result.held is True and failed.frame_result().held is None
