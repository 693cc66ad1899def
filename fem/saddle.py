"""Constraints on a factored body: the compliance of constraint rows and the saddle point.

With ``C`` the inverse of a body's factored stiffness on its free DOFs (a free body: the
pseudo-inverse, rigid part removed), constraint rows ``E`` (``E u = g``) and a free body's
rigid modes ``Phi`` with amplitudes ``a``, the constraint forces ``lam`` solve

    [[W, G], [G^T, 0]] [lam; a] = [rhs; c],     W = E C E^T,  G = -E Phi,  c = -Phi^T f

(a held body has no ``G``: ``W lam = rhs``). ``W`` is the small dense Schur complement of
the extra prescribed DOFs on top of the one factorisation: the answer is exactly that of
re-partitioning and re-factoring, at the cost of one back-solve per new constraint row
(:class:`ConstraintRows` keeps every row's compliance; rows on DOFs marked before the
factorisation take partial solves instead). Rigid modes the constraints do not hold are
left out once the loads are checked to be in balance in them (:func:`held_modes`).
"""

from __future__ import annotations

from collections.abc import Callable
from itertools import pairwise

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from .errors import LoadError, SolverError

__all__ = [
    "BLOCK",
    "RANK_TOL",
    "ROW_CACHE",
    "ConstraintRows",
    "check_balance",
    "cholesky_or_none",
    "constraint_matrix",
    "csr_entries",
    "determinate_support",
    "free_columns",
    "held_modes",
    "rigid_body_modes",
    "rigid_part",
    "solve_saddle",
    "solve_saddle_with",
    "spd_solve",
]

#: Columns of back-solves done at once when building a Schur complement.
BLOCK = 256
#: Constraint rows whose mutual compliance is kept (a dense square of this size at most).
ROW_CACHE = 8192
#: Rigid modes whose singular value in the constraint matrix is below this fraction of the
#: largest are taken as not held (see :func:`solve_saddle`).
RANK_TOL = 1e-8


def rigid_body_modes(points: ArrayLike) -> NDArray[np.float64]:
    """Orthonormal basis of the six rigid-body displacement modes.

    Parameters
    ----------
    points : array_like, shape (N, 3)

    Returns
    -------
    ndarray, shape (3N, 6)
        Columns span the three translations and three infinitesimal rotations about the
        centroid; orthonormal.
    """
    x = np.asarray(points, dtype=np.float64)
    n = len(x)
    r = x - x.mean(axis=0)
    phi = np.zeros((n, 3, 6))
    for i in range(3):
        phi[:, i, i] = 1.0
    # rotation about axis a: u = e_a x r
    phi[:, 1, 3], phi[:, 2, 3] = -r[:, 2], r[:, 1]
    phi[:, 0, 4], phi[:, 2, 4] = r[:, 2], -r[:, 0]
    phi[:, 0, 5], phi[:, 1, 5] = -r[:, 1], r[:, 0]
    q, _ = np.linalg.qr(phi.reshape(3 * n, 6))
    return q


def rigid_part(
    points: NDArray[np.float64], u: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The rigid part ``t + omega x (x - c)`` of displacements ``u`` of ``points``.

    A least-squares fit about the centroid ``c``.

    Returns
    -------
    t : ndarray, shape (3,)
        The centroid's translation (m).
    omega : ndarray, shape (3,)
        The rotation vector (rad).
    """
    x = np.asarray(points, dtype=np.float64)
    d = np.asarray(u, dtype=np.float64).reshape(-1, 3)
    c = x.mean(axis=0)
    r = x - c
    t = d.mean(axis=0)
    j = (r * r).sum() * np.eye(3) - r.T @ r
    omega = np.linalg.solve(j, np.cross(r, d - t).sum(axis=0))
    return t, omega


def check_balance(f: NDArray[np.float64], points: ArrayLike, rtol: float = 1e-8) -> None:
    """Raise :class:`LoadError` if nodal forces are not in balance.

    The resultant force and the moment about the centroid must both vanish to ``rtol``
    relative to the total magnitude of the forces (and that times the body's size).
    """
    x = np.asarray(points, dtype=np.float64)
    fv = np.asarray(f, dtype=np.float64).reshape(-1, 3)
    r = x - x.mean(axis=0)
    force = fv.sum(axis=0)
    moment = np.cross(r, fv).sum(axis=0)
    scale = np.linalg.norm(fv, axis=1).sum()
    size = max(float(np.ptp(x, axis=0).max()), 1e-300)
    if scale == 0.0:
        return
    if np.linalg.norm(force) > rtol * scale or np.linalg.norm(moment) > rtol * scale * size:
        raise LoadError(
            "loads on a free body are not in balance: resultant force "
            f"[{force[0]:.6g}, {force[1]:.6g}, {force[2]:.6g}] N, moment about the centroid "
            f"[{moment[0]:.6g}, {moment[1]:.6g}, {moment[2]:.6g}] N m"
        )


def determinate_support(modes: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    """A free body's statically determinate support: six DOFs, and the others.

    The six DOFs span the rigid modes ``(n, 6)`` best (pivoted QR of ``modes^T``): fixing
    them removes the modes, and their reactions vanish for a balanced load.

    Returns
    -------
    support, inner : ndarray of int
        The six support DOFs and the other DOFs, both sorted.
    """
    _, _, piv = sla.qr(modes.T, mode="economic", pivoting=True)
    support = np.sort(piv[:6])
    keep = np.ones(modes.shape[0], dtype=bool)
    keep[support] = False
    return support, np.flatnonzero(keep)


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
        The factor's partial solve of columns ``(n_marked, k)`` on the marked rows.
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

    Notes
    -----
    A free body's partial solves give ``J``, the inverse on its inner DOFs (zero on its
    six support DOFs); with ``P = I - Phi Phi^T`` its compliance is
    ``r1 P J P r2 = r1 J r2 - a1 b2 - b1 a2 + a1 H a2`` where ``a = Phi^T r``,
    ``b = (J Phi)^T r`` and ``H = Phi^T J Phi``.
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
    ) -> None:
        self._inverse = inverse
        self._partial = partial
        self._frow = frow
        self._marks = marked
        self._n_factored = n_factored
        self._modes = modes
        self._j_phi = j_phi
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

    def compliance(self, ef: sp.csr_matrix) -> NDArray[np.float64]:
        """The dense compliance of rows ``ef`` over the free DOFs (indices sorted).

        Only rows not seen before cost solves; past :data:`ROW_CACHE` kept rows, the rows
        kept are forgotten first.
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
            for j in range(0, rows.shape[0], BLOCK):
                self._add_rows(rows[j : j + BLOCK])
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

    def _add_rows(self, rows: sp.csr_matrix) -> None:
        """Keep new rows and their compliance with every kept row (and each other)."""
        old = 0 if self._rows is None else self._rows.shape[0]
        k = rows.shape[0]
        rows_m, inside = self._on_marks(rows)
        self._rows = rows if self._rows is None else sp.vstack([self._rows, rows]).tocsr()
        self._rows_m = rows_m if self._rows_m is None else sp.vstack([self._rows_m, rows_m]).tocsr()
        self._inside = np.concatenate([self._inside, inside])
        total = old + k
        cross = np.zeros((total, k))
        out = np.flatnonzero(~inside)
        if out.size:
            z = self._inverse(rows[out].T.toarray())  # C r, full
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

    def _partial_cross(self, rows: sp.csr_matrix, rows_m: sp.csr_matrix) -> NDArray:
        """Compliance of the kept rows on the marks with ``rows``, from partial solves.

        A held body: ``R K11^-1 r`` needs the solution on the marked DOFs only; a free
        body: see the class's notes. Rows of the result for kept rows off the marks are
        meaningless.
        """
        z = self._partial(rows_m.T.toarray())
        cross = self._rows_m @ z
        if self._modes is not None and self._j_phi is not None:
            phi, jphi = self._modes, self._j_phi()
            a_all, b_all = self._rows @ phi, self._rows @ jphi
            a_new, b_new = rows @ phi, rows @ jphi
            h = phi.T @ jphi
            cross = cross - a_all @ b_new.T - b_all @ a_new.T + a_all @ h @ a_new.T
        return cross


def csr_entries(
    e: sp.csr_matrix, keep: NDArray[np.bool_], col: NDArray[np.int64], n_cols: int
) -> sp.csr_matrix:
    """The entries ``keep`` of ``e``, in their rows, moved to columns ``col`` (of ``n_cols``)."""
    m = e.shape[0]
    row = np.repeat(np.arange(m), np.diff(e.indptr))
    ptr = np.concatenate([[0], np.cumsum(np.bincount(row[keep], minlength=m))])
    return sp.csr_matrix((e.data[keep], col[keep], ptr), shape=(m, n_cols))


def constraint_matrix(
    extra: ArrayLike | sp.spmatrix, n: int, prescribed: NDArray[np.int64]
) -> sp.csr_matrix:
    """The ``(m, n)`` constraint matrix of extra prescribed DOFs, or of a given matrix.

    Raises
    ------
    SolverError
        On a matrix without ``n`` columns, or DOFs out of range, repeated or prescribed.
    """
    if sp.issparse(extra):
        e = sp.csr_matrix(extra, dtype=np.float64)
        if e.shape[1] != n:
            raise SolverError(f"constraint matrix must have {n} columns, got {e.shape}")
        return e
    dofs = np.asarray(extra, dtype=np.int64).ravel()
    if dofs.size and (dofs.min() < 0 or dofs.max() >= n):
        raise SolverError(f"extra prescribed DOFs must lie in 0..{n - 1}")
    if np.unique(dofs).size != dofs.size:
        raise SolverError("extra prescribed DOFs repeat a DOF")
    clash = np.intersect1d(dofs, prescribed)
    if clash.size:
        raise SolverError(f"extra prescribed DOFs {clash[:5].tolist()} are already prescribed")
    m = dofs.size
    return sp.csr_matrix((np.ones(m), (np.arange(m), dofs)), shape=(m, n))


def free_columns(e: sp.csr_matrix, pos: NDArray[np.int64], n_free: int) -> sp.csr_matrix:
    """``e``'s columns of the free DOFs (in order), indices sorted.

    ``pos`` is each DOF's position among the free ones (-1: prescribed).
    """
    if n_free == e.shape[1]:  # a copy: the rows kept share no array with e
        return e.sorted_indices() if not e.has_sorted_indices else e.copy()
    p = pos[e.indices]  # increasing with the DOF: the order is kept
    ef = csr_entries(e, p >= 0, p, n_free)
    if not e.has_sorted_indices:
        ef.sort_indices()
    return ef


def spd_solve(s: NDArray, rhs: NDArray) -> NDArray:
    """``s^-1 rhs`` by Cholesky for a symmetric positive definite compliance ``s``."""
    if s.size == 0:
        return np.zeros(0)
    try:
        c = sla.cho_factor(s)
        return sla.cho_solve(c, rhs)
    except sla.LinAlgError as exc:
        raise SolverError(
            "the extra constraints are dependent (their compliance is singular): a DOF or "
            "constraint is repeated"
        ) from exc


def solve_saddle(
    w: NDArray, g: NDArray, rhs: NDArray, c: NDArray, load_scale: float = 0.0
) -> tuple[NDArray, NDArray]:
    """Solve ``[[W, G], [G^T, 0]] [lam; a] = [rhs; c]``: constraint forces and rigid modes.

    ``W`` (m x m) is the compliance of the constraints, ``G`` (m x r) the constraints'
    values of the rigid modes, ``c`` minus the loads in the modes. Rigid modes the
    constraints do not hold (singular values of ``G`` below :data:`RANK_TOL` of the
    largest: a frictionless sphere's spin, a ball between two parallel plates sliding
    sideways) are left out with ``a = 0`` in them, once the loads are checked to be in
    balance in them. ``W`` is factored by Cholesky and the amplitudes solved from the
    small Schur complement ``G^T W^-1 G``, so that weakly held modes stay well posed.

    ``load_scale`` is the size of the loads (a norm of the load vector): the balance in
    the free modes is checked to ``1e-8`` of it (and of ``c``).

    Raises
    ------
    LoadError
        If the loads are out of balance in a mode the constraints do not hold.
    """
    m, r = g.shape
    v1 = held_modes(g, c, load_scale)
    if m == 0:
        return np.zeros(0), np.zeros(r)
    cw = cholesky_or_none(w)
    if cw is None:
        # dependent rows (a node against two facets meeting at it): least squares
        g1, c1 = g @ v1, v1.T @ c
        k = g1.shape[1]
        big = np.block([[w, g1], [g1.T, np.zeros((k, k))]])
        # complete orthogonal factorisation (QR with column pivoting): the same minimum
        # norm solution as the SVD's, in about half its time
        sol, *_ = sla.lstsq(
            big, np.concatenate([rhs, c1]), cond=1e-12, lapack_driver="gelsy", check_finite=False
        )
        return sol[:m], v1 @ sol[m:]
    return solve_saddle_with(lambda v: sla.cho_solve(cw, v), g, rhs, c, v1)


def cholesky_or_none(w: NDArray, rtol: float = 1e-12) -> tuple | None:
    """``scipy.linalg.cho_factor`` of ``w``, or None where its rows are dependent.

    Dependent rows (the same constraint twice) make ``w`` singular; round-off may still
    let the factorisation through with a pivot of round-off size. A pivot whose square
    is below ``rtol`` times the largest diagonal entry counts as zero.
    """
    try:
        cw = sla.cho_factor(w)
    except sla.LinAlgError:
        return None
    pivots = np.abs(np.diag(cw[0]))
    if pivots.size and pivots.min() ** 2 < rtol * float(np.abs(np.diag(w)).max()):
        return None
    return cw


def held_modes(g: NDArray, c: NDArray, load_scale: float = 0.0) -> NDArray:
    """The rigid modes the constraints hold: an orthonormal basis ``(r, k)`` of them.

    See :func:`solve_saddle`; checks the loads ``c`` are in balance in the others.

    Raises
    ------
    LoadError
        If the loads are out of balance in a mode the constraints do not hold.
    """
    m, r = g.shape
    if not r:
        return np.zeros((0, 0))
    sv, vt = (np.linalg.svd(g, full_matrices=False)[1:]) if m else (np.zeros(0), None)
    held = sv > RANK_TOL * sv.max() if sv.size and sv.max() > 0 else np.zeros(0, bool)
    v1 = vt[held].T if held.any() else np.zeros((r, 0))
    if v1.shape[1] == r:  # every mode held: nothing to check
        return v1
    v0 = np.linalg.svd(v1.T)[2][v1.shape[1] :].T if v1.shape[1] else np.eye(r)
    scale = max(float(np.abs(c).max(initial=0.0)), load_scale, 1e-300)
    if v0.shape[1] and np.abs(v0.T @ c).max() > 1e-8 * scale:
        raise LoadError(
            "the constraints do not hold the free body in every direction and the "
            "loads are not in balance in the free directions"
        )
    return v1


def solve_saddle_with(
    w_inv: Callable[[NDArray], NDArray], g: NDArray, rhs: NDArray, c: NDArray, v1: NDArray
) -> tuple[NDArray, NDArray]:
    """:func:`solve_saddle` with ``W^-1`` applied by ``w_inv`` and the held modes ``v1``.

    ``w_inv`` takes an ``(m,)`` or ``(m, k)`` array; ``v1`` is :func:`held_modes`'s.
    """
    if not v1.shape[1]:
        return w_inv(rhs), np.zeros(g.shape[1])
    g1, c1 = g @ v1, v1.T @ c
    both = w_inv(np.column_stack([rhs, g1]))  # one solve for both
    lam, wg = both[:, 0], both[:, 1:]
    b = np.linalg.solve(g1.T @ wg, g1.T @ lam - c1)
    return lam - wg @ b, v1 @ b
