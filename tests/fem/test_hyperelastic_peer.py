"""The finite-strain bodies against a peer: scikit-fem's forms with the same discrete energy.

:mod:`fem.hyperelastic` is written again here in scikit-fem's weak forms, on scikit-fem's
own mapping, quadrature and assembly: the neo-Hookean law pointwise with
``lambda - kappa`` in place of ``lambda``, and ``kappa V / 2 (ln v / V)^2`` on each
averaged volume (a brick's own, a node's quarter of its tetrahedra's), whose gradient is
the element constant ``dU/dv`` times ``J F^-T``. On the same mesh the two must give the
same forces and tangent at any displacement, and the same equilibrium of a block held
between two bonded plates, compressed 30 % and sheared: an inhomogeneous finite strain
(barrelling, bent sides) that no closed form gives.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

import fem
from fem.newton import solve_finite_strain

skfem = pytest.importorskip("skfem", reason="needs scikit-fem (the test extra)")
from skfem.helpers import ddot, det, grad, inv, mul, transpose  # noqa: E402

#: ``skfem_hex[:, i] = vtk_hex[:, HEX_VTK_TO_SKFEM[i]]`` (benchmarks/assembly.py).
HEX_VTK_TO_SKFEM = np.array([0, 4, 3, 1, 7, 5, 2, 6])


def _kinematics(w):
    f = grad(w["u"]) + np.eye(3)[:, :, None, None]
    return f, det(f), transpose(inv(f))


@skfem.Functional
def _volume(w):
    return _kinematics(w)[1]


@skfem.Functional
def _volume0(w):
    return np.ones_like(w.x[0])


@skfem.LinearForm
def _residual(v, w):
    f, j, fit = _kinematics(w)
    p = w["mu"] * (f - fit) + w["lc"] * np.log(j) * fit + w["s"] * j * fit
    return ddot(p, grad(v))


@skfem.BilinearForm
def _tangent(du, v, w):
    _, j, fit = _kinematics(w)
    df = grad(du)
    turned = mul(mul(fit, transpose(df)), fit)
    dp = w["mu"] * df + (w["mu"] - w["lc"] * np.log(j)) * turned + w["lc"] * ddot(fit, df) * fit
    dp = dp + w["s"] * j * (ddot(fit, df) * fit - turned)  # the slope times dv's curvature
    return ddot(dp, grad(v))


@skfem.BilinearForm
def _volume_gradients(q, v, w):
    # a piecewise constant trial q: the columns are each cell's dv/du
    _, j, fit = _kinematics(w)
    return q * j * ddot(fit, grad(v))


class Peer:
    """The mesh in scikit-fem, and the energy's forces and tangent at displacements ``u``."""

    def __init__(self, mesh: fem.Mesh, kind: str, e: float, nu: float) -> None:
        p = np.ascontiguousarray(mesh.points.T)
        conn = mesh.cells[kind]
        if kind == "hexahedron":
            m = skfem.MeshHex(p, np.ascontiguousarray(conn[:, HEX_VTK_TO_SKFEM].T))
            el, el0, order = skfem.ElementHex1(), skfem.ElementHex0(), 3  # 2x2x2 Gauss
        else:
            m = skfem.MeshTet(p, np.ascontiguousarray(conn.T))
            el, el0, order = skfem.ElementTetP1(), skfem.ElementTetP0(), 2
        self.kind, self.mesh = kind, m
        self.basis = skfem.Basis(m, skfem.ElementVector(el), intorder=order)
        self.cells = self.basis.with_element(el0)
        self.perm = np.asarray(self.basis.nodal_dofs).T.ravel()  # ours -> scikit-fem's
        self.lam = e * nu / ((1 + nu) * (1 - 2 * nu))
        self.mu = e / (2 * (1 + nu))
        self.kappa = self.lam + 2 * self.mu / 3

    def _groups(self, ui):
        """The averaged volumes: cells to groups, each group's slope and curvature."""
        v = _volume.elemental(self.basis, u=ui)
        v0 = _volume0.elemental(self.basis, u=ui)
        if self.kind == "tetra":
            t = self.mesh.t
            ne = t.shape[1]
            to_group = sp.csr_matrix(
                (np.full(4 * ne, 0.25), (t.ravel(), np.tile(np.arange(ne), 4))),
                shape=(self.mesh.p.shape[1], ne),
            )
        else:
            to_group = sp.identity(v.size, format="csr")
        gv, gv0 = to_group @ v, to_group @ v0
        ln = np.log(gv / gv0)
        slope = self.kappa * gv0 * ln / gv
        curve = self.kappa * gv0 * (1 - ln) / gv**2
        cell_slope = (to_group.T @ slope) / (to_group.T @ np.ones(gv.size))
        return to_group, cell_slope, curve

    def state(self, u: np.ndarray) -> tuple[np.ndarray, sp.csr_matrix]:
        """Forces and tangent at ``u`` (our node order, ``(N, 3)``), in our DOF order."""
        us = np.zeros(self.basis.N)
        us[self.perm] = np.asarray(u).ravel()
        ui = self.basis.interpolate(us)
        to_group, cell_slope, curve = self._groups(ui)
        w = dict(u=ui, mu=self.mu, lc=self.lam - self.kappa, s=self.cells.interpolate(cell_slope))
        force = skfem.asm(_residual, self.basis, **w)
        gradients = skfem.asm(_volume_gradients, self.cells, self.basis, u=ui) @ to_group.T
        k = skfem.asm(_tangent, self.basis, **w) + gradients @ sp.diags(curve) @ gradients.T
        k = sp.csr_matrix(k)
        return force[self.perm], k[self.perm][:, self.perm]

    def solve(self, held, values, increments: int, tol: float = 1e-11) -> tuple[np.ndarray, ...]:
        """Newton's method with held DOFs (ours) moved to ``values`` over the increments.

        A step that turns a cell inside out is halved.
        """
        n = self.basis.N
        free = np.setdiff1d(np.arange(n), held)
        u = np.zeros(n)
        for step in range(1, increments + 1):
            u[held] = values * step / increments
            for _ in range(20):
                f, k = self.state(u.reshape(-1, 3))
                if np.abs(f[free]).max() <= tol * np.abs(f).max():
                    break
                du = sp.linalg.spsolve(k[free][:, free].tocsc(), f[free])
                for _ in range(10):  # halved while it turns a cell inside out
                    trial = u.copy()
                    trial[free] -= du
                    with np.errstate(invalid="ignore"):
                        if np.isfinite(self.state(trial.reshape(-1, 3))[0]).all():
                            break
                    du = du / 2
                u = trial
            else:
                pytest.fail(f"the peer's Newton did not converge in increment {step}")
        return u.reshape(-1, 3), self.state(u.reshape(-1, 3))[0].reshape(-1, 3)


def _block(kind: str, n: int = 3) -> fem.Mesh:
    mesh = fem.box_mesh((1.0, 1.0, 1.0), (n, n, n))
    return fem.hex_to_tet(mesh) if kind == "tetra" else mesh


def _smooth(points: np.ndarray) -> np.ndarray:
    x, y, z = points.T
    return 0.1 * np.stack([np.sin(2 * y), x**2, -z * x], axis=1)


@pytest.mark.parametrize("kind", ["hexahedron", "tetra"])
@pytest.mark.parametrize("nu", [0.3, 0.49])
def test_forces_and_tangent_equal_the_peers(kind, nu):
    mesh = _block(kind)
    u = _smooth(mesh.points)
    ours = fem.finite_strain(mesh, fem.LinearElastic(1.0e4, nu), u)
    force, k = Peer(mesh, kind, 1.0e4, nu).state(u)
    assert np.abs(ours.force - force).max() <= 1e-12 * np.abs(force).max()
    assert abs(ours.stiffness - k).max() <= 1e-12 * abs(k).max()


@pytest.mark.parametrize("kind", [pytest.param("hexahedron", marks=pytest.mark.slow), "tetra"])
def test_a_bonded_block_compressed_and_sheared_as_the_peer_solves_it(kind):
    # the bricks' force and tangent meet the peer's to 1e-12 above; their whole solve: slow
    mesh = _block(kind)
    z = mesh.points[:, 2]
    bottom, top = np.flatnonzero(np.isclose(z, 0.0)), np.flatnonzero(np.isclose(z, 1.0))
    held = np.concatenate([3 * bottom[:, None] + np.arange(3), 3 * top[:, None] + np.arange(3)])
    moved = np.concatenate([np.zeros((bottom.size, 3)), np.tile([0.15, 0.0, -0.3], (top.size, 1))])
    ours = solve_finite_strain(
        mesh, fem.LinearElastic(1.0e4, 0.45), prescribed=held.ravel(), values=moved.ravel(),
        increments=5,
    )  # fmt: skip
    assert ours.converged
    u, force = Peer(mesh, kind, 1.0e4, 0.45).solve(held.ravel(), moved.ravel(), increments=5)
    # the same equilibrium: a barrelled, sheared block, the plates' forces to round-off
    assert np.abs(u[:, :2]).max() > 0.05  # far from homogeneous: the sides bulge and bend
    assert np.abs(ours.u - u).max() <= 1e-9
    plate = ours.reactions.reshape(-1, 3)[top].sum(axis=0)
    assert np.abs(plate - force[top].sum(axis=0)).max() <= 1e-9 * np.abs(plate).max()
    assert plate[2] < 0.0 and plate[0] > 0.0  # the plate pushes down and drags sideways
