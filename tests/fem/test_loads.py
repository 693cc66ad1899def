import numpy as np
import pytest

import fem
from tests.helpers import distort


def test_gravity_total_is_weight(any_mesh):
    mats = {0: fem.LinearElastic(1e6, 0.3, 1000.0), 1: fem.LinearElastic(1e6, 0.3, 3000.0)}
    f = fem.gravity_load(any_mesh, mats, (0.0, -9.0, 0.0)).reshape(-1, 3)
    mass = sum(
        (np.where(any_mesh.regions[k] == 0, 1000.0, 3000.0) * v).sum()
        for k, v in any_mesh.volumes.items()
    )
    assert f.sum(axis=0) == pytest.approx([0.0, -9.0 * mass, 0.0], rel=1e-12, abs=1e-9)


def test_gravity_is_consistent_on_a_brick():
    """One cube: each of the 8 nodes carries 1/8 of the weight."""
    m = fem.box_mesh((2.0, 2.0, 2.0), (1, 1, 1))
    f = fem.gravity_load(m, fem.LinearElastic(1.0, 0.3, 10.0), (0, 0, -1)).reshape(-1, 3)
    assert np.allclose(f[:, 2], -10.0)


def test_pressure_on_closed_surface_balances(any_mesh):
    f = fem.pressure_load(any_mesh, any_mesh.boundary, 2.5e4)
    fem.check_balance(f, any_mesh.points, rtol=1e-12)
    assert np.abs(f).max() > 0


def test_pressure_resultant_on_a_face():
    m = distort(fem.box_mesh((2.0, 3.0, 1.0), (2, 3, 2)), 0.1, boundary=False)
    top = {
        k: np.isclose(m.points[f][:, :, 2], 1.0).all(axis=1) for k, f in m.boundary.faces.items()
    }
    f = fem.pressure_load(m, m.boundary.subset(top), 100.0).reshape(-1, 3)
    assert f.sum(axis=0) == pytest.approx([0.0, 0.0, -600.0], abs=1e-9)


def test_internal_pressure_of_a_shell_is_outward_and_balanced():
    shell = fem.shell_mesh(0.8, 1.0, divisions=3, layers=1)
    inner = {
        k: np.linalg.norm(shell.points[f].mean(axis=1), axis=1) < 0.9
        for k, f in shell.boundary.faces.items()
    }
    f = fem.pressure_load(shell, shell.boundary.subset(inner), 1e3).reshape(-1, 3)
    fem.check_balance(f.ravel(), shell.points, rtol=1e-12)
    loaded = np.abs(f).sum(axis=1) > 0
    radial = np.einsum("ij,ij->i", f[loaded], shell.points[loaded])
    assert (radial > 0).all()  # pushes the wall outward
    # each half feels p times the projected area of the (faceted) inner surface
    assert f[shell.points[:, 2] > 1e-9, 2].sum() > 0


def test_point_load_errors():
    with pytest.raises(fem.LoadError, match="node 9"):
        fem.point_load(4, [9], [1.0, 0.0, 0.0])
    with pytest.raises(fem.LoadError, match=r"shape \(2, 3\)"):
        fem.point_load(4, [0, 1], np.ones((3, 3)))
    f = fem.point_load(4, [1, 1], [0.0, 2.0, 0.0])
    assert f[4] == 4.0


def test_pressure_errors():
    m = fem.box_mesh((1, 1, 1), (1, 1, 1))
    with pytest.raises(fem.LoadError, match="'polygon'"):
        fem.pressure_load(m, {"polygon": [[0, 1, 2]]}, 1.0)
    with pytest.raises(fem.LoadError, match=r"shape \(F, 4\)"):
        fem.pressure_load(m, {"quad": [[0, 1, 2]]}, 1.0)
    with pytest.raises(fem.LoadError, match="outside"):
        fem.pressure_load(m, {"quad": [[0, 1, 2, 99]]}, 1.0)


def test_initial_stress_relaxes_a_free_body(any_mesh):
    """A free body with a uniform initial stress relaxes to zero total stress."""
    mat = fem.LinearElastic(1e6, 0.3)
    sigma0 = np.array([1e3, -2e3, 5e2, 3e2, -1e2, 4e2])
    f = fem.initial_stress_load(any_mesh, sigma0)
    fem.check_balance(f, any_mesh.points, rtol=1e-12)
    k = fem.assemble_stiffness(any_mesh, mat)
    sol = fem.StaticSolver(k, points=any_mesh.points).solve(f)
    s0 = fem.loads.voigt_to_tensor(sigma0)
    initial = {kind: np.broadcast_to(s0, (len(c), 3, 3)) for kind, c in any_mesh.cells.items()}
    for s in fem.cell_stress(any_mesh, mat, sol.u, initial).values():
        assert np.abs(s).max() < 1e-9 * np.abs(sigma0).max()


def test_initial_stress_shape_error():
    m = fem.box_mesh((1, 1, 1), (1, 1, 1))
    with pytest.raises(fem.LoadError, match="initial stress for hexahedron"):
        fem.initial_stress_load(m, {"hexahedron": np.zeros((2, 6))})


def _moment(x, f, c):
    return np.cross(x - c, f).sum(axis=0)


@pytest.mark.parametrize("center", [None, (0.3, -0.2, 0.7)])
def test_resultant_load_has_its_force_and_moment(any_mesh, center):
    w = fem.loads.nodal_volumes(any_mesh)
    assert w.sum() == pytest.approx(any_mesh.volume, rel=1e-12)
    c = w @ any_mesh.points / w.sum() if center is None else np.array(center)
    force, moment = np.array([1.5, -2.0, 0.5]), np.array([0.2, 0.1, -0.3])
    f = fem.loads.resultant_load(any_mesh.points, w, force, moment, c)
    scale = np.abs(f).sum()
    assert np.abs(f.sum(axis=0) - force).max() < 1e-12 * scale
    assert np.abs(_moment(any_mesh.points, f, c) - moment).max() < 1e-12 * scale
    # the force alone about the weighted centroid is a body force: nodal volume times F / V
    cw = w @ any_mesh.points / w.sum()
    g = fem.loads.resultant_load(any_mesh.points, w, force, np.zeros(3), cw)
    assert np.allclose(g, np.outer(w, force / w.sum()), rtol=0, atol=1e-15 * scale)


def test_resultant_load_is_invariant_to_node_order():
    rng = np.random.default_rng(0)
    x, w = rng.normal(size=(40, 3)), rng.uniform(0.1, 2.0, 40)
    args = ((1.0, 2.0, 3.0), (-0.5, 0.25, 1.0), (0.1, 0.2, 0.3))
    f = fem.loads.resultant_load(x, w, *args)
    p = rng.permutation(40)
    g = fem.loads.resultant_load(x[p], w[p], *args)
    assert np.abs(g - f[p]).max() < 1e-12 * np.abs(f).max()


def test_resultant_load_matches_gravity_for_a_weight():
    """Weights as masses, a weight's force about the centre of mass: gravity's lumped loads."""
    m = fem.box_mesh((1.0, 2.0, 0.5), (2, 3, 2))
    mass = 800.0 * fem.loads.nodal_volumes(m)
    g = np.array([0.0, 0.0, -9.81])
    cm = mass @ m.points / mass.sum()
    f = fem.loads.resultant_load(m.points, mass, mass.sum() * g, np.zeros(3), cm)
    ref = fem.gravity_load(m, fem.LinearElastic(1e6, 0.3, 800.0), g).reshape(-1, 3)
    assert np.allclose(f, ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())


def test_resultant_load_errors():
    x = np.array([[0.0, 0, 0], [1.0, 0, 0], [2.0, 0, 0]])
    with pytest.raises(fem.LoadError, match="add up to zero"):
        fem.loads.resultant_load(x, np.zeros(3), (1, 0, 0), (0, 0, 0), (0, 0, 0))
    with pytest.raises(fem.LoadError, match="on a line"):
        fem.loads.resultant_load(x, np.ones(3), (0, 0, 0), (0, 0, 1), (0, 0, 0))
    with pytest.raises(fem.LoadError, match="negative"):
        fem.loads.resultant_load(x, [1.0, -1.0, 1.0], (1, 0, 0), (0, 0, 0), (0, 0, 0))
    with pytest.raises(fem.LoadError, match="moment must be 3 finite"):
        fem.loads.resultant_load(x, np.ones(3), (1, 0, 0), (0, np.nan, 0), (0, 0, 0))
    with pytest.raises(fem.LoadError, match=r"points \(n, 3\)"):
        fem.loads.resultant_load(x[:, :2], np.ones(3), (1, 0, 0), (0, 0, 0), (0, 0, 0))
    # nodes on a line still carry a force through their centroid
    f = fem.loads.resultant_load(x, np.ones(3), (0, 0, 3), (0, 0, 0), (1, 0, 0))
    assert np.allclose(f, [[0, 0, 1]] * 3)
