"""The compliance of constraint rows on a factored body, kept for every row met.

With ``C`` the inverse of a body's factored stiffness on its free DOFs (a free body: the
pseudo-inverse, rigid part removed), the compliance ``W = E C E^T`` of constraint rows
``E`` is the Schur complement of extra prescribed DOFs on top of the one factorisation
(:mod:`fem.saddle`). Rows on DOFs marked before the factorisation take partial solves
through its trailing block; a row off them a back-solve, until those have cost a
factorisation: then the marks are widened and the body refactored. The costs are the
factor's operation counts, not times: the same rows take the same path on any machine,
at any load.
"""

from __future__ import annotations

import inspect
import weakref
from collections.abc import Callable
from itertools import pairwise
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from .saddle import csr_entries

if TYPE_CHECKING:
    from .linsolve import Factorization

__all__ = [
    "BLOCK",
    "FACTOR_OVERHEAD",
    "ROW_CACHE",
    "ConstraintRows",
    "back_solve_cost",
    "factor_cost",
]

#: Back-solves done at once when building a Schur complement (rows on the marks: all).
BLOCK = 256
#: Constraint rows whose mutual compliance is kept (a dense square of this size at most).
ROW_CACHE = 8192
#: What a factorisation costs besides its operations (the ordering, the set-up), in
#: back-solves: with it, the operation counts that decide between renting back-solves and
#: refactoring follow the times measured with PARDISO on 4k to 35k DOFs (a factorisation
#: 134 to 259 block back-solves long).
FACTOR_OVERHEAD = 60


def back_solve_cost(fact: Factorization) -> float:
    """Operations of one back-solve: the factor's nonzeros twice, a multiply and an add each."""
    return 4.0 * fact.factor_nnz


def factor_cost(fact: Factorization) -> float:
    """Operations of a factorisation (``factor_flops``), its set-up counted in back-solves."""
    return fact.factor_flops + FACTOR_OVERHEAD * back_solve_cost(fact)


def _weak(f: Callable | None) -> Callable | None:
    """A bound method, called without holding its object.

    The solver that owns these rows hands them its methods: held strongly, they would
    close a cycle through it, and its factorisation would wait for the garbage collector.
    """
    if f is None or not inspect.ismethod(f):
        return f
    ref = weakref.WeakMethod(f)

    def call(*args: object, **kwargs: object) -> object:
        return ref()(*args, **kwargs)  # type: ignore[misc]

    return call


class ConstraintRows:
    """The compliance ``R C R^T`` of constraint rows, kept for every row met.

    The compliance between two rows depends on those rows alone, so it is kept for every
    row met so far: a contact set that gains or loses a few nodes costs a few solves, not
    one per contact DOF. A row on marked DOFs only takes a partial solve; a row off them a
    full back-solve, whose answer is kept to give its compliance with the rows met later.
    One object serves one factorisation.

    Parameters
    ----------
    inverse : callable
        ``C r`` of columns ``(n_free, k)`` over the free DOFs: full back-solves.
    partial : callable
        The factor's partial solve of columns ``(n_marked, k)`` on the marked rows (given
        sparse, answered dense).
    frow : ndarray of int, shape (n_free,)
        Row of the factored matrix of each free DOF (-1: a free body's support DOF).
    marked : ndarray of int
        Rows of the factored matrix marked for partial solves (those of the factor).
    n_factored : int
        Rows of the factored matrix.
    modes : ndarray, shape (n_free, 6), optional
        A free body's rigid modes ``Phi`` (None: a held body).
    j_phi : callable, optional
        A free body's ``J Phi``: the inverse on its inner DOFs applied to ``Phi``.
    widen : callable, optional
        Marks the factored matrix's rows it is given too and refactors, returning
        whether it did (see the notes).
    buy : float
        Floating-point operations of the factorisation (what ``widen`` costs).
    column : float
        Floating-point operations of one back-solve (a column of ``inverse``,
        :func:`back_solve_cost`).

    Notes
    -----
    A free body's partial solves give ``J``, the inverse on its inner DOFs (zero on its
    six support DOFs); with ``P = I - Phi Phi^T`` its compliance is
    ``r1 P J P r2 = r1 J r2 - a1 b2 - b1 a2 + a1 H a2`` where ``a = Phi^T r``,
    ``b = (J Phi)^T r`` and ``H = Phi^T J Phi``.

    Rows off the marks (a contact patch grown past its marked zone) are rented: each
    costs a back-solve. Once the back-solves have cost more than the factorisation,
    the next rows off the marks buy instead: the DOFs of every row off the marks are
    marked and the body refactored (``widen``), and :meth:`compliance` answers None
    (ask the new factorisation). Rent then never passes the price of a factorisation by
    more than one block of back-solves: the ski-rental rule, at most about twice the
    cost of knowing the rows beforehand, with no estimate of either cost.
    """

    def __init__(
        self,
        inverse: Callable[[NDArray], NDArray],
        partial: Callable[[NDArray], NDArray],
        frow: NDArray[np.int64],
        marked: NDArray[np.int64],
        n_factored: int,
        modes: NDArray[np.float64] | None = None,
        j_phi: Callable[[], NDArray[np.float64]] | None = None,
        widen: Callable[[NDArray[np.int64]], bool] | None = None,
        buy: float = np.inf,
        column: float = 0.0,
    ) -> None:
        self._inverse = _weak(inverse)
        self._widen = _weak(widen)
        self._buy = buy
        self._column = column
        #: Floating-point operations of back-solves so far (rows off the marks).
        self.rent = 0.0
        self._partial = _weak(partial)
        self._frow = frow
        self._marks = marked
        self._n_factored = n_factored
        self._modes = modes
        self._j_phi = _weak(j_phi)
        self.reset()

    def reset(self) -> None:
        """Forget every row kept."""
        self._row_index: dict[bytes, int] = {}
        self._rows: sp.csr_matrix | None = None
        self._rows_m: sp.csr_matrix | None = None
        self._inside = np.zeros(0, dtype=bool)
        self._zout = np.zeros((0, 0))  # C r of the kept rows off the marks
        self._out_rows = np.zeros(0, dtype=np.int64)
        self._gram = np.zeros((0, 0))

    def compliance(self, ef: sp.csr_matrix) -> NDArray[np.float64] | None:
        """The dense compliance of rows ``ef`` over the free DOFs (indices sorted).

        Only rows not seen before cost solves; past :data:`ROW_CACHE` kept rows, the rows
        kept are forgotten first. None when the rows widened the marks (the body is
        refactored: this object is spent).
        """
        m = ef.shape[0]
        # a row's key: its (free) columns and values, as bytes cut from the whole arrays
        ind = ef.indices.astype(np.int64).tobytes()
        dat = ef.data.tobytes()
        ptr = (8 * ef.indptr).tolist()
        keys = [ind[a:b] + dat[a:b] for a, b in pairwise(ptr)]
        new = list(dict.fromkeys(k for k in keys if k not in self._row_index))
        if new:
            if len(self._row_index) + len(new) > ROW_CACHE:
                self.reset()
                new = list(dict.fromkeys(keys))
            if len(new) == m:  # every row new and different: all of them, in order
                rows = ef
            else:
                first = {k: i for i, k in reversed(list(enumerate(keys)))}
                rows = ef[[first[k] for k in new]]
            # pieces of at most BLOCK rows off the marks (back-solves, rent checked
            # between them); rows on the marks need no such cut
            off = np.flatnonzero(~self._on_marks(rows)[1])
            cuts = [0, *off[BLOCK::BLOCK].tolist(), rows.shape[0]]
            for a, b in pairwise(cuts):
                if not self._add_rows(rows[a:b]):
                    return None
            for k in new:
                self._row_index[k] = len(self._row_index)
        idx = np.array([self._row_index[k] for k in keys], dtype=np.int64)
        s = self._gram[np.ix_(idx, idx)]
        return 0.5 * (s + s.T)

    def _on_marks(self, rows: sp.csr_matrix) -> tuple[sp.csr_matrix, NDArray[np.bool_]]:
        """Rows (over the free DOFs) on the marked DOFs' numbering, and which lie on them.

        A free body's support DOFs count as marked: its inner inverse is zero there.
        """
        marks = self._marks
        k = rows.shape[0]
        if not marks.size:
            return sp.csr_matrix((k, 0)), np.zeros(k, dtype=bool)
        where = np.full(self._n_factored, -1, dtype=np.int64)
        where[marks] = np.arange(marks.size)
        row = np.repeat(np.arange(k), np.diff(rows.indptr))
        frow = self._frow[rows.indices]
        sup = frow < 0
        col = where[np.where(sup, 0, frow)]
        off = ~sup & (col < 0)
        inside = np.ones(k, dtype=bool)
        inside[row[off]] = False
        return csr_entries(rows, ~sup & ~off, col, marks.size), inside

    def _add_rows(self, rows: sp.csr_matrix) -> bool:
        """Keep new rows and their compliance with every kept row (and each other).

        False, with nothing kept, when the rows off the marks widened them instead.
        """
        old = 0 if self._rows is None else self._rows.shape[0]
        k = rows.shape[0]
        rows_m, inside = self._on_marks(rows)
        if not inside.all() and self.rent > self._buy and self._widen is not None:
            off = (
                rows[~inside]
                if self._rows is None
                else sp.vstack([self._rows[self._out_rows], rows[~inside]])
            )
            frow = self._frow[off.indices]
            if self._widen(np.unique(frow[frow >= 0])):
                return False
            self._widen = None  # refused (past the marks' capacity): rent from now on
        self._rows = rows if self._rows is None else sp.vstack([self._rows, rows]).tocsr()
        self._rows_m = rows_m if self._rows_m is None else sp.vstack([self._rows_m, rows_m]).tocsr()
        self._inside = np.concatenate([self._inside, inside])
        total = old + k
        cross = np.zeros((total, k))
        out = np.flatnonzero(~inside)
        if out.size:
            z = self._inverse(rows[out].T.toarray())  # C r, full
            self.rent += self._column * out.size
            cross[:, out] = self._rows @ z
            self._zout = np.hstack([self._zout, z]) if self._zout.size else z
            self._out_rows = np.concatenate([self._out_rows, old + out])
        inn = np.flatnonzero(inside)
        if inn.size:
            kept_in = np.flatnonzero(self._inside)
            part = self._partial_cross(rows[inn], rows_m[inn])  # (total, k_in)
            cross[np.ix_(kept_in, inn)] = part[kept_in]
            if self._out_rows.size:
                # rows off the marks: their kept answers C r give the compliance
                cross[np.ix_(self._out_rows, inn)] = (rows[inn] @ self._zout).T
        if self._gram.shape[0] < total:
            grown = np.zeros((max(total, 2 * self._gram.shape[0]),) * 2)
            grown[:old, :old] = self._gram[:old, :old]
            self._gram = grown
        cols = slice(old, total)
        self._gram[:total, cols] = cross
        self._gram[cols, :total] = cross.T
        return True

    def _partial_cross(self, rows: sp.csr_matrix, rows_m: sp.csr_matrix) -> NDArray:
        """Compliance of the kept rows on the marks with ``rows``, from partial solves.

        A held body: ``R K11^-1 r`` needs the solution on the marked DOFs only; a free
        body: see the class's notes. Rows of the result for kept rows off the marks are
        meaningless.
        """
        z = self._partial(rows_m.T)  # sparse: a gather of the inverse, once it is made
        cross = self._rows_m @ z
        if self._modes is not None and self._j_phi is not None:
            phi, jphi = self._modes, self._j_phi()
            a_all, b_all = self._rows @ phi, self._rows @ jphi
            a_new, b_new = rows @ phi, rows @ jphi
            h = phi.T @ jphi
            cross = cross - a_all @ b_new.T - b_all @ a_new.T + a_all @ h @ a_new.T
        return cross
