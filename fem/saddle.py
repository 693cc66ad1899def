"""Constraints on a factored body: the compliance of constraint rows and the saddle point.

With ``C`` the inverse of a body's factored stiffness on its free DOFs (a free body: the
pseudo-inverse, rigid part removed), constraint rows ``E`` (``E u = g``) and a free body's
rigid modes ``Phi`` with amplitudes ``a``, the constraint forces ``lam`` solve

    [[W, G], [G^T, 0]] [lam; a] = [rhs; c],     W = E C E^T,  G = -E Phi,  c = -Phi^T f

(a held body has no ``G``: ``W lam = rhs``). ``W`` is the small dense Schur complement of
the extra prescribed DOFs on top of the one factorisation: the answer is exactly that of
re-partitioning and re-factoring (:mod:`fem.constraintrows` computes and keeps it). Rigid
modes the constraints do not hold are left out once the loads are checked to be in
balance in them (:func:`held_modes`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from .errors import LoadError, SolverError

__all__ = [
    "RANK_TOL",
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
    "turned_placement",
]

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


def turned_placement(
    points: ArrayLike, t: ArrayLike, omega: ArrayLike
) -> NDArray[np.float64]:
    """The 4x4 placement that turns ``points`` by the finite rotation ``omega`` and moves them.

    About their centroid ``c``: ``x -> R (x - c) + c + t``, ``R`` the rotation by
    ``|omega|`` about ``omega`` (Rodrigues): the finite motion of a :func:`rigid_part`.
    """
    c = np.asarray(points, dtype=np.float64).mean(axis=0)
    angle = float(np.linalg.norm(omega))
    rot = np.eye(3)
    if angle > 0:
        k = np.asarray(omega, dtype=np.float64) / angle
        kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
        rot = rot + np.sin(angle) * kx + (1.0 - np.cos(angle)) * kx @ kx
    out = np.eye(4)
    out[:3, :3] = rot
    out[:3, 3] = c + np.asarray(t, dtype=np.float64) - rot @ c
    return out


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
