import numpy as np
import pytest
import scipy.sparse as sp

import fem
from tests.helpers import distort

skfem = pytest.importorskip("skfem")
from skfem.models.elasticity import lame_parameters, linear_elasticity  # noqa: E402

E, NU = 2.5e6, 0.35


def _skfem_stiffness(mesh: fem.Mesh) -> sp.csr_matrix:
    """scikit-fem's K for the same mesh, permuted into our node-major DOF order."""
    if "tetra" in mesh.cells:
        m = skfem.MeshTet(mesh.points.T, mesh.cells["tetra"].T)
        elem = skfem.ElementVector(skfem.ElementTetP1())
        basis = skfem.Basis(m, elem, intorder=1)
    else:
        # scikit-fem orders hex nodes 000, 001, 010, 100, 011, 101, 110, 111 (xyz)
        t = mesh.cells["hexahedron"][:, [0, 4, 3, 1, 7, 5, 2, 6]]
        m = skfem.MeshHex(mesh.points.T, t.T, sort_t=False)
        elem = skfem.ElementVector(skfem.ElementHex1())
        basis = skfem.Basis(m, elem, intorder=3)  # 2x2x2 Gauss
    k = skfem.asm(linear_elasticity(*lame_parameters(E, NU)), basis).tocsr()
    perm = basis.nodal_dofs.T.ravel()  # our dof 3n+c -> skfem dof
    return k[perm][:, perm]


@pytest.mark.parametrize("element", ["tetra", "hexahedron"])
def test_stiffness_equals_scikit_fem(element):
    mesh = distort(fem.box_mesh((1.0, 0.7, 1.3), (3, 4, 3), element=element), 0.2, seed=7)
    k = fem.assemble_stiffness(mesh, fem.LinearElastic(E, NU), bbar=False)
    ref = _skfem_stiffness(mesh)
    err = sp.linalg.norm(k - ref) / sp.linalg.norm(ref)
    assert err < 1e-12


def test_symmetric_and_rigid_modes_in_null_space(any_mesh):
    k = fem.assemble_stiffness(
        any_mesh, {0: fem.LinearElastic(E, NU), 1: fem.LinearElastic(3 * E, 0.2)}
    )
    assert sp.linalg.norm(k - k.T) <= 1e-13 * sp.linalg.norm(k)
    phi = fem.rigid_body_modes(any_mesh.points)
    assert np.allclose(phi.T @ phi, np.eye(6), atol=1e-12)
    assert np.linalg.norm(k @ phi) <= 1e-10 * sp.linalg.norm(k)


def test_six_zero_eigenvalues(any_mesh):
    k = fem.assemble_stiffness(any_mesh, fem.LinearElastic(E, NU)).toarray()
    ev = np.linalg.eigvalsh(k)
    assert np.abs(ev[:6]).max() <= 1e-10 * ev[-1]
    assert ev[6] > 1e-4 * ev[-1]


def test_region_materials_scale_stiffness():
    mesh = fem.box_mesh((1, 1, 1), (2, 2, 2))
    k1 = fem.assemble_stiffness(mesh, fem.LinearElastic(1.0, 0.3))
    k5 = fem.assemble_stiffness(mesh, {0: fem.LinearElastic(5.0, 0.3)})
    assert sp.linalg.norm(k5 - 5 * k1) <= 1e-14 * sp.linalg.norm(k5)


def test_missing_region_material_is_named():
    mesh = fem.box_mesh((1, 1, 1), (2, 2, 2))
    mesh = fem.Mesh(mesh.points, mesh.cells, {"hexahedron": np.arange(8) % 3})
    with pytest.raises(fem.MaterialError, match="region 2 has no material"):
        fem.assemble_stiffness(mesh, {0: fem.LinearElastic(1.0, 0.3), 1: fem.LinearElastic(1, 0.3)})


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"E": -1.0, "nu": 0.3}, "E = -1.0: must be positive"),
        ({"E": 1.0, "nu": 0.5}, "nu = 0.5: must be above -1 and below 0.5"),
        ({"E": 1.0, "nu": -1.0}, "nu = -1.0"),
        ({"E": 1.0, "nu": 0.3, "density": -2.0}, "density = -2.0"),
        ({"E": float("nan"), "nu": 0.3}, "must be finite"),
        ({"E": "steel", "nu": 0.3}, "must be a number"),
    ],
)
def test_material_validation(kwargs, match):
    with pytest.raises(fem.MaterialError, match=match):
        fem.LinearElastic(**kwargs)


def test_elasticity_matrix_matches_lame():
    d = fem.elasticity_matrix(1.0, 0.25)
    lam, mu = fem.lame(1.0, 0.25)
    assert d[0, 0] == pytest.approx(lam + 2 * mu)
    assert d[0, 1] == pytest.approx(lam)
    assert d[3, 3] == pytest.approx(mu)
    # uniaxial stress: strain from the compliance gives E and nu back
    c = np.linalg.inv(d)
    assert 1 / c[0, 0] == pytest.approx(1.0)
    assert -c[1, 0] / c[0, 0] == pytest.approx(0.25)


def test_bad_region_material_names_region_and_value():
    mesh = fem.box_mesh((1, 1, 1), (2, 2, 2))
    mesh = fem.Mesh(mesh.points, mesh.cells, {"hexahedron": np.arange(8) % 2})
    with pytest.raises(fem.MaterialError, match=r"region 1: nu = 0\.7: must be above -1"):
        fem.assemble_stiffness(mesh, {0: {"E": 1e6, "nu": 0.3}, 1: {"E": 1e6, "nu": 0.7}})
    with pytest.raises(fem.MaterialError, match=r"region 0: .*unexpected keyword argument .G."):
        fem.assemble_stiffness(mesh, {0: {"E": 1e6, "G": 0.3}, 1: {"E": 1e6, "nu": 0.3}})
    k = fem.assemble_stiffness(mesh, {0: {"E": 1e6, "nu": 0.3}, 1: fem.LinearElastic(1e6, 0.3)})
    assert k.shape == (81, 81)
