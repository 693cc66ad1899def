"""A follower pressure: its forces on the deformed faces and their stiffness."""

import numpy as np
import pytest

import fem
from fem.follower import follower_pressure


def _box():
    return fem.box_mesh((1.0, 2.0, 1.5), (2, 2, 2))


@pytest.mark.parametrize("kind", ["hexahedron", "tetra"])
def test_the_stiffness_is_the_forces_derivative(kind):
    mesh = _box() if kind == "hexahedron" else fem.hex_to_tet(_box())
    faces = mesh.boundary.faces
    top = {k: f[np.isclose(mesh.points[f][..., 2], 1.5).all(axis=1)] for k, f in faces.items()}
    rng = np.random.default_rng(0)
    u = 0.1 * rng.standard_normal(mesh.n_dofs)
    du = 1e-7 * rng.standard_normal(mesh.n_dofs)
    for part, closed in ((top, False), (faces, True)):
        _, k = follower_pressure(mesh, part, 3.0, u, closed=closed)
        fp, _ = follower_pressure(mesh, part, 3.0, u + du)
        fm, _ = follower_pressure(mesh, part, 3.0, u - du)
        # K = -df/du
        assert np.allclose(-(fp - fm) / 2, k @ du, rtol=0, atol=1e-7 * np.abs(k @ du).max())
        if closed:
            assert abs(k - k.T).max() <= 1e-12 * abs(k).max()


def test_a_pressure_on_a_closed_surface_is_in_balance_at_any_placement():
    mesh = fem.hex_to_tet(_box())
    rng = np.random.default_rng(1)
    u = 0.2 * rng.standard_normal((mesh.n_points, 3))
    f, _ = follower_pressure(mesh, mesh.boundary, 5.0, u)
    x = mesh.points + u
    forces = f.reshape(-1, 3)
    assert np.abs(forces.sum(axis=0)).max() <= 1e-12 * np.abs(forces).max()
    assert np.abs(np.cross(x, forces).sum(axis=0)).max() <= 1e-12 * np.abs(forces).max()


def test_at_rest_it_is_the_reference_pressure_load():
    mesh = _box()
    f, _ = follower_pressure(mesh, mesh.boundary, 2.0, np.zeros(mesh.n_dofs))
    assert np.allclose(f, fem.pressure_load(mesh, mesh.boundary, 2.0), rtol=1e-14, atol=1e-14)
