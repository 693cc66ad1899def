"""Measuring a pair's gaps with a survey and a patch search gives the full search's answer."""

import numpy as np
import pytest

import fem
from contact.geometry.surfacequery import SurfaceError, TriangleSurface
from contact.solver.body import ElasticBody
from contact.solver.pairs import ContactPair, Penetrations, measure

R = 0.02


def bodies():
    """A coarse ball above a pad: the ball's closed surface is the master of the pad's nodes."""
    ball = ElasticBody(
        "ball",
        fem.ball_mesh(R, divisions=4, layers=2, center=(0, 0, R)),
        fem.LinearElastic(1e6, 0.3),
    )
    pad_mesh = fem.box_mesh((3 * R, 3 * R, R), (8, 8, 2), (-1.5 * R, -1.5 * R, -R))
    bottom = np.flatnonzero(np.isclose(pad_mesh.points[:, 2], -R))
    pad = ElasticBody(
        "pad", pad_mesh, fem.LinearElastic(1e5, 0.3), prescribed=fem.node_dofs(bottom)
    )
    return ball, pad


def displacements(ball, pad, k, rng):
    """The ball sinks into the pad, both bodies wobble a little."""
    ub = np.zeros((ball.mesh.n_points, 3))
    ub[:, 2] = -0.12 * R * k
    ub[:, 0] = 0.02 * R * np.sin(k)
    ub += 0.01 * R * rng.standard_normal(ub.shape)
    up = 0.01 * R * rng.standard_normal((pad.mesh.n_points, 3))
    return {"ball": ub, "pad": up}


def same(a, b, u, master):
    assert np.array_equal(a.nodes, b.nodes)
    assert np.allclose(a.gap, b.gap, rtol=0, atol=1e-15)
    assert np.allclose(a.normal, b.normal, rtol=0, atol=1e-12)
    # on an edge or at a vertex either facet may be named: the point is the same
    x = master.mesh.points + u[master.name]
    pa = np.einsum("mk,mkj->mj", a.weights, x[a.facet])
    pb = np.einsum("mk,mkj->mj", b.weights, x[b.facet])
    assert np.allclose(pa, pb, rtol=0, atol=1e-15)


def reference(pair, u, margin):
    """Every candidate searched on the whole master, inside told by the winding number."""
    slave, master = pair.slave, pair.master
    nodes = pair.candidates
    x = slave.mesh.points[nodes] + u[slave.name][nodes]
    surface = master.contact_surface.moved(master.mesh.points + u[master.name])
    c = surface.closest(x)
    gap = np.where(surface.winding_number(x) > 0.5, -c.distance, c.distance)
    near = gap < margin
    return Penetrations(
        nodes[near], gap[near], surface.triangles[c.face[near]], c.bary[near], c.normal[near]
    )


def test_survey_skips_far_nodes_and_changes_nothing():
    ball, pad = bodies()
    pair = ContactPair(pad, ball)
    assert ball.contact_closed
    rng = np.random.default_rng(3)
    margin = 0.25 * R
    survey = None
    asked = []
    for k in range(8):
        u = displacements(ball, pad, k, rng)
        p, survey = measure(pair, u, margin, survey)
        same(p, reference(pair, u, margin), u, ball)
        asked.append(int((survey.clear <= margin).sum()))
    inside = [
        int((measure(pair, displacements(ball, pad, k, rng), margin)[0].gap < 0).sum())
        for k in range(8)
    ]
    assert max(inside) > 10  # the ball sank in: a real test of the inside side
    # the survey's bounds left most of the pad's surface out of the searches
    assert survey.clear.size == pair.candidates.size
    assert max(asked) < 0.5 * pair.candidates.size


def test_open_master_and_plane_have_no_survey():
    ball, pad = bodies()
    u = {"ball": np.zeros((ball.mesh.n_points, 3)), "pad": np.zeros((pad.mesh.n_points, 3))}
    assert not pad.contact_closed
    _, survey = measure(ContactPair(ball, pad), u, 0.1 * R)
    assert survey is None


@pytest.fixture(scope="module")
def skin() -> TriangleSurface:
    from contact import load_hand
    from contact.geometry.surfaces import surface_arrays

    pts, tri = surface_arrays(load_hand("coarse").skin)
    return TriangleSurface(pts, tri, name="coarse skin")


def test_patch_search_equals_the_whole_surface_near_the_patch(skin):
    rng = np.random.default_rng(7)
    centre = skin.points[skin.triangles].mean(axis=1)
    local = np.flatnonzero(np.linalg.norm(centre - centre[0], axis=1) < 0.02)
    f = rng.choice(local, size=300)
    w = rng.dirichlet(np.ones(3), size=300)
    x = np.einsum("ki,kij->kj", w, skin.points[skin.triangles[f]])
    x += rng.uniform(-2e-3, 2e-3, (300, 1)) * skin.face_normals[f]
    # the patch: every triangle meeting the points' box grown by 3 mm holds the closest
    # point of every point within 3 mm of the skin
    lo, hi = x.min(axis=0) - 3e-3, x.max(axis=0) + 3e-3
    t = skin.points[skin.triangles]
    patch = np.flatnonzero(np.all((t.max(axis=1) >= lo) & (t.min(axis=1) <= hi), axis=1))
    assert 100 < patch.size < 0.5 * skin.n_faces
    c, full = skin.closest(x, faces=patch), skin.closest(x)
    assert full.distance.max() < 3e-3
    assert np.allclose(c.distance, full.distance, rtol=0, atol=1e-15)
    assert np.allclose(c.normal, full.normal, rtol=0, atol=1e-12)
    assert np.array_equal(c.side(x) < 0, full.side(x) < 0)
    assert np.isin(c.face, patch).all()
    with pytest.raises(SurfaceError, match="coarse skin: faces must list triangles"):
        skin.closest(x, faces=[skin.n_faces])
    with pytest.raises(SurfaceError, match="coarse skin: faces must list triangles"):
        skin.closest(x, faces=[])
