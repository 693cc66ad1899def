"""Static equilibrium at finite strain: Newton's method on the partitioned system.

With prescribed DOFs ``k`` (values ``Uk``) and external loads ``R``, equilibrium of a
hyperelastic body (:mod:`fem.hyperelastic`) is the root of the residual
``r(U) = f_int(U) - R`` on the unknown DOFs. Each Newton step solves the partitioned
tangent system of Gourret, Magnenat-Thalmann and Thalmann (1989), equation (7), with the
tangent ``K_T`` in place of ``K``::

    K_T,11 dUu = -r_u

and a backtracking line search on the residual's norm. A pressure may follow the deformed
surface (:mod:`fem.follower`). The prescribed values and loads are applied in load
steps, each a Newton solve from the last.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from .errors import MaterialError, SolverError
from .follower import follower_pressure
from .hyperelastic import finite_strain
from .linsolve import factorize
from .material import LinearElastic
from .mesh import BoundaryFaces, Mesh

__all__ = ["NewtonSolution", "solve_finite_strain"]

log = logging.getLogger(__name__)

#: Residual, over the largest load or internal force, at which a load step has converged.
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
    follower: tuple[BoundaryFaces | Mapping[str, ArrayLike], float] | None = None,
    closed: bool = True,
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
    follower : (faces, pressure), optional
        A pressure (Pa) on the deformed faces (:func:`fem.follower.follower_pressure`),
        growing with the load steps as the loads do.
    closed : bool
        The follower's faces close a volume (its stiffness is then symmetric).

    Raises
    ------
    SolverError
        Bad DOF indices or sizes.
    """
    n = mesh.n_dofs
    given = np.asarray(prescribed, dtype=np.int64).ravel()
    k, first = np.unique(given, return_index=True)  # sorted; a repeat takes its first value
    if k.size and (k.min() < 0 or k.max() >= n):
        raise SolverError(f"prescribed DOFs must lie in [0, {n}), got {k.min()}..{k.max()}")
    uk = np.zeros(k.size)
    if values is not None:
        try:
            uk = np.broadcast_to(np.asarray(values, dtype=np.float64), given.shape)[first]
        except ValueError as exc:
            raise SolverError(
                f"values must be one number or one per prescribed DOF ({given.size})"
            ) from exc
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

        def external(x: NDArray, s: float = s) -> tuple[NDArray, sp.csr_matrix | None]:
            if follower is None:
                return s * load, None
            f, kp = follower_pressure(mesh, follower[0], s * follower[1], x, closed=closed)
            return s * load + f, kp

        used, res, done = _newton(mesh, materials, u, k, target, free, external, tol,
                                  max_steps)
        steps.append(used)
        ok = ok and done
        if not done:
            log.warning("load step %d of %d: residual %.3g after %d steps", step, increments,
                        res, used)
            break
    state = finite_strain(mesh, materials, u, stiffness=False)
    return NewtonSolution(u.reshape(-1, 3), state.force - external(u)[0], steps, res, ok)


def _newton(mesh, materials, u, k, target, free, external, tol, max_steps):
    """Newton steps on ``u`` (in place) to equilibrium with ``u[k] = target``.

    Each step moves the prescribed DOFs the rest of the way to ``target`` and the free
    ones by the tangent's answer to it (``K11 dUu = -r_u - K12 dUk``): the first step of a
    load step predicts the whole field instead of moving a boundary layer alone.
    Returns the steps taken, the relative residual and whether it converged.
    """
    res = np.inf
    for it in range(max_steps + 1):
        state = finite_strain(mesh, materials, u)
        f_ext, k_ext = external(u)
        r = state.force - f_ext
        res = _relative(r, f_ext, state.force, free)
        gap = target - u[k]
        if res <= tol and not np.abs(gap).max(initial=0.0):
            return it, res, True
        if it == max_steps:
            break
        kt = state.stiffness if k_ext is None else (state.stiffness + k_ext).tocsr()
        k11 = kt[free][:, free]
        rhs = -r[free] - kt[free][:, k] @ gap
        try:
            du_free = factorize(k11).solve(rhs)
        except SolverError:
            du_free = factorize(k11, backend="superlu").solve(rhs)  # an indefinite tangent
        du = np.zeros_like(u)
        du[free], du[k] = du_free, gap
        step = _searched(mesh, materials, u, du, free, external, float(np.linalg.norm(r[free])),
                         bool(np.abs(gap).max(initial=0.0)))
        u += step * du
        if step == 1.0:
            u[k] = target  # exactly, not to round-off
    return max_steps, res, False


def _relative(r: NDArray, f_ext: NDArray, f_int: NDArray, free: NDArray) -> float:
    """The free DOFs' largest residual over the largest load or internal force."""
    scale = max(float(np.abs(f_ext).max(initial=0.0)), float(np.abs(f_int).max(initial=0.0)),
                1e-300)
    return float(np.abs(r[free]).max(initial=0.0)) / scale


def _searched(mesh, materials, u, du, free, external, size: float, moving: bool) -> float:
    """The fraction of the step ``du`` the line search takes.

    Halved until no cell turns inside out and, once the prescribed DOFs are where they go
    (``moving`` False), until the free DOFs' residual norm falls (Armijo on ``|r|^2``,
    whose descent direction Newton's step is).
    """
    step = 1.0
    for _ in range(HALVINGS):
        trial = u + step * du
        try:
            f = finite_strain(mesh, materials, trial, stiffness=False).force
        except MaterialError:  # a cell turned inside out: shorter
            step *= 0.5
            continue
        if moving:
            return step
        now = float(np.linalg.norm((f - external(trial)[0])[free]))
        if now <= (1.0 - 1e-4 * step) * size:
            return step
        step *= 0.5
    return step
