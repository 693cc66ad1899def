"""The exact inverse of a free body whose stiffness sees its turns (fem.TurningInverse)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

import fem

MAT = fem.LinearElastic(1.0e6, 0.4)


def _squeezed(stretch: float = 0.998):
    """A box compressed along z (its sides held) and its full neo-Hookean tangent there.

    Mildly: the tangent with its six support DOFs held must stay positive definite (a
    turn is cheap on a coarse mesh whose support is six single DOFs).
    """
    mesh = fem.box_mesh((0.02, 0.02, 0.02), (2, 2, 3))
    x = mesh.points
    u = np.zeros_like(x)
    u[:, 2] = (stretch - 1.0) * (x[:, 2] - x[:, 2].mean())
    state = fem.finite_strain(mesh, MAT, u)
    return mesh, u, state


def _clamped_inverse(k: sp.spmatrix, solver: fem.StaticSolver) -> np.ndarray:
    """``J``: the dense inverse of ``k`` with the solver's six support DOFs held."""
    n = k.shape[0]
    inner = np.setdiff1d(np.arange(n), solver._support)
    j = np.zeros((n, n))
    j[np.ix_(inner, inner)] = np.linalg.inv(k.toarray()[np.ix_(inner, inner)])
    return j


@pytest.mark.parametrize("marked", [False, True])
def test_border_solves_the_stressed_free_body_exactly(marked):
    mesh, u, state = _squeezed()
    # a spring on every DOF makes the tangent invertible; the border is exact for any K
    k = (state.stiffness + 1e2 * sp.identity(mesh.n_dofs)).tocsr()
    placed = mesh.points + u
    solver = fem.StaticSolver(k, points=placed, lazy=True)
    if marked:
        solver.mark(np.arange(30))
    t = fem.TurningInverse(solver.factorize())
    f = np.random.default_rng(1).normal(size=mesh.n_dofs)
    exact = np.linalg.solve(k.toarray(), f)
    assert np.allclose(t.solve(f), exact, rtol=1e-9, atol=1e-12 * np.abs(exact).max())
    j = _clamped_inverse(k, solver)
    assert np.allclose(t.inverse(f), j @ f, atol=1e-10 * np.abs(j @ f).max())
    assert np.allclose(t.h, t.h.T)


def test_squeezed_body_turns_with_negative_stiffness():
    """Squeezed, a turn is driven by the forces' arms: ``H < 0`` along every turn."""
    mesh, u, state = _squeezed()
    placed = mesh.points + u
    t = fem.TurningInverse(fem.StaticSolver(state.stiffness, points=placed))
    turns = t.solver.modes[:, 3:]
    # each mode's stiffness along a rigid turn about x, y and z through the centroid
    r = placed - placed.mean(axis=0)
    axes = []
    for a in np.eye(3):
        v = np.cross(a, r).ravel()
        axes.append(np.linalg.lstsq(turns, v, rcond=None)[0])
    h = t.h[3:, 3:]
    stiff = [float(c @ h @ c) for c in axes]
    scale = float(np.abs(state.force).sum()) * 0.02
    assert max(stiff) < -1e-3 * scale
    # squeezed most along z, it turns most readily about x and y
    assert stiff[0] < stiff[2] and stiff[1] < stiff[2]
    # the translations move no force
    assert np.abs(t.h[:3]).max() < 1e-8 * np.abs(h).max()


def test_linear_body_border_is_its_modes():
    """Unstressed, a linear stiffness: ``Psi = Phi`` and ``H = 0`` (the linear free body)."""
    mesh = fem.box_mesh((0.02, 0.02, 0.02), (2, 2, 2))
    k = fem.assemble_stiffness(mesh, MAT)
    s = fem.StaticSolver(k, points=mesh.points)
    t = fem.TurningInverse(s)
    assert np.allclose(t.psi, s.modes, atol=1e-9)
    assert np.abs(t.h).max() < 1e-9 * abs(k).max()


def test_a_supported_body_has_no_border():
    mesh = fem.box_mesh((1, 1, 1), (1, 1, 1))
    k = fem.assemble_stiffness(mesh, MAT)
    with pytest.raises(fem.SolverError, match="free body"):
        fem.TurningInverse(fem.StaticSolver(k, fem.node_dofs([0, 1, 2, 3])))


@pytest.mark.parametrize("marked", [False, True])
def test_extended_border_is_the_exact_constrained_solve(marked):
    """The rows' forces of the bordered system are those of ``K u = b + E^T lam``, ``E u = -g0``.

    The rows' compliance is the solver's own (partial solves where their DOFs are marked).
    """
    mesh, u, state = _squeezed()
    k = (state.stiffness + 1e2 * sp.identity(mesh.n_dofs)).tocsr()
    solver = fem.StaticSolver(k, points=mesh.points + u, lazy=True)
    rng = np.random.default_rng(2)
    e = sp.csr_matrix(rng.normal(size=(4, mesh.n_dofs)) * (np.arange(mesh.n_dofs) < 30))
    if marked:
        solver.mark(np.arange(30))
    t = fem.TurningInverse(solver.factorize())
    b, g0 = rng.normal(size=mesh.n_dofs), 1e-3 * rng.normal(size=4)
    kd = k.toarray()
    ki = np.linalg.inv(kd)
    ed = e.toarray()
    lam = np.linalg.solve(ed @ ki @ ed.T, -(g0 + ed @ ki @ b))
    g, h, c = t.extended(e, b)
    w = solver.compliance(e)
    rhs = -(g0 + e @ solver.apply_inverse(b))
    big = np.block([[w, g], [g.T, -h]])
    sol = np.linalg.solve(big, np.concatenate([rhs, c]))
    assert np.allclose(sol[:4], lam, rtol=1e-8)
    disp = t.displacement(b + e.T @ sol[:4], sol[4:])
    assert np.allclose(kd @ disp, b + e.T @ lam, atol=1e-8 * np.abs(b).max())
