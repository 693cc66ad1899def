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
