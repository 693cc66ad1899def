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
    G^T lambda = c                                              (free bodies in balance)

is written as the root of the Alart-Curnier natural map (Alart and Curnier 1991), with
``xi = lambda_p - c_p g`` and ``z = lambda_t - c_t s``::

    F_p = lambda_p - max(0, xi)
    F_t = lambda_t - proj_{|.| <= mu max(0, xi)}(z)

and solved by a semismooth Newton method: each step is the primal-dual active set of
Hueber, Stadler and Wohlmuth (2008) (open, stick and slip contacts read off ``xi`` and
``z``), with their slip derivative, then a backtracking line search on ``|F|^2``.
``c_p`` and ``c_t`` are the inverse diagonal compliances, which makes every residual a
force. Where the active sets cycle, it starts again with another multiple of them, then
tries a fixed point of Tresca problems (the radii ``mu N`` of the last normal forces)
finished by Coulomb's, then other multiples with and without a line search
(:data:`PHASES`).
Where ``mu = 0`` everywhere the frictionless LCP (:mod:`contact.solver.lcp`) is used
instead.
"""

from __future__ import annotations

import copy
import warnings
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
from numpy.typing import NDArray

from fem.threads import dense_threads

from .delassus import TOUCHING

__all__ = ["FRICTION_TOLERANCE", "FrictionResult", "solve_friction"]

#: Residual of the natural map, over the force scale, below which a solve has converged.
FRICTION_TOLERANCE = 1e-9
#: Newton steps before a solve gives up (an unload that reverses the slip takes the most).
MAX_NEWTON = 200
#: Newton steps without halving the residual after which the active sets are taken to
#: cycle and the next strategy starts.
STALL = 10
#: Newton steps a strategy may take.
TRY_STEPS = 40
#: The strategies tried in turn from the same start, each a factor on the augmentation
#: ``c_p, c_t`` (the inverse diagonal compliances) and whether steps are searched along
#: (a backtracking line search on ``|F|^2``) or taken whole: the natural map's roots do
#: not depend on them, the active sets the steps visit do.
STRATEGIES = ((1.0, False), (0.3, False), (0.1, False), (3.0, False), (1.0, True), (0.3, True))
#: The order the solve tries them in, with the fixed point of Tresca problems (the radii
#: ``mu N`` of the last normal forces) after the first two.
PHASES = (*STRATEGIES[:2], "tresca", *STRATEGIES[2:])
#: Newton steps that polish a solve past the tolerance, towards :data:`POLISH_TOL`.
POLISH = 3
POLISH_TOL = 1e-14
#: A contact's tangential compliance block below this fraction of the largest diagonal
#: is taken as held both ways (no friction there).
DEGENERATE = 1e-10
#: The shift, over the largest Jacobian entry, of a singular Newton system.
SHIFT = 1e-10
#: Tresca solves of the fixed point (each with the radii of the last normal forces).
TRESCA = 30


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


class _Problem:
    """The natural map of one contact set and its generalised Jacobian."""

    def __init__(self, w, g, rhs, c, mu, tangent) -> None:
        self.fixed: NDArray | None = None  # Tresca: each frictional contact's radius
        self.w, self.g, self.rhs, self.c = w, g, rhs, c
        self.wg = np.hstack([w, g])  # the rows' values per unknown: d y / d(lam, a)
        self.k = mu.size
        self.m, self.r = g.shape
        self.fr = np.flatnonzero(tangent[:, 0] >= 0)  # contacts with friction
        self.t = tangent[self.fr]  # (kf, 2) their tangential rows
        d = np.diag(w).copy()
        floor = 1e-12 * max(float(d.max(initial=0.0)), 1e-300)
        # a contact whose tangential rows no body can move along (a node on a symmetry
        # plane: both bodies held across it) takes no friction: its rows stay at zero
        self.mu = mu.copy()
        if self.fr.size:
            tt = w[self.t[:, :, None], self.t[:, None, :]]  # (kf, 2, 2)
            least = np.linalg.eigvalsh(tt)[:, 0]
            self.mu[self.fr[least <= DEGENERATE * max(float(d.max()), 1e-300)]] = 0.0
        self.cp = 1.0 / np.maximum(d[: self.k], floor)
        dt = d[self.t].mean(axis=1) if self.fr.size else np.zeros(0)
        self.ct = 1.0 / np.maximum(dt, floor)

    def scaled(self, factor: float, fixed: NDArray | None = None) -> _Problem:
        """The same problem with its augmentation ``c_p, c_t`` times ``factor``.

        With ``fixed``, Tresca's law instead: each frictional contact's radius is given
        (where it is closed).
        """
        out = copy.copy(self)
        out.cp = self.cp * factor
        out.ct = self.ct * factor
        out.fixed = fixed
        return out

    def values(self, lam: NDArray, a: NDArray) -> NDArray:
        return self.w @ lam + self.g @ a - self.rhs

    def residual(self, lam: NDArray, a: NDArray) -> tuple[NDArray, dict]:
        """``F`` (M + r) and what its Jacobian needs."""
        k, fr, t = self.k, self.fr, self.t
        y = self.values(lam, a)
        xi = lam[:k] - self.cp * y[:k]
        closed = xi > 0
        f = np.empty(self.m + self.r)
        f[:k] = np.where(closed, self.cp * y[:k], lam[:k])
        if self.fixed is None:
            radius = self.mu[fr] * np.maximum(xi[fr], 0.0)
        else:
            radius = np.where(closed[fr], self.fixed, 0.0)
        lt = lam[t]  # (kf, 2)
        z = lt - self.ct[:, None] * y[t]
        nz = np.linalg.norm(z, axis=1)
        stick = (nz <= radius) & (radius > 0)
        q = z / np.maximum(nz, 1e-300)[:, None]
        ft = np.where(stick[:, None], self.ct[:, None] * y[t], lt - radius[:, None] * q)
        f[t.ravel()] = ft.ravel()
        # rows of the system that belong to no contact's normal or tangent: none
        f[self.m :] = self.g.T @ lam - self.c
        return f, {
            "closed": closed,
            "stick": stick,
            "q": q,
            "nz": nz,
            "radius": radius,
            "y": y,
            "lt": lt,
        }

    def inactive(self, s: dict) -> NDArray[np.bool_]:
        """The unknowns whose rows of ``F`` are their own value (open contacts' forces)."""
        out = np.zeros(self.m + self.r, dtype=bool)
        out[: self.k] = ~s["closed"]
        free = ~s["stick"] & (s["radius"] <= 0)
        out[self.t[free].ravel()] = True
        return out

    def jacobian(self, s: dict) -> NDArray:
        k, m, r, fr, t = self.k, self.m, self.r, self.fr, self.t
        n = m + r
        j = np.zeros((n, n))
        wg = self.wg  # (m, n): d y / d(lam, a)
        closed = s["closed"]
        rows = np.arange(k)
        j[rows[closed], :] = self.cp[closed, None] * wg[rows[closed]]
        j[rows[~closed], rows[~closed]] = 1.0
        stick, q, nz, radius = s["stick"], s["q"], s["nz"], s["radius"]
        if fr.size:
            # stick: the tangential rows close, c_t s = 0
            st = np.flatnonzero(stick)
            j[t[st].ravel(), :] = (self.ct[st, None, None] * wg[t[st]]).reshape(-1, n)
            # open (radius 0): F_t = lam_t
            op = np.flatnonzero(~stick & (radius <= 0))
            j[t[op, 0], t[op, 0]] = 1.0
            j[t[op, 1], t[op, 1]] = 1.0
            # slip: d F_t = d lam_t - mu q d xi + A d z, d z = d lam_t - c_t d s, with
            # A = (cone q^T - r I) / |z| (Hueber, Stadler and Wohlmuth's slip derivative:
            # the exact one has r q q^T where this has the force projected on the cone;
            # they agree at a solution, lam_t = r q, and this one does not stall)
            sl = np.flatnonzero(~stick & (radius > 0))
            if sl.size:
                ts, ps, qs = t[sl], fr[sl], q[sl]
                lt = s["lt"][sl]
                size = np.linalg.norm(lt, axis=1)
                big = size > radius[sl]
                shrink = np.ones(sl.size)
                shrink[big] = radius[sl][big] / size[big]
                cone = lt * shrink[:, None]
                amat = cone[:, :, None] * qs[:, None, :] - radius[sl, None, None] * np.eye(2)
                amat /= nz[sl, None, None]
                mu = self.mu[ps] if self.fixed is None else np.zeros(sl.size)
                blk = -self.ct[sl, None, None] * np.einsum("cij,cjn->cin", amat, wg[ts])
                blk += (mu * self.cp[ps])[:, None, None] * qs[:, :, None] * wg[ps][:, None, :]
                rows = ts.ravel()
                j[rows, :] = blk.reshape(-1, n)
                eye = np.eye(2) + amat  # d lam_t (1 + A)
                for a_ in range(2):
                    for b_ in range(2):
                        j[ts[:, a_], ts[:, b_]] += eye[:, a_, b_]
                j[ts[:, 0], ps] -= mu * qs[:, 0]
                j[ts[:, 1], ps] -= mu * qs[:, 1]
        j[m:, :m] = self.g.T
        return j


def _relative(f: NDArray, lam: NDArray, scale: float) -> float:
    """``max |F|`` (a force) over the larger of ``scale`` and the largest force."""
    return float(np.abs(f).max(initial=0.0)) / max(scale, float(np.abs(lam).max(initial=0.0)))


def _reduced_step(j: NDArray, f: NDArray, inactive: NDArray[np.bool_]) -> NDArray:
    """Newton step ``J d = -F`` with the open contacts' rows (``J`` = identity) taken out.

    Their forces step to zero (``d = -F`` there); the rest is a system of the closed
    contacts and the free bodies' modes only: a few rows where the candidates are many.
    """
    d = np.empty_like(f)
    d[inactive] = -f[inactive]
    act = ~inactive
    if act.any():
        ja = j[np.ix_(act, act)]
        d[act] = _step(ja, f[act] + j[np.ix_(act, inactive)] @ d[inactive])
    return d


def _step(j: NDArray, f: NDArray) -> NDArray:
    """Newton step ``J d = -F``.

    Where ``J`` is singular (rows that repeat one another, a mode nothing holds), the
    step of ``J + delta I`` (a tiny shift) where it solves ``J d = -F`` nearly as well,
    else least squares.
    """
    size = max(float(np.linalg.norm(f)), 1e-300)
    for shift in (0.0, SHIFT * max(float(np.abs(j).max(initial=0.0)), 1e-300)):
        try:
            with warnings.catch_warnings():  # a singular J is looked at below
                warnings.simplefilter("ignore", sla.LinAlgWarning)
                lu = sla.lu_factor(
                    j + shift * np.eye(j.shape[0]) if shift else j, check_finite=False
                )
                d = sla.lu_solve(lu, -f, check_finite=False)
        except (np.linalg.LinAlgError, ValueError):
            continue
        if (
            np.isfinite(d).all()
            and np.linalg.norm(j @ d + f) <= (1e-8 if not shift else 1e-6) * size
        ):
            return d
    return np.linalg.lstsq(j, -f, rcond=1e-12)[0]


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
        )


def _newton(w, g, rhs, c, mu, tangent, start, load_scale, tol, max_steps) -> FrictionResult:
    base = _Problem(w, g, rhs, c, mu, tangent)
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

    def measure(lam: NDArray, a: NDArray) -> float:
        f, _ = base.residual(lam, a)
        return _relative(f, lam, scale)

    best = (measure(lam, a), lam, a)
    steps = 0
    for phase in PHASES:
        if best[0] <= tol or steps >= max_steps:
            break
        if phase == "tresca":
            if not base.fr.size:
                continue
            # Tresca's law with the radii of the last normal forces, in turn, until the
            # normal forces settle; then Coulomb's from there
            x, n = _tresca(base, best, measure, tol, max_steps - steps)
        else:
            factor, search = phase
            x, n = _descend(base.scaled(factor), lam, a, measure, tol, search, max_steps - steps)
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


def _placed(base: _Problem, lam: NDArray) -> NDArray:
    """Free bodies' amplitudes that best close the rows pushing under ``lam``."""
    if not base.r:
        return np.zeros(0)
    on = np.flatnonzero(lam[: base.k] > 0)
    rows = np.concatenate([on, base.t[np.isin(base.fr, on)].ravel()])
    if not rows.size:
        return np.zeros(base.r)
    return np.linalg.lstsq(base.g[rows], (base.rhs - base.w @ lam)[rows], rcond=None)[0]


def _descend(prob: _Problem, lam, a, measure, tol, search: bool, budget: int):
    """Newton steps on ``prob`` from ``(lam, a)``: the best ``(residual, lam, a)`` and the steps.

    Stops at ``tol``, after :data:`TRY_STEPS` steps, or where the residual has not halved
    in :data:`STALL` steps (active sets that cycle). ``search``: a backtracking line
    search on ``|F|^2`` (otherwise full steps).
    """
    m = prob.m
    f, s = prob.residual(lam, a)
    best = (measure(lam, a), lam, a)
    trail = [best[0]]
    n = 0
    while best[0] > tol and n < min(TRY_STEPS, budget):
        d = _reduced_step(prob.jacobian(s), f, prob.inactive(s))
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


def _tresca(base: _Problem, best, measure, tol, budget: int):
    """Tresca solves with the radii ``mu N`` of the last normal forces until they settle."""
    k = base.k
    _, lam, a = best
    n = 0
    normal = np.maximum(lam[:k], 0.0)
    for _ in range(TRESCA):
        fixed = base.mu[base.fr] * normal[base.fr]
        tres = base.scaled(1.0, fixed)

        def gap(lam: NDArray, a: NDArray, prob=tres) -> float:
            f, _ = prob.residual(lam, a)
            return _relative(f, lam, 1e-300)

        x, used = _strategies(base, fixed, lam, a, gap, tol, budget - n)
        n += used
        lam, a = x[1], x[2]
        now = np.maximum(lam[:k], 0.0)
        settled = np.abs(now - normal).max(initial=0.0) <= tol * max(now.max(initial=0.0), 1e-300)
        normal = now
        if settled or n >= budget:
            break
    # Coulomb's law from the settled Tresca solution
    x, used = _strategies(base, None, lam, a, measure, tol, budget - n)
    return x, n + used


def _strategies(base: _Problem, fixed, lam, a, measure, tol, budget: int):
    """:data:`STRATEGIES` in turn from ``(lam, a)`` until one reaches ``tol``: its result."""
    n = 0
    for factor, search in STRATEGIES:
        x, used = _descend(base.scaled(factor, fixed), lam, a, measure, tol, search, budget - n)
        n += used
        if x[0] <= tol or n >= budget:
            break
    return x, n
