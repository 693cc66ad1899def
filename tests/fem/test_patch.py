"""Patch tests: a linear displacement imposed on the boundary is reproduced inside."""

import numpy as np
import pytest

import fem
from tests.helpers import distort

A = np.array([[1.0, 0.3, -0.2], [0.1, -0.5, 0.4], [0.25, 0.05, 0.7]]) * 1e-3
C = np.array([1e-4, -2e-4, 3e-4])


def _linear(points):
    return points @ A.T + C


def test_displacement_patch_test(any_mesh):
    mat = {0: fem.LinearElastic(2e6, 0.3), 1: fem.LinearElastic(2e6, 0.3)}
    k = fem.assemble_stiffness(any_mesh, mat)
    bnd = any_mesh.boundary.nodes
    exact = _linear(any_mesh.points).ravel()
    dofs = fem.node_dofs(bnd)
    sol = fem.StaticSolver(k, dofs).solve(values=exact[dofs])
    interior = np.setdiff1d(np.arange(any_mesh.n_points), bnd)
    assert interior.size > 0
    err = np.abs(sol.u - exact).max() / np.abs(exact).max()
    assert err < 1e-10
    eps = 0.5 * (A + A.T)
    lam, mu = fem.lame(2e6, 0.3)
    sigma = lam * np.trace(eps) * np.eye(3) + 2 * mu * eps
    for s in fem.cell_stress(any_mesh, mat, sol.u, at="gauss").values():
        assert np.abs(s - sigma).max() < 1e-10 * np.abs(sigma).max()
    vm = fem.von_mises(sigma)
    nodal = fem.nodal_average(
        any_mesh, {k: fem.von_mises(s) for k, s in fem.cell_stress(any_mesh, mat, sol.u).items()}
    )
    assert np.allclose(nodal, vm, rtol=1e-10)


@pytest.mark.parametrize("element", ["tetra", "hexahedron", "wedge"])
def test_traction_patch_test_uniaxial(element):
    """Uniform traction on x = 1 with a statically determinate support: uniform stress."""
    mat = fem.LinearElastic(2e6, 0.3)
    mesh = fem.box_mesh((1.0, 1.0, 1.0), (2, 3, 2), element=element)
    pts = mesh.points
    k = fem.assemble_stiffness(mesh, mat)
    right = {
        kind: np.isclose(pts[f][:, :, 0], 1.0).all(axis=1)
        for kind, f in mesh.boundary.faces.items()
    }
    f = fem.pressure_load(mesh, mesh.boundary.subset(right), -1e3)  # 1 kPa tension
    assert f.reshape(-1, 3).sum(axis=0) == pytest.approx([1e3, 0.0, 0.0], abs=1e-9)
    x0 = np.flatnonzero(np.isclose(pts[:, 0], 0.0))
    origin = np.flatnonzero(np.isclose(pts, 0.0).all(axis=1))[0]
    top = np.flatnonzero(np.isclose(pts, [0.0, 0.0, 1.0]).all(axis=1))[0]
    fixed = [*fem.node_dofs(x0, [0]), 3 * origin + 1, 3 * origin + 2, 3 * top + 1]
    sol = fem.StaticSolver(k, fixed).solve(f)
    expected = np.zeros((3, 3))
    expected[0, 0] = 1e3
    for s in fem.cell_stress(mesh, mat, sol.u).values():
        assert np.abs(s - expected).max() < 1e-9 * 1e3
    resultant = sol.reactions.reshape(-1, 3).sum(axis=0) + f.reshape(-1, 3).sum(axis=0)
    assert np.abs(resultant).max() < 1e-9


@pytest.mark.parametrize("element", ["tetra", "hexahedron", "wedge"])
def test_patch_on_strongly_distorted_single_type(element):
    mesh = distort(fem.box_mesh((2.0, 1.0, 1.0), (4, 3, 3), element=element), 0.3, seed=11)
    k = fem.assemble_stiffness(mesh, fem.LinearElastic(1.0, 0.45))
    bnd = fem.node_dofs(mesh.boundary.nodes)
    exact = _linear(mesh.points).ravel()
    sol = fem.StaticSolver(k, bnd, backend="superlu").solve(values=exact[bnd])
    assert np.abs(sol.u - exact).max() < 1e-10 * np.abs(exact).max()
