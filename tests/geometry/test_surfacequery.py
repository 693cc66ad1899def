"""Closest points, weights, normals and inside tests of contact.geometry.surfacequery."""

from __future__ import annotations

import numpy as np
import pytest

import fem
from contact.geometry.surfacequery import (
    Closest,
    SurfaceError,
    TriangleSurface,
    closest_on_triangles,
    surface_of_mesh,
)

CUBE_POINTS = np.array(
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
    dtype=float,
)
#: The unit cube's 12 triangles, counter-clockwise seen from outside.
CUBE_TRIANGLES = np.array(
    [
        [0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
        [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7],
    ]
)  # fmt: skip


def _sphere(refinement: int = 3) -> TriangleSurface:
    pts, tri = fem.sphere_surface(1.0, refinement=refinement)
    return TriangleSurface(pts, tri, name="sphere")


def _segment_closest(x, a, b):
    d = b - a
    t = np.clip(np.einsum("ij,ij->i", x - a, d) / np.einsum("ij,ij->i", d, d), 0.0, 1.0)
    return a + t[:, None] * d


def _reference_closest(x, a, b, c):
    """Independent closest point on triangles: the plane's foot if it falls inside the
    triangle, else the nearest of the three edges' closest points."""
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1)[:, None]
    foot = x - np.einsum("ij,ij->i", x - a, n)[:, None] * n
    inside = np.ones(len(x), bool)
    for p, q in ((a, b), (b, c), (c, a)):
        inside &= np.einsum("ij,ij->i", np.cross(q - p, foot - p), n) >= 0
    cands = [_segment_closest(x, a, b), _segment_closest(x, b, c), _segment_closest(x, c, a)]
    dist = np.stack([np.linalg.norm(x - p, axis=1) for p in cands])
    best = np.stack(cands)[dist.argmin(axis=0), np.arange(len(x))]
    return np.where(inside[:, None], foot, best)


def _brute_force(surface: TriangleSurface, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance and closest point of each x over every facet, with the reference above."""
    tri = surface.points[surface.triangles]
    k, m = len(x), len(tri)
    xx = np.repeat(x, m, axis=0)
    p = _reference_closest(xx, *(np.tile(tri[:, i], (k, 1)) for i in range(3)))
    d = np.linalg.norm(xx - p, axis=1).reshape(k, m)
    j = d.argmin(axis=1)
    return d[np.arange(k), j], p.reshape(k, m, 3)[np.arange(k), j]


# --- closest points ------------------------------------------------------------------------


def test_closest_on_triangles_matches_an_independent_projection():
    rng = np.random.default_rng(0)
    a, b, c = (rng.normal(size=(5000, 3)) for _ in range(3))
    x = 2.0 * rng.normal(size=(5000, 3))
    w = closest_on_triangles(x, a, b, c)
    p = w[:, :1] * a + w[:, 1:2] * b + w[:, 2:] * c
    ref = _reference_closest(x, a, b, c)
    assert np.abs(p - ref).max() < 1e-12
    assert w.min() >= 0.0
    assert np.abs(w.sum(axis=1) - 1.0).max() < 1e-15
    # every region is exercised: interior, edges and vertices
    zeros = (w == 0).sum(axis=1)
    assert set(np.unique(zeros)) == {0, 1, 2}


def test_closest_matches_brute_force_on_random_points():
    s = _sphere(1)
    rng = np.random.default_rng(1)
    x = rng.normal(size=(1000, 3)) * rng.uniform(0.1, 1.8, (1000, 1))
    c = s.closest(x)
    d, p = _brute_force(s, x)
    assert np.abs(c.distance - d).max() <= 1e-12 * d.max()
    assert np.abs(c.point - p).max() <= 1e-12
    # the facet holds the point; where it is unique (not on an edge) it is the true one
    assert np.allclose(np.linalg.norm(x - c.point, axis=1), c.distance, rtol=0, atol=1e-15)
    assert np.bincount(c.feature, minlength=4)[1:].min() > 50  # vertices, edges, facets


def test_barycentric_weights_reconstruct_the_point():
    s = _sphere(3)
    rng = np.random.default_rng(2)
    x = rng.normal(size=(4000, 3))
    c = s.closest(x)
    rebuilt = np.einsum("ki,kij->kj", c.bary, s.points[s.face_nodes(c.face)])
    assert np.abs(rebuilt - c.point).max() <= 1e-12 * np.abs(c.point).max()
    assert c.bary.min() >= 0.0
    assert np.abs(c.bary.sum(axis=1) - 1.0).max() <= 1e-15
    assert isinstance(c, Closest) and len(c) == 4000


def test_distances_to_a_sphere_within_its_discretisation_error():
    s = _sphere(3)
    # facets lie inside the unit sphere by at most 1 - h (h: least distance of a facet plane)
    h = np.abs(np.einsum("ij,ij->i", s.face_normals, s.points[s.triangles[:, 0]])).min()
    assert 0.99 < h < 1.0
    rng = np.random.default_rng(3)
    u = rng.normal(size=(3000, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    r = rng.uniform(0.3, 2.0, 3000)
    c = s.closest(u * r[:, None])
    err = c.distance - np.abs(r - 1.0)
    assert np.abs(err).max() <= (1.0 - h) + 1e-12
    assert np.abs(err).max() > 0.2 * (1.0 - h)  # the bound is tight, not vacuous
    # normals point out: nearly radial on this smooth surface
    assert np.einsum("ij,ij->i", c.normal, u).min() > 0.97


def test_pseudonormals_tell_inside_exactly_on_a_cube():
    s = TriangleSurface(CUBE_POINTS, CUBE_TRIANGLES, name="cube")
    rng = np.random.default_rng(4)
    x = rng.uniform(-0.5, 1.5, (5000, 3))
    # points whose closest feature is an edge or a corner of the cube
    x[:8] = CUBE_POINTS + 0.1 * np.sign(CUBE_POINTS - 0.5)
    x[8] = [1.2, 1.3, 0.5]
    c = s.closest(x)
    truth = np.all((x > 0) & (x < 1), axis=1)
    assert np.array_equal(c.side(x) < 0, truth)
    assert np.array_equal(c.feature[:8], np.ones(8))
    assert c.feature[8] == 2
    assert np.allclose(c.normal[:8], np.sign(CUBE_POINTS - 0.5) / np.sqrt(3))
    assert np.allclose(c.normal[8], [1 / np.sqrt(2), 1 / np.sqrt(2), 0])
    inner = np.minimum(x, 1 - x).min(axis=1)
    dist_box = np.linalg.norm(np.maximum(np.maximum(-x, x - 1), 0), axis=1)
    expected = np.where(truth, -inner, dist_box)
    assert np.abs(s.signed_distance(x) - expected).max() < 1e-15
    assert np.abs(s.signed_distance(x, sign="pseudonormal") - expected).max() < 1e-15


# --- inside -------------------------------------------------------------------------------


def test_inside_a_cube_near_its_faces_edges_and_corners():
    s = TriangleSurface(CUBE_POINTS, CUBE_TRIANGLES, name="cube")
    g = np.array([-1e-4, 1e-4, 0.3, 0.5, 1 - 1e-4, 1 + 1e-4])
    x = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)
    truth = np.all((x > 0) & (x < 1), axis=1)
    assert truth.sum() == 4**3
    assert np.array_equal(s.inside(x), truth)
    w = s.winding_number(x)
    assert np.abs(w - truth).max() < 0.05


@pytest.fixture(scope="module")
def coarse_skin() -> TriangleSurface:
    from contact import load_hand
    from contact.geometry.surfaces import surface_arrays

    pts, tri = surface_arrays(load_hand("coarse").skin)
    return TriangleSurface(pts, tri, name="coarse skin")


@pytest.mark.parametrize("offset", [1e-4, 1e-6])
def test_inside_the_hand_skin_just_off_every_node(coarse_skin, offset):
    s = coarse_skin
    assert s.is_closed and s.n_faces == 2726
    n = s.vertex_normals
    x_in, x_out = s.points - offset * n, s.points + offset * n
    assert s.inside(x_in).all()
    assert not s.inside(x_out).any()
    assert (s.signed_distance(x_in, sign="pseudonormal") < 0).all()
    assert (s.signed_distance(x_out, sign="pseudonormal") > 0).all()
    d = np.abs(s.signed_distance(np.concatenate([x_in, x_out])))
    # the node itself is offset away; a facet can be nearer, not much nearer on this skin
    assert d.max() <= offset * (1 + 1e-9)
    assert d.min() >= 0.2 * offset


def test_winding_and_pseudonormal_agree_near_the_skin(coarse_skin):
    s = coarse_skin
    rng = np.random.default_rng(5)
    f = rng.integers(s.n_faces, size=4000)
    w = rng.dirichlet(np.ones(3), size=4000)
    x = np.einsum("ki,kij->kj", w, s.points[s.triangles[f]])
    x += rng.uniform(-3e-3, 3e-3, (4000, 1)) * s.face_normals[f]
    inside = s.inside(x)
    assert 1000 < inside.sum() < 3000
    assert np.array_equal(inside, s.closest(x).side(x) < 0)


def test_moved_surface_follows_its_points(coarse_skin):
    s = coarse_skin
    shift = np.array([0.01, -0.02, 0.005])
    m = s.moved(s.points + shift)
    rng = np.random.default_rng(6)
    x = s.points[rng.integers(s.n_points, size=500)] + rng.normal(0, 2e-3, (500, 3))
    a, b = s.closest(x), m.closest(x + shift)
    assert np.abs(a.distance - b.distance).max() < 1e-12
    assert np.abs((a.point + shift) - b.point).max() < 1e-12
    assert np.array_equal(s.inside(x), m.inside(x + shift))
    assert m.triangles is s.triangles
    with pytest.raises(SurfaceError, match="moved\\(\\) needs 1365 points"):
        s.moved(s.points[:-1])


# --- meshes -------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["hex box", "tet ball", "hex ball"])
def test_surface_of_mesh_is_closed_outward_and_holds_the_mesh_volume(kind):
    if kind == "hex box":
        mesh = fem.box_mesh((1.0, 2.0, 0.5), (3, 4, 2))
    elif kind == "tet ball":
        mesh = fem.hex_to_tet(fem.ball_mesh(1.0, 0.4))
    else:
        mesh = fem.ball_mesh(1.0, 0.4)
    nodes, tri = surface_of_mesh(mesh)
    assert np.array_equal(nodes, mesh.boundary.nodes)
    quads = len(mesh.boundary.faces.get("quad", ()))
    assert len(tri) == len(mesh.boundary.faces.get("triangle", ())) + 2 * quads
    s = TriangleSurface(mesh.points, tri, name=kind)  # interior nodes are unused: allowed
    s.check_closed()
    assert s.volume == pytest.approx(mesh.volume, rel=1e-12)
    # a compact copy gives the same surface
    compact = TriangleSurface(mesh.points[nodes], np.searchsorted(nodes, tri))
    assert compact.volume == pytest.approx(s.volume, rel=1e-14)
    # interior nodes are inside, weights act on boundary nodes
    interior = np.setdiff1d(np.arange(mesh.n_points), nodes)
    assert s.inside(mesh.points[interior]).all()
    c = s.closest(mesh.points[interior])
    assert np.isin(s.face_nodes(c.face), nodes).all()


def test_surface_of_a_subset_of_faces():
    mesh = fem.box_mesh((1.0, 1.0, 1.0), (2, 2, 2))
    b = mesh.boundary
    top = {"quad": b.faces["quad"][mesh.face_centroids(b.faces)["quad"][:, 2] > 1 - 1e-9]}
    nodes, tri = surface_of_mesh(mesh, top)
    assert len(nodes) == 9 and len(tri) == 8
    s = TriangleSurface(mesh.points, tri, name="top")
    assert np.allclose(s.face_normals, [0, 0, 1])
    assert not s.is_closed
    with pytest.raises(SurfaceError, match=r"top: .*(open|closed)"):
        s.inside([[0.5, 0.5, 0.5]])


# --- errors -------------------------------------------------------------------------------


def test_bad_surfaces_and_queries_are_named():
    tri = CUBE_TRIANGLES
    bad = CUBE_POINTS.copy()
    bad[3, 1] = np.nan
    with pytest.raises(SurfaceError, match="box: 1 point\\(s\\) have non-finite"):
        TriangleSurface(bad, tri, name="box")
    with pytest.raises(SurfaceError, match=r"box: 1 triangle\(s\) refer to nodes outside 0\.\.7"):
        TriangleSurface(CUBE_POINTS, np.vstack([tri, [0, 1, 8]]), name="box")
    with pytest.raises(SurfaceError, match="box: 1 triangle\\(s\\) repeat a node"):
        TriangleSurface(CUBE_POINTS, np.vstack([tri, [0, 1, 1]]), name="box")
    flat = CUBE_POINTS.copy()
    flat[5] = flat[0] + 0.5 * (flat[1] - flat[0])  # triangle [0, 1, 5] collapses to a segment
    with pytest.raises(SurfaceError, match=r"box: .*degenerate triangle"):
        TriangleSurface(flat, tri, name="box")
    with pytest.raises(SurfaceError, match="box: triangles must be integers"):
        TriangleSurface(CUBE_POINTS, tri.astype(float), name="box")
    s = TriangleSurface(CUBE_POINTS, tri, name="box")
    with pytest.raises(SurfaceError, match="box: 1 query point\\(s\\) are not finite"):
        s.closest([[0.5, 0.5, np.inf], [0, 0, 0]])
    with pytest.raises(SurfaceError, match="box: query points must have shape"):
        s.inside(np.zeros((4, 2)))
    inward = TriangleSurface(CUBE_POINTS, tri[:, ::-1], name="box")
    with pytest.raises(SurfaceError, match="box: the triangles face inward"):
        inward.inside([[0.5, 0.5, 0.5]])
    with pytest.raises(SurfaceError, match="box: sign must be"):
        s.signed_distance([[0.5, 0.5, 0.5]], sign="parity")
    assert isinstance(SurfaceError("x"), ValueError)


def test_empty_query():
    s = TriangleSurface(CUBE_POINTS, CUBE_TRIANGLES)
    c = s.closest(np.zeros((0, 3)))
    assert c.point.shape == (0, 3) and c.face.shape == (0,)
    assert s.inside(np.zeros((0, 3))).shape == (0,)


def test_vertex_normals_of_some_nodes_equal_the_whole_surface():
    s = _sphere(2)
    pts, tri = s.points, s.triangles
    nodes = np.array([0, 5, 5, len(pts) - 1])
    got = s.vertex_normals_at(nodes)
    np.testing.assert_allclose(got, TriangleSurface(pts, tri).vertex_normals[nodes], atol=1e-14)
    assert np.linalg.norm(got - pts[nodes] / np.linalg.norm(pts[nodes], axis=1)[:, None]) < 0.1
    moved = s.moved(pts * 2.0)
    np.testing.assert_allclose(moved.vertex_normals_at(nodes), got, atol=1e-14)


def test_topology_of_a_surface_outlives_many_small_ones(monkeypatch):
    """The topology record keeps a big surface while a posing makes a surface of every bone
    (tens of small ones), and drops the least recently used past its triangle budget."""
    import contact.geometry.topology as sq

    monkeypatch.setattr(sq, "_TOPOLOGY", type(sq._TOPOLOGY)())
    big = fem.box_mesh((1.0, 1.0, 1.0), (6, 6, 6), element="tetra")
    pts, tri = big.points, surface_of_mesh(big)[1]
    first = TriangleSurface(pts, tri, name="skin")
    assert first.is_closed
    _ = first._twins
    for k in range(40):  # a posing's bones: small surfaces, all different
        box = fem.box_mesh((1.0, 1.0, 1.0), (1, 1, 1 + k), element="tetra")
        TriangleSurface(box.points, surface_of_mesh(box)[1], name=f"bone {k}")
    again = TriangleSurface(pts + 0.1, tri, name="skin moved")
    assert again._topology is first._topology
    assert {"closed", "twins"} <= set(again._topology)
    monkeypatch.setattr(sq, "_TOPOLOGY_TRIANGLES", len(tri) + 20)
    box = fem.box_mesh((1.0, 2.0, 1.0), (3, 3, 3), element="tetra")
    other = surface_of_mesh(box)[1]
    assert 20 < len(other) < len(tri)
    TriangleSurface(box.points, other, name="another")  # skin + another: over the budget
    assert len(sq._TOPOLOGY) == 1  # the least recently used dropped, the skin too
    assert TriangleSurface(pts, tri, name="skin")._topology is not first._topology


# --- the compiled hierarchy ---------------------------------------------------------------


def test_hierarchy_holds_every_facet_once_in_small_leaves():
    from contact.geometry.closestkernels import LEAF, build_tree

    s = _sphere(3)
    order, child, start, count = build_tree(s.points, s.triangles, LEAF)
    assert np.array_equal(np.sort(order), np.arange(s.n_faces))
    inner = np.flatnonzero(child >= 0)
    assert (child[inner] > inner).all()  # children after their parent: refit leaves up
    # the two children split their parent's run of facets
    assert np.array_equal(start[child[inner]], start[inner])
    assert np.array_equal(count[child[inner]] + count[child[inner] + 1], count[inner])
    leaves = child < 0
    assert count[leaves].max() <= LEAF and count[leaves].sum() == s.n_faces
    assert len(child) < 2 * s.n_faces / LEAF * 2


def test_closest_on_a_deformed_copy_matches_brute_force():
    """The hierarchy is built at the first coordinates of a connectivity; a twisted and
    squashed copy (:meth:`TriangleSurface.moved`) refits its boxes and still finds the
    closest point of every query, near or far."""
    s = _sphere(2)
    p = s.points
    turn = 2.0 * p[:, 2]
    bent = np.column_stack(
        [
            p[:, 0] * np.cos(turn) - p[:, 1] * np.sin(turn),
            p[:, 0] * np.sin(turn) + p[:, 1] * np.cos(turn),
            0.3 * p[:, 2] + 0.2 * p[:, 0] ** 2,
        ]
    )
    s.closest(np.zeros((1, 3)))  # the original has its boxes: the copy must not take them
    m = s.moved(bent)
    assert m._tree is s._tree
    rng = np.random.default_rng(11)
    x = rng.normal(size=(600, 3)) * rng.uniform(0.02, 2.0, (600, 1))
    c = m.closest(x)
    d, q = _brute_force(m, x)
    assert np.abs(c.distance - d).max() <= 1e-12
    assert np.abs(c.point - q).max() <= 1e-9  # the point is unique off the medial axis
    # a patch searches its own hierarchy
    patch = np.arange(0, m.n_faces, 3)
    sub = TriangleSurface(m.points, m.triangles[patch], name="patch")
    cp = m.closest(x, faces=patch)
    assert np.abs(cp.distance - _brute_force(sub, x)[0]).max() <= 1e-12
    assert np.isin(cp.face, patch).all()


def test_ties_at_edges_and_corners_do_not_depend_on_the_facet_order():
    """A point whose closest point is a cube's corner or edge lies at the same distance
    from every facet there: whatever the facets' order, it gets the corner's (edge's)
    exact weights, feature and pseudo-normal; a point equidistant from facets of
    different planes (the centre) gets the lowest-numbered one."""
    x = np.array([[1.5, 1.5, 1.5], [1.3, 0.5, 1.2], [-0.2, 0.25, -0.4], [0.5, 0.5, 0.5]])
    rng = np.random.default_rng(3)
    answers = []
    for trial in range(6):
        perm = rng.permutation(12) if trial else np.arange(12)
        roll = rng.integers(3, size=12) if trial else np.zeros(12, int)
        tri = np.array([np.roll(t, r) for t, r in zip(CUBE_TRIANGLES[perm], roll)])
        s = TriangleSurface(CUBE_POINTS, tri, name="cube")
        c = s.closest(x)
        answers.append((c.point[:3], c.feature[:3], c.normal[:3]))
        assert c.face[3] == 0  # the centre: every facet at 0.5
    for point, feature, normal in answers:
        np.testing.assert_array_equal(feature, [1, 2, 2])
        np.testing.assert_allclose(point, [[1, 1, 1], [1, 0.5, 1], [0, 0.25, 0]], atol=1e-15)
        np.testing.assert_allclose(normal, answers[0][2], atol=1e-15)
    np.testing.assert_allclose(answers[0][2][0], np.full(3, 1 / np.sqrt(3)), atol=1e-15)


def test_facet_cross_products_and_degenerate_facets():
    """The compiled doubled-area vectors equal numpy's cross products; a repeated corner
    and a sliver are degenerate; triangles off the points are refused, not read."""
    from contact.geometry.surfacequery import degenerate_triangles

    rng = np.random.default_rng(8)
    x = rng.normal(size=(50, 3))
    tri = np.array([rng.choice(50, 3, replace=False) for _ in range(200)])
    tri[:3, 1] = tri[:3, 0]  # a repeated node: zero area
    x[49] = 0.5 * (x[47] + x[48]) + 1e-14  # a sliver of three nearly aligned nodes
    tri[3] = [47, 48, 49]
    cross, dbl, bad = degenerate_triangles(x, tri)
    ref = np.cross(x[tri[:, 1]] - x[tri[:, 0]], x[tri[:, 2]] - x[tri[:, 0]])
    np.testing.assert_allclose(cross, ref, rtol=0, atol=1e-15)
    np.testing.assert_allclose(dbl, np.linalg.norm(ref, axis=1), rtol=1e-15, atol=1e-15)
    y = x[tri]
    edge2 = np.max([((y[:, i] - y[:, (i + 1) % 3]) ** 2).sum(axis=1) for i in range(3)], 0)
    np.testing.assert_array_equal(bad, np.linalg.norm(ref, axis=1) <= 1e-12 * edge2)
    assert bad[:4].all() and bad.sum() == 4
    with pytest.raises(SurfaceError, match=r"outside 0\.\.49"):
        degenerate_triangles(x, np.array([[0, 1, 50]]))


def test_compiled_weights_equal_the_numpy_region_test():
    """The hierarchy's closest-point weights are Ericson's region test as
    :func:`closest_on_triangles` computes it: the same regions (exact zeros) and weights."""
    from contact.geometry.closestkernels import _weights

    rng = np.random.default_rng(12)
    k = 3000
    corners = rng.normal(size=(k, 3, 3))
    x = 2.0 * rng.normal(size=(k, 3))
    ref = closest_on_triangles(x, corners[:, 0], corners[:, 1], corners[:, 2])
    got = np.empty((k, 3))
    d2 = np.empty(k)
    tri = np.array([0, 1, 2])
    for i in range(k):
        w = np.empty(3)
        d2[i] = _weights(x[i], corners[i], tri, w)
        got[i] = w
    np.testing.assert_array_equal(got == 0.0, ref == 0.0)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12)
    point = np.einsum("ki,kij->kj", ref, corners)
    np.testing.assert_allclose(d2, ((x - point) ** 2).sum(axis=1), rtol=1e-10, atol=1e-14)
    assert set(np.unique((ref == 0).sum(axis=1))) == {0, 1, 2}  # facets, edges, vertices


def test_closest_far_from_the_origin_and_on_elongated_facets():
    """A surface 1 km from the origin (a scene in survey coordinates) and one of long thin
    facets (a stretched mesh from another tool): the same closest points as brute force,
    the ties' rounding band scaled with the coordinates."""
    s = _sphere(2)
    rng = np.random.default_rng(21)
    x = rng.normal(size=(400, 3)) * rng.uniform(0.05, 1.6, (400, 1))
    shift = np.array([1000.0, -2000.0, 500.0])
    far = TriangleSurface(s.points + shift, s.triangles, name="far sphere")
    a, b = s.closest(x), far.closest(x + shift)
    np.testing.assert_allclose(b.distance, a.distance, rtol=0, atol=1e-11)
    np.testing.assert_allclose(b.point - shift, a.point, rtol=0, atol=1e-11)
    np.testing.assert_array_equal(b.feature, a.feature)
    long = TriangleSurface(s.points * [50.0, 1.0, 0.02], s.triangles, name="stretched")
    y = x * [50.0, 1.0, 0.02]
    c = long.closest(y)
    d, p = _brute_force(long, y)
    np.testing.assert_allclose(c.distance, d, rtol=0, atol=1e-12)
    np.testing.assert_allclose(c.point, p, rtol=0, atol=1e-9)
