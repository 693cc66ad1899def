"""Neo-Hookean finite strain against exact answers: homogeneous compression and shear on
any mesh, a rigid rotation free of stress, the small-strain limit equal to the linear
elements, and the energy, forces and tangent consistent with one another."""

import numpy as np
import pytest

import fem
from fem.hyperelastic import cauchy_stress, finite_strain, neo_hookean
from fem.newton import solve_finite_strain
from tests.helpers import distort, mixed_mesh, uniaxial_stress

E = 1.0e6


def _meshes():
    box = fem.box_mesh((1.0, 1.0, 1.0), (3, 3, 3))
    return {
        "hexahedron": distort(box, 0.15, seed=1, boundary=False),
        "tetra": distort(fem.hex_to_tet(box), 0.15, seed=2, boundary=False),
        "mixed": distort(mixed_mesh(), 0.1, seed=3, boundary=False),
    }


MESHES = _meshes()


@pytest.fixture(params=sorted(MESHES))
def mesh(request):
    return MESHES[request.param]


def _faces(mesh, c, value):
    return np.flatnonzero(np.isclose(mesh.points[:, c], value))


def test_the_law_at_a_point():
    # W, P = dW/dF and A = dP/dF by central differences at a general F
    rng = np.random.default_rng(0)
    f = np.eye(3) + 0.3 * rng.standard_normal((3, 3))
    lam, mu = np.array(2.0), np.array(0.7)
    _, p, a = neo_hookean(f - np.eye(3), lam, mu)
    h = 1e-6
    for k in range(3):
        for m in range(3):
            d = np.zeros((3, 3))
            d[k, m] = h
            wp, pp, _ = neo_hookean(f + d - np.eye(3), lam, mu)
            wm, pm, _ = neo_hookean(f - d - np.eye(3), lam, mu)
            assert (wp - wm) / (2 * h) == pytest.approx(p[k, m], rel=1e-7, abs=1e-9)
            assert np.allclose((pp - pm) / (2 * h), a[:, :, k, m], rtol=1e-6, atol=1e-8)
    j = np.linalg.det(f)
    b = f @ f.T
    sigma = (mu * (b - np.eye(3)) + lam * np.log(j) * np.eye(3)) / j
    assert np.allclose(p @ f.T / j, sigma, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("nu", [0.3, 0.49])
def test_forces_and_tangent_are_the_energys_derivatives(mesh, nu):
    mat = fem.LinearElastic(E, nu)
    rng = np.random.default_rng(4)
    u = 0.02 * rng.standard_normal(mesh.n_dofs)
    s = finite_strain(mesh, mat, u)
    du = 1e-6 * rng.standard_normal(mesh.n_dofs)
    up = finite_strain(mesh, mat, u + du, stiffness=False)
    um = finite_strain(mesh, mat, u - du, stiffness=False)
    assert (up.energy - um.energy) / 2 == pytest.approx(s.force @ du, rel=1e-7)
    kdu = s.stiffness @ du
    assert np.abs((up.force - um.force) / 2 - kdu).max() <= 1e-7 * np.abs(kdu).max()
    assert abs(s.stiffness - s.stiffness.T).max() <= 1e-12 * abs(s.stiffness).max()


@pytest.mark.parametrize("nu", [0.3, 0.499])
def test_the_small_strain_limit_is_the_linear_model(mesh, nu):
    mat = fem.LinearElastic(E, nu)
    k0 = finite_strain(mesh, mat, np.zeros(mesh.n_dofs)).stiffness
    linear = fem.assemble_stiffness(mesh, mat, nodal_pressure=True)
    assert abs(k0 - linear).max() <= 1e-12 * abs(linear).max()
    # a small pull solved both ways: the same to 1e-6
    x = mesh.points
    k = np.concatenate([3 * _faces(mesh, c, 0.0) + c for c in range(3)])
    top = _faces(mesh, 2, x[:, 2].max())
    loads = np.zeros(mesh.n_dofs)
    loads[3 * top + 2] = 1e-7 * E / top.size
    sol = solve_finite_strain(mesh, mat, prescribed=k, loads=loads)
    lin = fem.StaticSolver(linear, k).solve(loads).u
    assert sol.converged
    assert np.abs(sol.u.ravel() - lin).max() <= 1e-6 * np.abs(lin).max()


def test_a_rigid_rotation_carries_no_stress(mesh):
    mat = fem.LinearElastic(E, 0.45)
    c, s = np.cos(np.radians(90.0)), np.sin(np.radians(90.0))
    about_x = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    turn = about_x @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    u = mesh.points @ turn.T - mesh.points
    state = finite_strain(mesh, mat, u, stiffness=False)
    assert abs(state.energy) <= 1e-12 * E * 1.0
    assert np.abs(state.force).max() <= 1e-12 * E
    for sigma in cauchy_stress(mesh, mat, u).values():
        assert np.abs(sigma).max() <= 1e-12 * E


@pytest.mark.parametrize("nu", [0.3, 0.49])
def test_compression_between_frictionless_plates_to_30_percent_is_exact(mesh, nu):
    mat = fem.LinearElastic(E, nu)
    lam, mu = mat.lame
    stretch = 0.7
    x = mesh.points
    span = x.max(axis=0)
    top = _faces(mesh, 2, span[2])
    k = np.concatenate([3 * _faces(mesh, c, 0.0) + c for c in range(3)] + [3 * top + 2])
    v = np.zeros(k.size)
    v[-top.size :] = (stretch - 1) * span[2]
    order = np.argsort(k)
    sol = solve_finite_strain(mesh, mat, prescribed=k[order], values=v[order], increments=3)
    assert sol.converged and max(sol.steps) <= 8
    side, p33 = uniaxial_stress(lam, mu, stretch)
    exact = x * np.array([side - 1, side - 1, stretch - 1])
    assert np.abs(sol.u - exact).max() <= 1e-10 * span.max()
    force = sol.reactions.reshape(-1, 3)[top, 2].sum()
    assert force == pytest.approx(p33 * span[0] * span[1], rel=1e-10)
    sigma33 = p33 * stretch / (side * side * stretch)
    for sigma in cauchy_stress(mesh, mat, sol.u).values():
        assert np.allclose(sigma[..., 2, 2], sigma33, rtol=1e-9)
        assert np.abs(sigma[..., :2, :2]).max() <= 1e-9 * abs(sigma33)


def test_simple_shear_to_half_is_exact(mesh):
    mat = fem.LinearElastic(E, 0.45)
    mu = mat.lame[1]
    gamma = 0.5
    x = mesh.points
    boundary = mesh.boundary.nodes
    k = (3 * boundary[:, None] + np.arange(3)).ravel()
    exact = np.zeros_like(x)
    exact[:, 0] = gamma * x[:, 2]
    sol = solve_finite_strain(mesh, mat, prescribed=k, values=exact[boundary].ravel(),
                              increments=2)
    assert sol.converged
    assert np.abs(sol.u - exact).max() <= 1e-10
    # J = 1: sigma = mu (b - I), b = F F^T
    f = np.eye(3)
    f[0, 2] = gamma
    want = mu * (f @ f.T - np.eye(3))
    for sigma in cauchy_stress(mesh, mat, sol.u).values():
        assert np.allclose(sigma, want, rtol=0, atol=1e-9 * mu)


def test_an_inverted_cell_is_named():
    mesh = fem.box_mesh((1.0, 1.0, 1.0), (1, 1, 1))
    u = np.zeros((mesh.n_points, 3))
    u[:, 2] = -2.0 * mesh.points[:, 2]  # the box turned inside out through its bottom
    with pytest.raises(fem.MaterialError, match="hexahedron cell 0 is inverted"):
        finite_strain(mesh, fem.LinearElastic(E, 0.3), u)


def test_prescribed_values_follow_their_dofs_in_any_order():
    mesh = fem.box_mesh((1.0, 1.0, 1.0), (1, 1, 1))
    bottom = np.flatnonzero(np.isclose(mesh.points[:, 2], 0.0))
    top = np.flatnonzero(np.isclose(mesh.points[:, 2], 1.0))
    k = np.concatenate([3 * top + 2, (3 * bottom[:, None] + np.arange(3)).ravel()])
    v = np.concatenate([np.full(top.size, -0.1), np.zeros(3 * bottom.size)])
    sol = solve_finite_strain(mesh, fem.LinearElastic(E, 0.3), prescribed=k, values=v)
    assert np.allclose(sol.u[top, 2], -0.1) and np.allclose(sol.u[bottom], 0.0)


def test_the_material_tangent_holds_exactly_the_rigid_modes_of_the_placement(mesh):
    # what a free body's solver needs: positive semidefinite, null on its six rigid modes
    mat = fem.LinearElastic(E, 0.45)
    rng = np.random.default_rng(5)
    x = mesh.points
    u = 0.01 * rng.standard_normal(mesh.n_dofs) + (0.3 * x * [1.0, -0.2, 0.5]).ravel()
    k = finite_strain(mesh, mat, u, tangent="material").stiffness.toarray()
    modes = fem.rigid_body_modes(x + u.reshape(-1, 3))
    assert np.abs(k @ modes).max() <= 1e-14 * np.abs(k).max()
    w = np.linalg.eigvalsh(k)
    assert w[:6].min() >= -1e-14 * w.max() and w[6] > 1e-6 * w.max()
    # the full tangent does not: a stressed body's turn moves its forces
    full = finite_strain(mesh, mat, u).stiffness.toarray()
    assert np.abs(full @ modes).max() > 1e-3 * np.abs(full).max()


def test_log_strain_of_a_stretch_and_a_turn(mesh):
    from fem.hyperelastic import log_strain

    x = mesh.points
    stretch = x * np.array([0.3, -0.2, 0.0])  # stretches 1.3, 0.8, 1
    c, s = np.cos(1.0), np.sin(1.0)
    turn = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    for u in (stretch, (x + stretch) @ turn.T - x):
        for e in log_strain(mesh, u).values():
            assert np.allclose(e, np.log([0.8, 1.0, 1.3]), rtol=0, atol=1e-12)
