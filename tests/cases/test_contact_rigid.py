"""A ball against rigid planes: the contact set, action and reaction, equilibrium."""

import numpy as np
import pytest

import fem
from contact.cases.rigid import solve_rigid_contact
from contact.errors import ContactError
from contact.geometry.plane import Plane, tributary_areas
from contact.solver.body import ElasticBody

R, E, NU = 0.035, 1.0e6, 0.45


@pytest.fixture(scope="module")
def ball_mesh():
    return fem.ball_mesh(R, divisions=6, layers=5, center=(0.0, 0.0, R))


def squeeze(mesh, depth, loads=None):
    body = ElasticBody("ball", mesh, fem.LinearElastic(E, NU, density=1100.0), loads=loads)
    planes = [
        Plane([0, 0, 0], [0, 0, 1], name="table"),
        Plane([0, 0, 2 * R], [0, 0, -1], motion=[0, 0, -depth], name="plate"),
    ]
    return body, solve_rigid_contact(body, planes)


def test_ball_between_table_and_plate(ball_mesh):
    body, res = squeeze(ball_mesh, 0.04 * R)
    assert res.converged and res.stop_reason == "converged"
    assert 1 <= res.iterations <= 10
    f_table, f_plate = res.obstacle_forces["table"], res.obstacle_forces["plate"]
    assert f_table[2] < 0 < f_plate[2]  # the ball pushes the table down, the plate up
    # action equals reaction, and the ball (free, no load) is in balance
    scale = abs(f_table[2])
    assert np.abs(res.total_contact_force + f_table + f_plate).max() <= 1e-10 * scale
    assert np.abs(f_table + f_plate).max() <= 1e-10 * scale
    # equilibrium of the ball: K u - f equals the contact forces at every node
    residual = body.stiffness @ res.displacement.ravel() - body.loads
    assert np.abs(residual - res.contact_force.ravel()).max() <= 1e-9 * scale
    # every contact pushes; nothing is left inside a plane
    x = ball_mesh.points + res.displacement
    assert x[:, 2].min() >= -1e-3 * np.sqrt(body.node_areas.max())
    assert x[:, 2].max() <= 2 * R - 0.04 * R + 1e-3 * np.sqrt(body.node_areas.max())
    nodes = res.contact_nodes
    bottom = nodes[ball_mesh.points[nodes, 2] < R]
    assert (res.contact_force[bottom, 2] > 0).all()
    assert len(res.history) == res.iterations
    assert res.history[-1].added == 0 and res.history[-1].released == 0


def test_deeper_press_gives_more_force_and_a_wider_patch(ball_mesh):
    _, shallow = squeeze(ball_mesh, 0.02 * R)
    _, deep = squeeze(ball_mesh, 0.2 * R)
    f1 = -shallow.obstacle_forces["table"][2]
    f2 = -deep.obstacle_forces["table"][2]
    assert f2 > 10.0 * f1  # Hertz: F grows like depth^1.5 (10^1.5 = 32)
    assert len(deep.contact_nodes) > len(shallow.contact_nodes)


def test_ball_resting_under_gravity_carries_its_weight(ball_mesh):
    mat = fem.LinearElastic(E, NU, density=1100.0)
    g = fem.gravity_load(ball_mesh, mat)
    # lift the ball a hair so that only gravity presses it: the table holds it
    mesh = fem.Mesh(ball_mesh.points - np.array([0.0, 0.0, 1e-6]), ball_mesh.cells)
    body = ElasticBody("ball", mesh, mat, loads=g)
    res = solve_rigid_contact(body, [Plane([0, 0, 0], [0, 0, 1], name="table")])
    assert res.converged
    weight = g.reshape(-1, 3).sum(axis=0)
    assert res.obstacle_forces["table"] == pytest.approx(weight, rel=1e-9, abs=1e-12)


def test_nothing_holds_a_falling_ball(ball_mesh):
    mat = fem.LinearElastic(E, NU, density=1100.0)
    body = ElasticBody("ball", ball_mesh, mat, loads=fem.gravity_load(ball_mesh, mat))
    far = Plane([0, 0, -1.0], [0, 0, 1], name="table")
    with pytest.raises(ContactError, match="ball: nothing holds it"):
        solve_rigid_contact(body, [far])


def test_plane_validation():
    with pytest.raises(ContactError, match="table: normal must not be zero"):
        Plane([0, 0, 0], [0, 0, 0], name="table")
    with pytest.raises(ContactError, match="plate: point must be 3 finite numbers"):
        Plane([0, 0], [0, 0, 1], name="plate")
    p = Plane([0, 0, 1], [0, 0, 2], motion=[0, 0, -0.5])
    assert p.signed_distance([[0, 0, 0.0], [1, 2, 1.0]]) == pytest.approx([-0.5, 0.5])
    assert np.allclose(p.project([[3, 4, 2.0]]), [[3, 4, 0.5]])


def test_tributary_areas_sum_to_surface_area():
    box = fem.box_mesh((1.0, 2.0, 3.0), (2, 2, 3))
    a = tributary_areas(box.points, box.boundary.faces)
    assert a.sum() == pytest.approx(2 * (2 + 3 + 6))
    tets = fem.box_mesh((1.0, 2.0, 3.0), (2, 2, 3), element="tetra")
    assert tributary_areas(tets.points, tets.boundary.faces).sum() == pytest.approx(22.0)


@pytest.mark.skipif("pardiso" not in fem.linsolve.BACKENDS, reason="partial solves need PARDISO")
def test_the_contact_zone_is_marked_and_its_rows_take_partial_solves(ball_mesh):
    body, res = squeeze(ball_mesh, 0.04 * R)
    s = body.solver
    assert res.converged and s.n_factorizations == 1
    # the zone (both poles' caps) was marked before the factorisation; every contact
    # row lies in it: no back-solve beyond the six of the free ball's rigid modes
    marked = np.unique(s.marked_dofs // 3)
    assert np.isin(res.contact_nodes, marked).all()
    assert s.n_partial_solves >= res.contact_nodes.size and s.n_back_solves <= 6
    assert marked.size <= body.surface_nodes.size / 3
    assert (np.abs(ball_mesh.points[marked, 2] - R) > 0.5 * R).all()


@pytest.mark.skipif("pardiso" not in fem.linsolve.BACKENDS, reason="partial solves need PARDISO")
def test_mark_zone_takes_the_nearest_nodes_up_to_the_limit(ball_mesh, monkeypatch):
    top = np.flatnonzero(ball_mesh.points[:, 2] > 1.9 * R)
    body = ElasticBody("ball", ball_mesh, fem.LinearElastic(E, NU), prescribed=fem.node_dofs(top))
    nodes = np.setdiff1d(body.surface_nodes, top)
    height = ball_mesh.points[nodes, 2]
    monkeypatch.setattr(fem.statics, "MARK_LIMIT", 30)  # ten nodes
    twice = np.concatenate([nodes, nodes])
    assert body.mark_zone(twice, np.concatenate([height, height])) == 10
    lowest = nodes[np.argsort(height, kind="stable")[:10]]
    assert np.array_equal(body.solver.marked_dofs, np.sort(fem.node_dofs(lowest)))
    body.solver.factorize()
    assert body.mark_zone(nodes, height) == 0  # factored: nothing more is marked
