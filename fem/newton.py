"""Static equilibrium at finite strain: Newton's method on the partitioned system.

With prescribed DOFs ``k`` (values ``Uk``) and external loads ``R``, equilibrium of a
hyperelastic body (:mod:`fem.hyperelastic`) is the root of the residual
``r(U) = f_int(U) - R`` on the unknown DOFs. Each Newton step solves the partitioned
tangent system of Gourret, Magnenat-Thalmann and Thalmann (1989), equation (7), with the
tangent ``K_T`` in place of ``K``::

    K_T,11 dUu = -r_u

and a backtracking line search on the total potential ``Pi(U) - R . U`` (its steps are
directions of descent where ``K_T,11`` is positive definite). The prescribed values are
applied in load steps, each a Newton solve from the last.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import MaterialError, SolverError
from .hyperelastic import finite_strain
from .linsolve import factorize
from .material import LinearElastic
from .mesh import Mesh

__all__ = ["NewtonSolution", "solve_finite_strain"]

log = logging.getLogger(__name__)

#: Residual, over the largest of the loads and reactions, at which a step has converged.
TOLERANCE = 1e-10
#: Newton steps a load step may take.
MAX_STEPS = 30
#: Halvings of a step the line search may take.
HALVINGS = 12


@dataclass(frozen=True)
class NewtonSolution:
    """Displacements, reactions and how Newton's method went.

    Attributes
    ----------
    u : ndarray, shape (N, 3)
        Displacements (m).
    reactions : ndarray, shape (3N,)
        Internal forces less loads: the reactions at the prescribed DOFs (N), zero to
        the tolerance elsewhere.
    steps : list of int
        Newton steps of each load step.
    residual : float
        The last relative residual.
    converged : bool
        Every load step reached the tolerance.
    """

    u: NDArray[np.float64]
    reactions: NDArray[np.float64]
    steps: list[int]
    residual: float
    converged: bool


def solve_finite_strain(
    mesh: Mesh,
    materials: LinearElastic | Mapping[int, LinearElastic],
    *,
    prescribed: ArrayLike,
    values: ArrayLike | None = None,
    loads: ArrayLike | None = None,
    increments: int = 1,
    tol: float = TOLERANCE,
    max_steps: int = MAX_STEPS,
    start: ArrayLike | None = None,
) -> NewtonSolution:
    """Solve the static equilibrium of a neo-Hookean body by Newton's method.

    Parameters
    ----------
    mesh : Mesh
    materials : LinearElastic or mapping of int to LinearElastic
        ``E, nu`` per region (the law of :mod:`fem.hyperelastic`).
    prescribed : array_like of int
        Prescribed DOFs (``3 * node + component``); together they must hold every rigid
        mode.
    values : array_like, optional
        Their displacements at the end (m); zero by default.
    loads : array_like, shape (3N,), optional
        Dead loads at the end (N).
    increments : int
        Load steps: the values and loads grow linearly over them.
    tol : float
        Relative residual to reach in each.
    max_steps : int
        Newton steps per load step.
    start : array_like, shape (3N,), optional
        Displacements to start from (zero by default).

    Raises
    ------
    SolverError
        Bad DOF indices or sizes.
    """
    n = mesh.n_dofs
    k = np.unique(np.asarray(prescribed, dtype=np.int64).ravel())
    if k.size and (k.min() < 0 or k.max() >= n):
        raise SolverError(f"prescribed DOFs must lie in [0, {n}), got {k.min()}..{k.max()}")
    uk = np.zeros(k.size) if values is None else np.broadcast_to(
        np.asarray(values, dtype=np.float64), (k.size,)
    )
    load = np.zeros(n) if loads is None else np.asarray(loads, dtype=np.float64).ravel()
    if load.size != n:
        raise SolverError(f"loads must have {n} entries, got {load.size}")
    free = np.setdiff1d(np.arange(n), k)
    u = np.zeros(n) if start is None else np.asarray(start, dtype=np.float64).ravel().copy()
    u0k = u[k].copy()
    steps: list[int] = []
    res, ok = 0.0, True
    for step in range(1, increments + 1):
        s = step / increments
        target = u0k + s * (uk - u0k)
        r_ext = s * load
        used, res, done = _newton(mesh, materials, u, k, target, free, r_ext, tol, max_steps)
        steps.append(used)
        ok = ok and done
        if not done:
            log.warning("load step %d of %d: residual %.3g after %d steps", step, increments,
                        res, used)
            break
    state = finite_strain(mesh, materials, u, stiffness=False)
    return NewtonSolution(u.reshape(-1, 3), state.force - s * load, steps, res, ok)


def _newton(mesh, materials, u, k, target, free, r_ext, tol, max_steps):
    """Newton steps on ``u`` (in place) to equilibrium with ``u[k] = target``.

    Each step moves the prescribed DOFs the rest of the way to ``target`` and the free
    ones by the tangent's answer to it (``K11 dUu = -r_u - K12 dUk``): the first step of a
    load step predicts the whole field instead of moving a boundary layer alone.
    Returns the steps taken, the relative residual and whether it converged.
    """
    res = np.inf
    for it in range(max_steps + 1):
        state = finite_strain(mesh, materials, u)
        r = state.force - r_ext
        scale = max(float(np.abs(r_ext).max(initial=0.0)), float(np.abs(state.force).max()),
                    1e-300)
        res = float(np.abs(r[free]).max(initial=0.0)) / scale
        gap = target - u[k]
        if res <= tol and not np.abs(gap).max(initial=0.0):
            return it, res, True
        if it == max_steps:
            break
        kt = state.stiffness
        k11 = kt[free][:, free]
        rhs = -r[free] - kt[free][:, k] @ gap
        try:
            du_free = factorize(k11).solve(rhs)
        except SolverError:
            du_free = factorize(k11, backend="superlu").solve(rhs)  # an indefinite tangent
        du = np.zeros_like(u)
        du[free], du[k] = du_free, gap
        step = _searched(mesh, materials, u, du, r, r_ext, state.energy)
        u += step * du
        if step < 1.0:
            continue
        u[k] = target  # exactly, not to round-off
    return max_steps, res, False


def _searched(mesh, materials, u, du, r, r_ext, energy) -> float:
    """The fraction of the step ``du`` the line search takes.

    Halved until the total potential falls (Armijo) and no cell turns inside out; the
    whole step where the fall it predicts is round-off of the potential (Newton's
    quadratic end).
    """
    slope = float(r @ du)
    base = energy - float(r_ext @ u)
    quadratic = abs(slope) <= 1e-9 * max(abs(base), 1e-300)
    step = 1.0
    for _ in range(HALVINGS):
        trial = u + step * du
        try:
            e = finite_strain(mesh, materials, trial, stiffness=False).energy
        except MaterialError:  # a cell turned inside out: shorter
            step *= 0.5
            continue
        if quadratic or slope >= 0 or e - float(r_ext @ trial) <= base + 1e-4 * step * slope:
            return step
        step *= 0.5
    return step
