"""Frictionless contact forces of a linearised contact set: a bounded QP in contact space.

For candidate rows whose compliance ``W`` is known (:mod:`contact.solver.delassus`), the forces
``lambda`` and the free bodies' rigid-mode amplitudes ``a`` solve the linear
complementarity problem of frictionless contact::

    gap = W lambda + G a - rhs >= 0,   lambda >= 0,   lambda . gap = 0,   G^T lambda = c

which is the optimality condition of the convex quadratic programme

    min  1/2 lambda^T W lambda - rhs^T lambda   s.t.  lambda >= 0,  G^T lambda = c.

It is solved by a primal active-set method in the manner of Lawson and Hanson's NNLS: each
step solves the equality problem on the rows held (:func:`fem.saddle.solve_saddle_with`,
bordering the last Cholesky factorisation of their ``W``); a row whose force would pull
is stopped at zero by a step of the line between the last feasible forces and the new
ones, and the row whose gap is most negative is taken next (all penetrating rows at once
at first). A row whose ``W`` repeats closed rows' (a node held both ways) is not closed
beside them: the force moves onto it along the null direction until one of them opens.
The forces stay feasible and the energy falls at every step, so rows that hold one another
(two-pass node-to-surface contact, where both meshes touch) cannot be released and taken
in turn for ever, as an outer loop that releases every pulling row at once would.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
from numpy.typing import NDArray

from fem.errors import LoadError
from fem.saddle import cholesky_or_none, held_modes, solve_saddle, solve_saddle_with
from fem.threads import dense_threads

__all__ = ["REFACTOR", "REPEATS", "LcpResult", "solve_lcp"]

#: Times a row may be taken again once rows are taken one at a time.
REPEATS = 3
#: The closed rows' compliance is factored again when the rows opened and closed since
#: its last factorisation pass this fraction of them (or 16); until then each step
#: borders the last factorisation with those rows.
REFACTOR = 0.1


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
        force start closed. By default the rows that penetrate without forces start
        closed (every row where none does), at zero force: rows that start open do not
        make the first step's equality problem dependent (a node near four planes has
        four rows on its three DOFs), and the first equality problem is smaller.
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
        If the closed rows cannot hold a free body whose loads are out of balance: the
        rows that started closed, then every row (the body moves until they touch), and
        then those of them that do not pull.
    """
    with dense_threads(np.size(rhs)):  # small dense work: one BLAS thread
        return _active_set(w, g, rhs, c, tol, start, load_scale, max_steps)


def _active_set(
    w: NDArray[np.float64],
    g: NDArray[np.float64],
    rhs: NDArray[np.float64],
    c: NDArray[np.float64],
    tol: NDArray[np.float64] | float,
    start: NDArray[np.float64] | None,
    load_scale: float,
    max_steps: int | None,
) -> LcpResult:
    """:func:`solve_lcp`'s primal active-set iteration."""
    m = rhs.size
    tol_arr = np.broadcast_to(np.asarray(tol, dtype=np.float64), (m,))
    if start is None:
        lam = np.zeros(m)
        closed = rhs > tol_arr  # the rows that penetrate without forces
        if not closed.any():
            closed[:] = True
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
    closed_solve = _ClosedSolver(w, g, rhs, c, load_scale)
    batch: NDArray[np.int64] | None = None  # the rows the last step closed at once
    widened = False
    while steps < limit:
        idx = np.flatnonzero(closed)
        z = np.zeros(m)
        try:
            z[idx], a = closed_solve(idx)
        except LoadError:
            # the closed rows leave a loaded body free (a ball the pads press, its
            # weight on a table row that starts open): it moves until the open rows
            # touch, so they close too, once; then what pulls opens as always
            if widened or closed.all():
                raise
            widened, closed[:] = True, True
            continue
        steps += 1
        if not closed_solve.exact and batch is not None:
            # rows closed together that repeat one another: taken one at a time instead
            closed[batch] = False
            taken[batch] -= 1
            one_at_a_time, batch = True, None
            continue
        batch = None
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
        if one_at_a_time:
            swap = _swap(closed_solve, w, idx, deepest, lam, small)
            if swap is not None:
                # the row repeats closed ones: their force moves onto it until one of
                # them reaches zero and opens
                lam, out = swap
                closed[out] = False
            closed[deepest] = True
            taken[deepest] += 1
        else:
            batch = np.flatnonzero(short)
            closed[batch] = True
            taken[batch] += 1
    gap = w @ lam + g @ a - rhs
    lam[lam <= small] = 0.0
    return LcpResult(lam, a, gap, steps, solved)


def _swap(
    solver: _ClosedSolver,
    w: NDArray,
    idx: NDArray[np.int64],
    j: int,
    lam: NDArray,
    small: float,
) -> tuple[NDArray, int] | None:
    """A step along the null direction of closed rows ``idx`` that row ``j`` repeats.

    When ``W_j`` is a combination ``W_C coef`` of the closed rows, closing ``j`` would make
    the equality problem singular; moving force ``t`` onto ``j`` and ``t coef`` off the
    closed rows changes no gap and lowers the energy while ``j`` penetrates. The step
    stops where the first closed row reaches zero force: that row opens. Returns the new
    forces and the row that opens, or None if ``j`` does not repeat them.
    """
    if not idx.size:
        return None
    op = solver.operator(idx)
    if op is None:
        return None
    coef = op(w[idx, j])
    own = float(w[j, j] - w[j, idx] @ coef)
    if own > 1e-10 * float(w[j, j]):
        return None
    pos = coef > 1e-12 * float(np.abs(coef).max())
    if not pos.any():
        return None
    ratio = lam[idx][pos] / coef[pos]
    k = int(np.argmin(ratio))
    t = float(ratio[k])
    lam = lam.copy()
    lam[idx] -= t * coef
    lam[j] = t
    out = int(idx[np.flatnonzero(pos)[k]])
    lam[out] = 0.0
    lam[np.abs(lam) <= small] = 0.0
    return lam, out


class _ClosedSolver:
    """The equality problem on a set of closed rows, for sets that change a few rows a step.

    ``W`` of a base set ``B`` is factored once (Cholesky); a set ``C`` differing from it by
    rows ``A`` added and ``D`` removed is solved by bordering that factorisation::

        [W_BB  W_BA  E_D] [x_B]   [v_B]
        [W_AB  W_AA   0 ] [x_A] = [v_A]      (x_D = 0 through the multipliers mu)
        [E_D^T  0     0 ] [mu ]   [ 0 ]

    through its Schur complement on ``A`` and ``D``: a step costs back-solves with the
    base factor (``|B|^2`` each) instead of a factorisation (``|C|^3 / 3``). The base is
    factored again when ``|A| + |D|`` passes ``REFACTOR |B|`` (or 16 rows).
    """

    def __init__(self, w: NDArray, g: NDArray, rhs: NDArray, c: NDArray, load_scale: float) -> None:
        self.w, self.g, self.rhs, self.c, self.load_scale = w, g, rhs, c, load_scale
        self.base = np.zeros(0, dtype=np.int64)
        self._in_base = np.zeros(rhs.size, dtype=bool)
        self.factor: tuple | None = None
        self.cols: dict[int, NDArray] = {}  # W_BB^-1 of each border column, by row
        self.exact = True
        self._last: tuple[NDArray[np.int64], Callable[[NDArray], NDArray] | None] | None = None

    def _refactor(self, idx: NDArray[np.int64]) -> bool:
        self.factor = cholesky_or_none(self.w[np.ix_(idx, idx)])
        if self.factor is None:
            return False
        self.base = idx
        self._in_base[:] = False
        self._in_base[idx] = True
        self.cols = {}
        return True

    def operator(self, idx: NDArray[np.int64]) -> Callable[[NDArray], NDArray] | None:
        """``v -> W_CC^-1 v`` for the closed rows ``idx`` (sorted); None if dependent.

        The last one is kept: a step's solve and its dependence test (:func:`_swap`) ask
        for the same rows.
        """
        if self._last is not None and np.array_equal(self._last[0], idx):
            return self._last[1]
        op = self._operator(idx)
        self._last = (idx.copy(), op)
        return op

    def _operator(self, idx: NDArray[np.int64]) -> Callable[[NDArray], NDArray] | None:
        closed = np.zeros(self._in_base.size, dtype=bool)
        closed[idx] = True
        kept = closed[self.base]
        added = idx[~self._in_base[idx]]  # sorted, as idx and the base are
        removed = self.base[~kept]
        if self.factor is not None and added.size + removed.size <= max(16, REFACTOR * idx.size):
            try:
                return self._inverse(idx, added, removed, kept)
            except np.linalg.LinAlgError:
                pass  # a row added that repeats the base's: factored anew below
        if not self._refactor(idx):
            return None
        none = np.zeros(0, dtype=np.int64)
        return self._inverse(idx, none, none, np.ones(idx.size, dtype=bool))

    def __call__(self, idx: NDArray[np.int64]) -> tuple[NDArray, NDArray]:
        """Forces and rigid-mode amplitudes with the rows ``idx`` closed.

        Sets :attr:`exact` False where the rows are dependent and were solved by least
        squares.
        """
        g, c = self.g[idx], self.c
        v1 = held_modes(g, c, self.load_scale)
        self.exact = True
        if not idx.size:
            return np.zeros(0), np.zeros(g.shape[1])
        rhs = self.rhs[idx]
        op = self.operator(idx)
        if op is None:
            # dependent rows (a node held both ways): least squares
            self.exact = False
            return solve_saddle(self.w[np.ix_(idx, idx)], g, rhs, c, self.load_scale)
        return solve_saddle_with(op, g, rhs, c, v1)

    def _columns(self, added: NDArray, removed: NDArray) -> NDArray:
        """``W_BB^-1`` of the border columns: added rows' ``W``, removed rows' unit vectors.

        Each row's column is kept while the base stands; the missing ones are solved
        together (one back-solve with many right-hand sides).
        """
        keys = [int(r) for r in added] + [-int(r) - 1 for r in removed]
        missing = [k for k in keys if k not in self.cols]
        if missing:
            rhs = np.zeros((self.base.size, len(missing)))
            for j, k in enumerate(missing):
                if k >= 0:
                    rhs[:, j] = self.w[self.base, k]
                else:
                    rhs[np.searchsorted(self.base, -k - 1), j] = 1.0
            sol = sla.cho_solve(self.factor, rhs)
            for j, k in enumerate(missing):
                self.cols[k] = sol[:, j]
        return np.column_stack([self.cols[k] for k in keys])

    def _inverse(
        self, idx: NDArray, added: NDArray, removed: NDArray, kept: NDArray[np.bool_]
    ) -> Callable[[NDArray], NDArray]:
        """``v -> W_CC^-1 v`` for the closed rows ``idx`` (sorted).

        ``kept`` tells which rows of the base are among them.
        """
        factor, base, w = self.factor, self.base, self.w
        if not added.size and not removed.size:
            return lambda v: sla.cho_solve(factor, v)
        na, nd = added.size, removed.size
        u = np.zeros((base.size, na + nd))
        u[:, :na] = w[np.ix_(base, added)]
        u[np.searchsorted(base, removed), na + np.arange(nd)] = 1.0
        y = self._columns(added, removed)
        z = np.zeros((na + nd, na + nd))
        z[:na, :na] = w[np.ix_(added, added)]
        t = z - u.T @ y
        own = np.diag(t)[:na]  # each added row's compliance left once the base holds
        if (own <= 1e-10 * np.diag(z)[:na]).any():  # a row added that repeats the base's
            raise np.linalg.LinAlgError("an added row depends on the base rows")
        in_base = np.searchsorted(idx, base[kept])
        pos_base = np.flatnonzero(kept)
        pos_added = np.searchsorted(idx, added)

        def apply(v: NDArray) -> NDArray:
            v = np.asarray(v, dtype=np.float64)
            shape = v.shape
            v2 = v.reshape(idx.size, -1)
            vb = np.zeros((base.size, v2.shape[1]))
            vb[pos_base] = v2[in_base]
            wb = sla.cho_solve(factor, vb)
            rhs = np.zeros((na + nd, v2.shape[1]))
            rhs[:na] = v2[pos_added]
            rhs -= u.T @ wb
            sol = np.linalg.solve(t, rhs)
            xb = wb - y @ sol
            out = np.empty_like(v2)
            out[in_base] = xb[pos_base]
            out[pos_added] = sol[:na]
            return out.reshape(shape)

        return apply
