import math

import numpy as np
import pytest

import fem
from fem.elements import ELEMENTS, face_quadrature


def test_reference_elements_partition_of_unity_and_volume():
    for elem in ELEMENTS.values():
        n = elem.shape(elem.points)
        assert np.allclose(n.sum(axis=1), 1.0, atol=1e-14)
        assert np.allclose(elem.grad(elem.points).sum(axis=1), 0.0, atol=1e-14)
    assert ELEMENTS["tetra"].weights.sum() == pytest.approx(1 / 6)
    assert ELEMENTS["hexahedron"].weights.sum() == pytest.approx(8.0)
    assert ELEMENTS["wedge"].weights.sum() == pytest.approx(1.0)


def test_shape_gradients_match_finite_differences():
    rng = np.random.default_rng(1)
    for elem in ELEMENTS.values():
        xi = rng.uniform(0.1, 0.3, (4, 3))
        g = elem.grad(xi)
        for d in range(3):
            dx = np.zeros(3)
            dx[d] = 1e-6
            fd = (elem.shape(xi + dx) - elem.shape(xi - dx)) / 2e-6
            assert np.allclose(fd, g[:, :, d], atol=1e-9)


def test_face_quadrature_integrates_area():
    for k, area in ((3, 0.5), (4, 4.0)):
        for degree in (2, 5):
            n, _, w = face_quadrature(k, degree)
            assert w.sum() == pytest.approx(area)
            assert np.allclose(n.sum(axis=1), 1.0)


@pytest.mark.parametrize("degree", [2, 5])
def test_face_quadrature_is_exact_to_its_degree(degree):
    # the triangle (0,0), (1,0), (0,1): int x^i y^j = i! j! / (i + j + 2)!
    n, _, w = face_quadrature(3, degree)
    xi, eta = n[:, 1], n[:, 2]
    for i in range(degree + 1):
        for j in range(degree + 1 - i):
            exact = math.factorial(i) * math.factorial(j) / math.factorial(i + j + 2)
            assert w @ (xi**i * eta**j) == pytest.approx(exact, rel=1e-13)
    # [-1, 1]^2: the nodes are the corners; x = sum N_k c_k
    n, _, w = face_quadrature(4, degree)
    c = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=float)
    x, y = (n @ c).T
    top = 3 if degree == 2 else 5
    for i in range(top + 1):
        for j in range(top + 1):
            exact = (1 + (-1) ** i) / (i + 1) * (1 + (-1) ** j) / (j + 1)
            assert w @ (x**i * y**j) == pytest.approx(exact, abs=1e-13)
    with pytest.raises(ValueError, match="degree"):
        face_quadrature(3, 6)


@pytest.mark.parametrize("element", ["tetra", "hexahedron", "wedge"])
def test_box_volume_and_boundary(element):
    m = fem.box_mesh((1.0, 2.0, 3.0), (2, 3, 4), element=element)
    assert m.volume == pytest.approx(6.0, rel=1e-13)
    for v in m.volumes.values():
        assert (v > 0).all()
    # outward orientation: sum of n dA vanishes and int x.n dA = 3 V (divergence theorem)
    total = np.zeros(3)
    flux = 0.0
    for kind, faces in m.boundary.faces.items():
        x = m.points[faces]
        if kind == "triangle":
            nda = 0.5 * np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
        else:
            nda = 0.5 * np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 1])
        total += nda.sum(axis=0)
        flux += np.einsum("fi,fi->", x.mean(axis=1), nda)
    assert np.allclose(total, 0.0, atol=1e-12)
    assert flux == pytest.approx(3 * 6.0, rel=1e-12)


def test_boundary_counts_and_owners():
    m = fem.box_mesh((1, 1, 1), (2, 3, 4))
    assert m.boundary.faces["quad"].shape == (2 * (6 + 12 + 8), 4)
    flat = np.concatenate(list(m.cells.values()))
    for faces, owners in zip(m.boundary.faces.values(), m.boundary.owners.values()):
        for f, o in zip(faces, owners):
            assert set(f) <= set(flat[o])
    assert m.boundary.nodes.size == 3 * 4 * 5 - 1 * 2 * 3


def test_boundary_is_closed(any_mesh):
    # every edge of the boundary surface is shared by exactly two boundary faces
    edges = []
    for f in any_mesh.boundary.faces.values():
        k = f.shape[1]
        edges += [np.sort(f[:, [i, (i + 1) % k]], axis=1) for i in range(k)]
    _, counts = np.unique(np.concatenate(edges), axis=0, return_counts=True)
    assert (counts == 2).all()


def test_errors_name_the_culprit():
    pts = np.eye(4, 3, k=-1)
    with pytest.raises(fem.MeshError, match=r"shape \(N, 3\)"):
        fem.Mesh(pts[:, :2], {"tetra": [[0, 1, 2, 3]]})
    bad = pts.copy()
    bad[2, 1] = np.nan
    with pytest.raises(fem.MeshError, match="point 2"):
        fem.Mesh(bad, {"tetra": [[0, 1, 2, 3]]})
    with pytest.raises(fem.MeshError, match="element 0 refers to node"):
        fem.Mesh(pts, {"tetra": [[0, 1, 2, 4]]})
    with pytest.raises(fem.MeshError, match="unsupported cell type 'pyramid'"):
        fem.Mesh(pts, {"pyramid": [[0, 1, 2, 3, 3]]})
    with pytest.raises(fem.MeshError, match=r"shape \(M, 4\)"):
        fem.Mesh(pts, {"tetra": [[0, 1, 2]]})
    with pytest.raises(fem.MeshError, match="repeats a node"):
        fem.Mesh(pts, {"tetra": [[0, 1, 1, 3]]})
    with pytest.raises(fem.MeshError, match="integers"):
        fem.Mesh(pts, {"tetra": [[0.0, 1.0, 2.0, 3.0]]})
    with pytest.raises(fem.MeshError, match="regions"):
        fem.Mesh(pts, {"tetra": [[0, 1, 2, 3]]}, {"tetra": [0, 1]})
    with pytest.raises(fem.MeshError, match="no cells"):
        fem.Mesh(pts, {"tetra": np.zeros((0, 4), int)})


def test_inverted_tet_is_named_with_its_volume():
    m = fem.box_mesh((1, 1, 1), (2, 2, 2), element="tetra")
    cells = m.cells["tetra"].copy()
    cells[7, [1, 2]] = cells[7, [2, 1]]
    with pytest.raises(fem.MeshError, match=r"tetra element 7 is inverted: volume -0\.0208333"):
        fem.Mesh(m.points, {"tetra": cells})


def test_inverted_and_degenerate_hex():
    m = fem.box_mesh((1, 1, 1), (2, 2, 2))
    cells = m.cells["hexahedron"].copy()
    cells[5] = cells[5][[4, 5, 6, 7, 0, 1, 2, 3]]
    with pytest.raises(fem.MeshError, match=r"hexahedron element 5 is inverted: volume -0\.125"):
        fem.Mesh(m.points, {"hexahedron": cells})
    pts = m.points.copy()
    flat = m.cells["hexahedron"][3]
    pts[flat[4:]] = pts[flat[:4]]  # top face on the bottom: zero volume
    with pytest.raises(fem.MeshError, match=r"hexahedron element 3 is (degenerate|inverted)"):
        fem.Mesh(pts, m.cells)


def test_inverted_wedge():
    m = fem.box_mesh((1, 1, 1), (1, 1, 1), element="wedge")
    cells = m.cells["wedge"].copy()
    cells[1] = cells[1][[0, 2, 1, 3, 5, 4]]
    with pytest.raises(fem.MeshError, match="wedge element 1 is inverted"):
        fem.Mesh(m.points, {"wedge": cells})


def test_remove_unused_points():
    pts = np.vstack([np.eye(4, 3, k=-1), [[5.0, 5.0, 5.0]]])
    m = fem.Mesh(pts, {"tetra": [[0, 1, 2, 3]]})
    assert not m.used_points.all()
    m2 = m.remove_unused_points()
    assert m2.n_points == 4 and m2.volume == pytest.approx(1 / 6)


@pytest.mark.parametrize("divisions", [2, 5])
def test_ball_and_shell_generators(divisions):
    ball = fem.ball_mesh(0.03, divisions=divisions, layers=divisions, center=(0.1, 0.0, 0.0))
    r = np.linalg.norm(ball.points - [0.1, 0.0, 0.0], axis=1)
    nodes = ball.boundary.nodes
    assert np.allclose(r[nodes], 0.03, rtol=1e-12)  # the whole boundary is the sphere
    assert ball.boundary.n_faces == 6 * divisions**2
    exact = 4 / 3 * np.pi * 0.03**3
    assert 0.75 * exact < ball.volume < exact
    shell = fem.shell_mesh(0.8, 1.0, divisions=divisions, layers=2)
    r = np.linalg.norm(shell.points, axis=1)
    assert set(np.round(r[shell.boundary.nodes], 12)) == {0.8, 1.0}
    assert shell.boundary.n_faces == 12 * divisions**2
    assert shell.n_points == 3 * (6 * divisions**2 + 2)


def test_ball_volume_converges():
    exact = 4 / 3 * np.pi
    errs = [abs(fem.ball_mesh(1.0, divisions=n, layers=n).volume - exact) for n in (4, 8, 16)]
    assert errs[0] > errs[1] > errs[2]
    assert errs[2] / exact < 0.01


def test_hex_to_tet_conforms():
    shell = fem.shell_mesh(0.5, 1.0, divisions=3, layers=2)
    tets = fem.hex_to_tet(shell)
    assert tets.volume == pytest.approx(shell.volume, rel=1e-12)
    # conforming: the boundary of the tet mesh is exactly the shell's surface, as triangles
    assert tets.boundary.n_faces == 4 * shell.boundary.n_faces


def test_boundary_is_kept_for_a_connectivity_moved_elsewhere():
    m = fem.box_mesh((1.0, 1.0, 1.0), (3, 2, 2), element="tetra")
    moved = fem.Mesh(m.points * 2.0 + 1.0, m.cells)
    assert moved.boundary is m.boundary  # the faces depend on the connectivity alone
    with pytest.raises(ValueError):
        moved.boundary.faces["triangle"][0, 0] = 0  # shared: read-only
    # another connectivity (one tet's nodes numbered from another corner) is not
    other = {"tetra": m.cells["tetra"].copy()}
    other["tetra"][0] = other["tetra"][0, [1, 2, 0, 3]]
    renumbered = fem.Mesh(m.points, other)
    assert renumbered.boundary is not m.boundary
    assert renumbered.boundary.n_faces == m.boundary.n_faces


def test_bounding_box_matches_min_max_and_refuses_no_points():
    x = np.random.default_rng(3).normal(size=(1000, 3))
    lo, hi = fem.bounding_box(x)
    np.testing.assert_array_equal(lo, x.min(axis=0))
    np.testing.assert_array_equal(hi, x.max(axis=0))
    with pytest.raises(ValueError, match="shape"):
        fem.bounding_box(np.zeros((0, 3)))
