"""The contact patch test: two stacked blocks with non-matching meshes under a uniform
pressure transmit it uniformly, whichever block is the stiffer, with mortar rows; node to
surface rows do not (the reason mortar exists)."""

import numpy as np
import pytest

import fem
from contact.solver import ContactSettings, solve_frame
from contact.solver.body import ElasticBody
from contact.solver.pairs import ContactPair

P = 1.0e4  # Pa
E_LOW = 1.0e6


def blocks(ratio):
    lower_mesh = fem.box_mesh((1.0, 1.0, 0.5), (7, 5, 3), (0.0, 0.0, -0.5))
    upper_mesh = fem.box_mesh((1.0, 1.0, 0.5), (4, 4, 2), (0.0, 0.0, 0.0))
    bottom = np.flatnonzero(np.isclose(lower_mesh.points[:, 2], -0.5))
    # the lower block sits on rollers (z held at the bottom) with one corner pinned: free
    # to expand sideways like the upper one, so that the exact state is uniform
    corner = bottom[np.argmin(np.linalg.norm(lower_mesh.points[bottom], axis=1))]
    edge_x = bottom[np.isclose(lower_mesh.points[bottom, 1], 0.0)]
    held = np.unique(
        np.concatenate(
            [
                fem.node_dofs(bottom, [2]),
                fem.node_dofs([corner], [0, 1]),
                fem.node_dofs(edge_x, [1]),
            ]
        )
    )
    lower = ElasticBody("lower", lower_mesh, fem.LinearElastic(E_LOW, 0.3), prescribed=held)
    top = upper_mesh.boundary.subset(
        {
            k: np.isclose(upper_mesh.points[f, 2], 0.5).all(axis=1)
            for k, f in upper_mesh.boundary.faces.items()
        }
    )
    loads = fem.pressure_load(upper_mesh, top, P)
    upper = ElasticBody("upper", upper_mesh, fem.LinearElastic(ratio * E_LOW, 0.3), loads=loads)
    return upper, lower


def stresses(body, res):
    return fem.cell_stress(body.mesh, body.materials, res.displacement[body.name].ravel())


@pytest.mark.parametrize("ratio", [0.01, 1.0, 100.0])
@pytest.mark.parametrize("upper_is_slave", [True, False])
def test_mortar_transmits_a_uniform_pressure_uniformly(ratio, upper_is_slave):
    upper, lower = blocks(ratio)
    pair = (
        ContactPair(upper, lower, mortar=True)
        if upper_is_slave
        else ContactPair(lower, upper, mortar=True)
    )
    res = solve_frame([upper, lower], [pair], [], ContactSettings())
    assert res.converged, res.stop_reason
    for body in (upper, lower):
        for sigma in stresses(body, res).values():
            expected = np.zeros((3, 3))
            expected[2, 2] = -P
            assert np.abs(sigma - expected).max() <= 1e-8 * P, body.name
    # the contact forces add up to the load on the top
    # the lower block holds the upper up against the pressure on its top (1 m^2)
    assert res.total_contact_force("upper")[2] == pytest.approx(P * 1.0, rel=1e-10)
    assert (res.contacts["force"] > 0).all()


def test_node_to_surface_does_not_pass_it():
    upper, lower = blocks(1.0)
    res = solve_frame([upper, lower], [ContactPair(upper, lower)], [], ContactSettings())
    assert res.converged
    worst = max(
        np.abs(sigma[:, 2, 2] + P).max()
        for body in (upper, lower)
        for sigma in stresses(body, res).values()
    )
    assert worst > 0.05 * P
