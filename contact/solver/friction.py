"""Coulomb friction of a linearised contact set: a semismooth Newton method in contact space.

Each contact ``i`` has a normal row ``p`` and, where its pair has friction, two tangential
rows ``t = (t1, t2)``. With the Delassus operator ``W`` and the free bodies' rigid modes
``G`` (:mod:`contact.solver.delassus`), the rows' values are ``y = W lambda + G a - rhs``:
the normal gap ``g = y_p`` and the tangential slip increment ``s = y_t`` (the slave node's
motion relative to its anchor, :mod:`contact.solver.anchors`). Coulomb's law, with its
isotropic cone and no regularisation::

    g >= 0,  lambda_p >= 0,  g lambda_p = 0                     (unilateral contact)
    |lambda_t| <= mu lambda_p                                   (the cone)
    s = 0 where |lambda_t| < mu lambda_p                        (stick)
    lambda_t = -mu lambda_p s / |s| where s != 0                (slip, opposed to it)
    G^T lambda - H a = c                                        (free bodies in balance)

(``H``: the modes' stiffness of a body that turns with it, :mod:`contact.solver.delassus`;
zero for linear bodies) is written as the root of the Alart-Curnier natural map (Alart
and Curnier 1991), with ``xi = lambda_p - c_p g`` and ``z = lambda_t - c_t s``::

    F_p = lambda_p - max(0, xi)
    F_t = lambda_t - proj_{|.| <= mu max(0, xi)}(z)

(:mod:`contact.solver.natural_map`) and solved by a semismooth Newton method: each step
is the primal-dual active set of Hueber, Stadler and Wohlmuth (2008) (open, stick and
slip contacts read off ``xi`` and ``z``). ``c_p`` and ``c_t`` are the inverse diagonal
compliances, which makes every residual a force. The first steps take the slip's exact
derivative with a backtracking line search on ``|F|^2``; where the active sets cycle it
starts again with another multiple of ``c_p, c_t`` or the derivative of Hueber, Stadler
and Wohlmuth, then tries a fixed point of Tresca problems (the radii ``mu N`` of the
normal forces, Anderson-accelerated) finished by Coulomb's, then a continuation in
springs that hold the free bodies (:data:`PHASES`).
Where ``mu = 0`` everywhere the frictionless LCP (:mod:`contact.solver.lcp`) is used
instead.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from fem.threads import dense_threads

from .delassus import TOUCHING
from .natural_map import NaturalMap
from .reducedstep import reduced_step

__all__ = ["FRICTION_TOLERANCE", "FrictionResult", "solve_friction"]

#: Residual of the natural map, over the force scale, below which a solve has converged.
FRICTION_TOLERANCE = 1e-9
#: Newton steps before a solve gives up (a contact set at its slip limit takes the most).
MAX_NEWTON = 400
#: Newton steps without halving the residual after which the active sets are taken to
#: cycle and the next strategy starts.
STALL = 10
#: Newton steps a strategy may take.
TRY_STEPS = 40
#: The strategies tried in turn from the same start, each a factor on the augmentation
#: ``c_p, c_t`` (the inverse diagonal compliances) and how a step is taken: ``"exact"``,
#: the slip's exact derivative and a backtracking line search on ``|F|^2`` (its
#: directions descend); ``"whole"``, Hueber, Stadler and Wohlmuth's derivative and whole
#: steps; ``"search"``, theirs searched along. The natural map's roots do not depend on
#: them, the active sets the steps visit do.
STRATEGIES = (
    (1.0, "exact"),
    (0.3, "exact"),
    (1.0, "whole"),
    (0.3, "whole"),
    (0.1, "whole"),
    (3.0, "whole"),
    (1.0, "search"),
    (0.3, "search"),
)
#: The order the solve tries them in: the whole-step strategies, then the fixed point of
#: Tresca problems (the radii ``mu N`` of the last normal forces), the continuation in
#: springs on the free bodies (:func:`_springs`), then the searched ones.
PHASES = (*STRATEGIES[:6], "tresca", "springs", *STRATEGIES[6:])
#: The continuation's springs on the free bodies, in the contacts' stiffness seen in
#: their modes: from stiff ones that carry every load (a problem any start solves) to
#: soft ones whose solution is the unsprung one's where the contacts hold the bodies.
SPRINGS = (1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6)
#: Newton steps that polish a solve past the tolerance, towards :data:`POLISH_TOL`.
POLISH = 3
POLISH_TOL = 1e-14
#: Tresca solves of the fixed point (each with the radii of the last normal forces).
TRESCA = 30
#: Iterates Anderson's acceleration of that fixed point mixes.
ANDERSON = 4
#: Newton steps the Tresca and the springs phases may take each: where one cannot settle
#: a contact set (Tresca's radii that cannot carry a free body's load), the other still
#: has its turn.
PHASE_STEPS = 150


OPEN, STICK, SLIP = 0, 1, 2


@dataclass(frozen=True)
class FrictionResult:
    """Forces of the candidate rows, the free bodies' amplitudes and each contact's status.

    Attributes
    ----------
    lam : ndarray, shape (M,)
        Row forces: normal ones ``>= 0``, tangential ones in their cone.
    a : ndarray, shape (r,)
        Rigid-mode amplitudes.
    y : ndarray, shape (M,)
        Row values ``W lam + G a - rhs``: normal gaps, tangential slip increments.
    status : ndarray of int, shape (k,)
        0 open, 1 stick, 2 slip (a frictionless closed contact slips).
    iterations : int
        Newton steps taken.
    residual : float
        ``max |F|`` over the force scale at the end.
    solved : bool
        The residual reached ``tol``.
    """

    lam: NDArray[np.float64]
    a: NDArray[np.float64]
    y: NDArray[np.float64]
    status: NDArray[np.int64]
    iterations: int
    residual: float
    solved: bool


def _relative(f: NDArray, lam: NDArray, scale: float) -> float:
    """``max |F|`` (a force) over the larger of ``scale`` and the largest force."""
    return float(np.abs(f).max(initial=0.0)) / max(scale, float(np.abs(lam).max(initial=0.0)))


def _measure(prob: NaturalMap, scale: float) -> Callable[[NDArray, NDArray], float]:
    """``(lam, a) -> `` ``prob``'s residual relative to ``scale`` (:func:`_relative`)."""

    def measure(lam: NDArray, a: NDArray) -> float:
        return _relative(prob.residual(lam, a)[0], lam, scale)

    return measure


def solve_friction(
    w: NDArray[np.float64],
    g: NDArray[np.float64],
    rhs: NDArray[np.float64],
    c: NDArray[np.float64],
    *,
    mu: NDArray[np.float64],
    tangent: NDArray[np.int64],
    start: NDArray[np.float64] | None = None,
    load_scale: float = 0.0,
    tol: float = FRICTION_TOLERANCE,
    max_steps: int = MAX_NEWTON,
    spring: float = 0.0,
    h: NDArray[np.float64] | None = None,
    aux: NDArray[np.bool_] | None = None,
    prox: NDArray[np.float64] | None = None,
) -> FrictionResult:
    """Solve the frictional contact problem of a contact set (see the module docstring).

    Parameters
    ----------
    w : ndarray, shape (M, M)
        Delassus operator of every row: the ``k`` normal rows first (row ``i`` is contact
        ``i``'s), then the tangential ones.
    g : ndarray, shape (M, r)
        The rows' values of the free bodies' rigid modes.
    rhs : ndarray, shape (M,)
        Minus the rows' values without contact forces.
    c : ndarray, shape (r,)
        Minus the loads in the rigid modes.
    mu : ndarray, shape (k,)
        Each contact's coefficient.
    tangent : ndarray of int, shape (k, 2)
        Each contact's two tangential rows, -1 where it has none (``mu = 0``).
    start : ndarray, shape (M,), optional
        Forces to start from (the last solve's, carried over).
    load_scale : float
        Size of the free bodies' loads (for the residual's scale).
    tol : float
        Residual to reach, relative to the force scale.
    max_steps : int
        Newton steps before giving up.
    spring : float
        Hold every free body by a spring of this stiffness in its modes, in the contacts'
        stiffness seen there (``mean |G_i|^2 / mean W_ii``): its balance row reads
        ``G^T lambda - c = spring a``, what the contacts do not carry.
    h : ndarray, shape (r, r), optional
        The modes' stiffness (:attr:`contact.solver.delassus.ContactSystem.h`).
    aux : ndarray of bool, shape (r,), optional
        The amplitudes that are a border's auxiliaries, held by their own rows
        (:attr:`contact.solver.delassus.ContactSystem.aux`).
    prox : ndarray, shape (r,), optional
        Springs of the problem's own on the amplitudes, in the unit of ``spring``
        (:attr:`contact.solver.delassus.ContactSystem.prox`): unlike ``spring``, part of
        the problem solved, not of the way to its solution.

    Returns
    -------
    FrictionResult
    """
    with dense_threads(np.size(rhs)):
        return _newton(
            w,
            g,
            rhs,
            c,
            np.asarray(mu, float),
            np.asarray(tangent, np.int64),
            start,
            load_scale,
            tol,
            max_steps,
            spring,
            h,
            aux,
            prox,
        )


def _newton(
    w, g, rhs, c, mu, tangent, start, load_scale, tol, max_steps, spring, h, aux, prox
) -> FrictionResult:
    base = NaturalMap(w, g, rhs, c, mu, tangent, h, aux, prox)
    if spring:
        base = base.scaled(1.0, spring=spring)
    m, k = base.m, base.k
    lam = np.zeros(m) if start is None else np.asarray(start, float).copy()
    lam[:k] = np.maximum(lam[:k], 0.0)
    if start is None:
        # start from the rows that penetrate without forces, closed and stuck; where none
        # does (a flat face microns from a plane), from every row touching, the free
        # bodies placed onto them: from all open, no step can close a row
        lam[:k] = np.maximum(base.cp * rhs[:k], 0.0)
        if not lam[:k].any():
            lam[:k] = TOUCHING * max(load_scale, 1e-300)
    a = _placed(base, lam)
    scale = max(float(np.abs(base.cp * rhs[:k]).max(initial=0.0)), load_scale, 1e-300)
    measure = _measure(base, scale)

    best = (measure(lam, a), lam, a)
    steps = 0
    for phase in PHASES:
        if best[0] <= tol or steps >= max_steps:
            break
        if phase == "springs":
            if not base.r:
                continue
            x, n = _springs(base, best, scale, tol, min(PHASE_STEPS, max_steps - steps))
        elif phase == "tresca":
            if not base.fr.size:
                continue
            # Tresca's law with the radii of the last normal forces, in turn, until the
            # normal forces settle; then Coulomb's from there
            x, n = _tresca(base, best, measure, tol, min(PHASE_STEPS, max_steps - steps))
        else:
            factor, mode = phase
            x, n = _descend(base.scaled(factor), lam, a, measure, tol, mode, max_steps - steps)
        steps += n
        if x[0] < best[0]:
            best = x
    if best[0] <= tol:
        # a few more steps take a solve this close to round-off (quadratic convergence)
        x, n = _descend(base, best[1], best[2], measure, POLISH_TOL, False, POLISH)
        steps += n
        if x[0] < best[0]:
            best = x
    res, lam, a = best
    _, s = base.residual(lam, a)
    status = np.where(s["closed"], SLIP, OPEN).astype(np.int64)
    status[base.fr[s["stick"] & s["closed"][base.fr]]] = STICK
    if res <= tol:
        # an open contact's forces are zero to the tolerance: make them exactly zero
        lam = lam.copy()
        lam[:k][status == OPEN] = 0.0
        lam[base.t[status[base.fr] == OPEN].ravel()] = 0.0
    return FrictionResult(
        lam=lam,
        a=a,
        y=s["y"],
        status=status,
        iterations=steps,
        residual=res,
        solved=res <= tol,
    )


def _placed(base: NaturalMap, lam: NDArray) -> NDArray:
    """Free bodies' amplitudes that best close the rows pushing under ``lam``."""
    if not base.r:
        return np.zeros(0)
    on = np.flatnonzero(lam[: base.k] > 0)
    rows = np.concatenate([on, base.t[np.isin(base.fr, on)].ravel()])
    if not rows.size:
        return np.zeros(base.r)
    return np.linalg.lstsq(base.g[rows], (base.rhs - base.w @ lam)[rows], rcond=None)[0]


def _descend(prob: NaturalMap, lam, a, measure, tol, mode: str, budget: int):
    """Newton steps on ``prob`` from ``(lam, a)``: the best ``(residual, lam, a)`` and the steps.

    Stops at ``tol``, after :data:`TRY_STEPS` steps, or where the residual has not halved
    in :data:`STALL` steps (active sets that cycle). ``mode``: how a step is taken (see
    :data:`STRATEGIES`).
    """
    m = prob.m
    search = mode != "whole"
    prob = prob.scaled(1.0, prob.fixed, exact=mode == "exact")
    f, s = prob.residual(lam, a)
    best = (measure(lam, a), lam, a)
    trail = [best[0]]
    n = 0
    while best[0] > tol and n < min(TRY_STEPS, budget):
        d = reduced_step(prob.jacobian(s), f, prob.inactive(s), a, prob)
        if not np.isfinite(d).all():
            break
        x0 = np.concatenate([lam, a])
        step, merit = 1.0, float(f @ f)
        while True:
            x = x0 + step * d
            f1, s1 = prob.residual(x[:m], x[m:])
            if not search or float(f1 @ f1) <= (1 - 1e-4 * step) * merit or step < 1e-6:
                break
            step *= 0.5
        lam, a, f, s = x[:m], x[m:], f1, s1
        n += 1
        res = measure(lam, a)
        if not np.isfinite(res):
            break
        if res < best[0]:
            best = (res, lam, a)
        trail.append(res)
        if len(trail) > STALL and min(trail[-STALL:]) > 0.5 * trail[-1 - STALL]:
            break
    return best, n


def _tresca(base: NaturalMap, best, measure, tol, budget: int):
    """Tresca solves with the radii ``mu N`` of the normal forces until those settle.

    The fixed point ``N = Phi(N)`` (``Phi``: the normal forces of the Tresca solve with
    radii ``mu N``) is taken by Anderson's acceleration over the last :data:`ANDERSON`
    iterates: near a slip limit the plain iteration swings between two states.
    """
    k = base.k
    _, lam, a = best
    n = 0
    x = np.maximum(lam[:k], 0.0)
    xs: list[NDArray] = []
    fs: list[NDArray] = []
    for _ in range(TRESCA):
        fixed = base.mu[base.fr] * x[base.fr]
        gap = _measure(base.scaled(1.0, fixed), 1e-300)
        y, used = _strategies(base, fixed, lam, a, gap, tol, budget - n)
        n += used
        lam, a = y[1], y[2]
        f = np.maximum(lam[:k], 0.0) - x
        if np.abs(f).max(initial=0.0) <= tol * max(float(np.abs(lam[:k]).max()), 1e-300):
            break
        if n >= budget:
            break
        xs.append(x)
        fs.append(f)
        step = x + f
        if len(fs) > 1:
            d_f = np.column_stack([fs[i + 1] - fs[i] for i in range(len(fs) - 1)][-ANDERSON:])
            d_x = np.column_stack([xs[i + 1] - xs[i] for i in range(len(xs) - 1)][-ANDERSON:])
            gamma = np.linalg.lstsq(d_f, f, rcond=None)[0]
            step = step - (d_x + d_f) @ gamma
        x = np.maximum(step, 0.0)
    # Coulomb's law from the settled Tresca solution
    x, used = _strategies(base, None, lam, a, measure, tol, budget - n)
    return x, n + used


def _springs(base: NaturalMap, best, scale: float, tol, budget: int):
    """Continuation in the free bodies' springs (:data:`SPRINGS`) down to ``base``'s own.

    Each sprung problem starts from the last one's solution, close to its own: a path of
    short Newton solves where one from afar cycles. The best ``(residual, lam, a)`` of
    ``base`` and the steps.
    """
    _, lam, a = best
    n = 0
    for spring in SPRINGS:
        prob = base.scaled(1.0, base.fixed, spring=spring)
        if prob.spring <= base.spring:
            break
        x, used = _strategies(prob, prob.fixed, lam, a, _measure(prob, scale), tol, budget - n)
        n += used
        lam, a = x[1], x[2]
        if n >= budget:
            break

    x, used = _strategies(base, base.fixed, lam, a, _measure(base, scale), tol, budget - n)
    return x, n + used


def _strategies(base: NaturalMap, fixed, lam, a, measure, tol, budget: int):
    """:data:`STRATEGIES` in turn from ``(lam, a)`` until one reaches ``tol``: its result."""
    n = 0
    for factor, mode in STRATEGIES:
        x, used = _descend(base.scaled(factor, fixed), lam, a, measure, tol, mode, budget - n)
        n += used
        if x[0] <= tol or n >= budget:
            break
    return x, n
