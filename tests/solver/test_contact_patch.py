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


def test_a_coupling_is_integrated_once_for_the_same_surfaces(monkeypatch):
    """A frame between the same two surfaces reuses the kept coupling, read-only, with the
    same answer; a body moved by a round-off of its size is integrated anew."""
    import contact.solver.rows as rows_mod
    from contact.solver.kept import Kept

    calls = []
    real = rows_mod.mortar_coupling
    monkeypatch.setattr(
        rows_mod, "mortar_coupling", lambda *a, **k: calls.append(1) or real(*a, **k)
    )
    monkeypatch.setattr(rows_mod, "_KEPT", Kept(rows_mod.KEEP))
    upper, lower = blocks(1.0)
    first = rows_mod.mortar_candidates(ContactPair(upper, lower, mortar=True), 0, 0.1)
    again = rows_mod.mortar_candidates(ContactPair(upper, lower, mortar=True), 3, 0.1)
    assert len(calls) == 1
    assert (again.rows.pair == 3).all() and (first.rows.pair == 0).all()
    assert np.array_equal(again.rows.g0, first.rows.g0)
    with pytest.raises(ValueError):
        again.rows.g0[0] = 1.0  # shared with later frames: never written
    moved = upper.translated(upper.mesh.points * (1 + 1e-15))
    rows_mod.mortar_candidates(ContactPair(moved, lower, mortar=True), 0, 0.1)
    assert len(calls) == 2
    res = [solve_frame([upper, lower], [ContactPair(upper, lower, mortar=True)], [],
                       ContactSettings()) for _ in range(2)]  # fmt: skip
    assert len(calls) == 3  # the frames' search differs from 0.1: once more, then kept
    assert np.array_equal(res[0].contacts["force"], res[1].contacts["force"])
