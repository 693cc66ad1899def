"""Frictionless contact forces of a linearised contact set: a bounded QP in contact space.

For candidate rows whose compliance ``W`` is known (:mod:`contact.delassus`), the forces
``lambda`` and the free bodies' rigid-mode amplitudes ``a`` solve the linear
complementarity problem of frictionless contact::

    gap = W lambda + G a - rhs >= 0,   lambda >= 0,   lambda . gap = 0,   G^T lambda = c

which is the optimality condition of the convex quadratic programme

    min  1/2 lambda^T W lambda - rhs^T lambda   s.t.  lambda >= 0,  G^T lambda = c.

It is solved by a primal active-set method in the manner of Lawson and Hanson's NNLS: each
step solves the equality problem on the rows held (:func:`fem.statics.solve_saddle`); a
row whose force would pull is stopped at zero by a step of the line between the last
feasible forces and the new ones, and the row whose gap is most negative is taken next.
The forces stay feasible and the energy falls at every step, so rows that hold one another
(two-pass node-to-surface contact, where both meshes touch) cannot be released and taken
in turn for ever, as an outer loop that releases every pulling row at once would.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from fem.statics import solve_saddle

__all__ = ["REPEATS", "LcpResult", "solve_lcp"]

#: Times a row may be taken again once rows are taken one at a time.
REPEATS = 3


@dataclass(frozen=True)
class LcpResult:
    """Forces of the candidate rows and the free bodies' amplitudes.

    Attributes
    ----------
    lam : ndarray, shape (m,)
        Contact forces, ``>= 0`` (zero on open rows).
    a : ndarray, shape (r,)
        Rigid-mode amplitudes.
    gap : ndarray, shape (m,)
        Linearised gaps ``W lam + G a - rhs`` (zero to round-off on closed rows).
    steps : int
        Equality solves taken.
    solved : bool
        False when the step limit stopped it first.
    """

    lam: NDArray[np.float64]
    a: NDArray[np.float64]
    gap: NDArray[np.float64]
    steps: int
    solved: bool


def solve_lcp(
    w: NDArray[np.float64],
    g: NDArray[np.float64],
    rhs: NDArray[np.float64],
    c: NDArray[np.float64],
    *,
    tol: NDArray[np.float64] | float,
    start: NDArray[np.float64] | None = None,
    load_scale: float = 0.0,
    max_steps: int | None = None,
) -> LcpResult:
    """Solve the frictionless contact LCP of candidate rows (see the module docstring).

    Parameters
    ----------
    w : ndarray, shape (m, m)
        Delassus operator (symmetric positive semi-definite).
    g : ndarray, shape (m, r)
        The rows' values of the free bodies' rigid modes.
    rhs : ndarray, shape (m,)
        Minus the gaps without contact forces.
    c : ndarray, shape (r,)
        Minus the loads in the rigid modes.
    tol : float or ndarray, shape (m,)
        A row is open when its gap is at least ``-tol`` (m).
    start : ndarray, shape (m,), optional
        Forces to start from (the last ones, for a set that grew); rows with a positive
        force start closed. By default every row starts closed, at zero force.
    load_scale : float
        Size of the loads, for the balance check of modes nothing holds.
    max_steps : int, optional
        Limit on equality solves (default ``4 m + 20``).

    Returns
    -------
    LcpResult

    Raises
    ------
    fem.LoadError
        If the closed rows cannot hold a free body whose loads are out of balance.
    """
    m = rhs.size
    tol_arr = np.broadcast_to(np.asarray(tol, dtype=np.float64), (m,))
    if start is None:
        lam = np.zeros(m)
        closed = np.ones(m, dtype=bool)
    else:
        lam = np.maximum(np.asarray(start, dtype=np.float64), 0.0)
        closed = lam > 0
        if not closed.any():
            closed[:] = True
    limit = max_steps if max_steps is not None else 4 * m + 20
    a = np.zeros(g.shape[1])
    taken = np.zeros(m, dtype=np.int64)  # times each row was taken while open
    one_at_a_time = False
    steps = 0
    solved = False
    # forces below this are round-off (a free body placed by its rigid modes at no force):
    # 1e-10 of the force that closes the deepest gap on the stiffest row
    diag = np.diag(w) if m else np.zeros(0)
    small = 1e-10 * max(
        float(np.abs(rhs).max(initial=0.0)) / max(float(diag.max(initial=0.0)), 1e-300),
        load_scale,
    )
    while steps < limit:
        idx = np.flatnonzero(closed)
        z = np.zeros(m)
        z[idx], a = solve_saddle(w[np.ix_(idx, idx)], g[idx], rhs[idx], c, load_scale)
        steps += 1
        neg = np.flatnonzero(closed & (z < -small))
        if neg.size:
            # the new forces pull on some rows: go from the last (feasible) forces towards
            # them until the first of those reaches zero; it, and any other there, opens
            step = lam[neg] / (lam[neg] - z[neg])
            first = int(np.argmin(step))
            lam = np.where(closed, lam + float(step[first]) * (z - lam), 0.0)
            opened = neg[lam[neg] <= small]
            lam[opened] = 0.0
            lam[neg[first]] = 0.0
            closed[opened] = False
            closed[neg[first]] = False
            continue
        lam = np.maximum(z, 0.0)
        gap = w @ z + g @ a - rhs
        short = ~closed & (gap < -tol_arr)
        if one_at_a_time:
            # a row taken again and again only to pull is dependent on the closed ones
            # (a node held both ways): it is left open
            short &= taken < REPEATS
        if not short.any():
            solved = True
            break
        # the open rows that penetrate: all at first, then the deepest alone once a row
        # comes back (Lawson and Hanson take one at a time, which cannot cycle)
        scaled = np.where(short, gap / np.maximum(tol_arr, 1e-300), np.inf)
        deepest = int(np.argmin(scaled))
        one_at_a_time |= bool(taken[deepest])
        chosen = np.array([deepest]) if one_at_a_time else np.flatnonzero(short)
        closed[chosen] = True
        taken[chosen] += 1
    gap = w @ lam + g @ a - rhs
    lam[lam <= small] = 0.0
    return LcpResult(lam, a, gap, steps, solved)
