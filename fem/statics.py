"""The partitioned static solve, and free bodies.

Given prescribed DOFs ``k`` with values ``Uk``, the system ``K U = R`` splits into
(Gourret, Magnenat-Thalmann and Thalmann 1989, equations (6) to (8))

    K11 Uu = Rk - K12 Uk        (7)
    Ru     = K21 Uu + K22 Uk    (8)

Only ``K11`` is factored, once. Extra prescribed DOFs (the contact nodes of an iteration)
are imposed on top of that factorisation through the small dense Schur complement of
:mod:`fem.saddle`: exactly the result of re-partitioning and re-factoring.

A body with no prescribed DOF is free: its stiffness has six rigid-body modes. Its
pseudo-inverse is applied exactly: a load is projected onto the balanced ones, solved on a
statically determinate support of six DOFs chosen by pivoted QR of the modes (whose
reactions vanish for a balanced load) and the rigid part of the result projected out.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from .constraintrows import ConstraintRows, back_solve_cost, factor_cost
from .errors import SolverError
from .linsolve import Factorization, factorize, resolve_backend
from .saddle import (
    check_balance,
    constraint_matrix,
    determinate_support,
    free_columns,
    rigid_body_modes,
    solve_saddle,
    spd_solve,
)

__all__ = [
    "MARK_LIMIT",
    "StaticSolution",
    "StaticSolver",
    "check_balance",
    "rigid_body_modes",
]

log = logging.getLogger(__name__)

#: Marked DOFs at most (:meth:`StaticSolver.mark`): the factor's dense trailing block,
#: whose Schur complement answers the partial solves (``fem.linsolve.SCHUR_MAX``); a row
#: off the marks costs a full solve instead. See benchmarks/results/patch.md.
MARK_LIMIT = 4800


@dataclass(frozen=True)
class StaticSolution:
    """Result of a static solve.

    Attributes
    ----------
    u : ndarray, shape (n_dofs,)
        Displacements, node-major.
    reactions : ndarray, shape (n_dofs,)
        Reactions ``K U - R`` at the prescribed DOFs (base and extra), zero elsewhere:
        the force the support exerts on the body.
    extra_reactions : ndarray, shape (m,)
        Reactions of the extra constraints, in their order (``-lambda``).
    rigid : ndarray, shape (6,)
        For a free body, the coefficients of the rigid-body modes in ``u``; else empty.
    """

    u: NDArray[np.float64]
    reactions: NDArray[np.float64]
    extra_reactions: NDArray[np.float64]
    rigid: NDArray[np.float64]


class StaticSolver:
    """Factor a body once; solve for many loads and changing extra prescribed DOFs.

    Parameters
    ----------
    stiffness : scipy.sparse matrix, shape (n, n)
        The assembled symmetric stiffness.
    prescribed : array_like of int, optional
        The base prescribed DOFs (e.g. bone nodes); ``K11`` over the others is factored.
        Empty: a free body, and ``points`` is required.
    points : array_like, shape (n/3, 3), optional
        Node coordinates, for the rigid-body modes of a free body.
    backend : str
        Linear solver name (see :func:`fem.factorize`).
    hold_rotation : bool
        Free body only: the extra constraints place it by its translations, its rotations
        held at zero (the moment they and the loads leave is not resolved): frictionless
        contact on a ball holds its spin only by discretisation effects, which a linear
        solve turns into large spurious rotations.
    lazy : bool
        Factor on first use (or :meth:`factorize`) instead of now, so that the DOFs
        where constraints will act can be marked first (:meth:`mark`).

    Notes
    -----
    Marked DOFs (:meth:`mark`) are ordered last by the factorisation (PARDISO): the
    compliance of constraint rows on them comes from its trailing block; a row off them
    costs a back-solve, and once those have cost a factorisation, they are marked too
    and the body refactored (:mod:`fem.constraintrows`).

    Examples
    --------
    >>> import numpy as np, fem
    >>> mesh = fem.box_mesh((1, 1, 1), (2, 2, 2))
    >>> K = fem.assemble_stiffness(mesh, fem.LinearElastic(1e6, 0.3))
    >>> fixed = fem.node_dofs(np.flatnonzero(mesh.points[:, 2] == 0))
    >>> s = fem.StaticSolver(K, fixed)
    >>> sol = s.solve(np.zeros(K.shape[0]))
    >>> float(abs(sol.u).max())
    0.0
    """

    def __init__(
        self,
        stiffness: sp.spmatrix,
        prescribed: ArrayLike | None = None,
        *,
        points: ArrayLike | None = None,
        backend: str = "auto",
        hold_rotation: bool = False,
        lazy: bool = False,
    ) -> None:
        k = sp.csr_matrix(stiffness, dtype=np.float64)
        n = k.shape[0]
        if k.shape != (n, n):
            raise SolverError(f"stiffness must be square, got shape {k.shape}")
        self.k = k
        self.n = n
        pres = np.unique(np.asarray([] if prescribed is None else prescribed, dtype=np.int64))
        if pres.size and (pres[0] < 0 or pres[-1] >= n):
            raise SolverError(f"prescribed DOFs must lie in 0..{n - 1}, got {pres[0]}..{pres[-1]}")
        self.prescribed = pres
        mask = np.ones(n, dtype=bool)
        mask[pres] = False
        self.free = np.flatnonzero(mask)
        self._pos = np.full(n, -1, dtype=np.int64)
        self._pos[self.free] = np.arange(self.free.size)
        self.free_body = pres.size == 0
        self.points = None if points is None else np.asarray(points, dtype=np.float64)
        if self.free_body:
            if self.points is None or self.points.shape != (n // 3, 3):
                raise SolverError(
                    "a body with no prescribed DOF is free: give its points (n/3, 3) so that "
                    "its rigid-body modes can be removed"
                )
            self.modes = rigid_body_modes(self.points)
            # the first three columns span the translations (QR keeps leading spans)
            self.placing_modes = self.modes[:, :3] if hold_rotation else self.modes
            self._support, self._inner = determinate_support(self.modes)
            self._to_factor = k[self._inner][:, self._inner]
            # row of the factored matrix of each free DOF (-1: a support DOF)
            self._frow = np.full(n, -1, dtype=np.int64)
            self._frow[self._inner] = np.arange(self._inner.size)
        else:
            self.modes = np.zeros((n, 0))
            self.placing_modes = self.modes
            k_free = k[self.free]
            self._k11 = k_free[:, self.free]
            self._k12 = k_free[:, pres]
            self._k_pres = k[pres]  # rows K21 | K22 of equation (8)
            self._to_factor = self._k11
            self._frow = np.arange(self.free.size)
        self.backend = resolve_backend(backend)
        self.n_back_solves = 0
        self.n_partial_solves = 0
        self.n_factorizations = 0
        self.factor_time = 0.0
        self._last_factor = 0.0
        self._factorization: Factorization | None = None
        self._marks = np.zeros(0, np.int64)
        self._jphi: NDArray[np.float64] | None = None
        # loads to solve with the factorisation, and their answer once solved
        self._anticipated: tuple[NDArray, NDArray | None] | None = None
        # the constraint rows kept: a new factorisation answers them anew
        self._constraints: ConstraintRows | None = None
        if not lazy:
            self.factorize()

    # --- the factorisation ------------------------------------------------------------

    def factorize(self) -> StaticSolver:
        """Factor now (with the DOFs marked so far) if not yet done; return self.

        A free body with marked DOFs solves ``J Phi`` (:meth:`modes_response`, which its
        partial solves need), and any body the loads it was told of (:meth:`anticipate`), with
        the factorisation's test solve: the factor is read once for all
        (:func:`fem.linsolve.factorize`'s ``rhs``).
        """
        if self._factorization is None:
            t = time.perf_counter()
            n_modes = self.modes.shape[1] if self.free_body and self._marks.size else 0
            cols = [self.modes[self._inner]] if n_modes else []
            known = self._anticipated
            if known is not None:
                cols.append(self._to_solve(known[0])[:, None])
            rhs = np.hstack(cols) if cols else None
            f = factorize(self._to_factor, self.backend, marked=self._marks, rhs=rhs)
            self._factorization = f
            self._last_factor = time.perf_counter() - t
            self.factor_time += self._last_factor
            self.n_factorizations += 1
            self._jphi = None
            if f.first is not None:
                if n_modes:
                    self._jphi = np.zeros_like(self.modes)
                    self._jphi[self._inner] = f.first[:, :n_modes]
                if known is not None:
                    self._anticipated = (known[0], self._finish(known[0], f.first[:, -1]))
                self.n_back_solves += f.first.shape[1]
            self._constraints = None
        return self

    @property
    def _fact(self) -> Factorization:
        return self.factorize()._factorization  # type: ignore[return-value]

    @property
    def factored_matrix(self) -> sp.csr_matrix:
        """The matrix factored: ``K11`` (a free body: ``K`` less its six support DOFs)."""
        return self._to_factor

    @property
    def marked(self) -> NDArray[np.int64]:
        """Rows of :attr:`factored_matrix` marked for partial solves (see :meth:`mark`)."""
        return self._marks

    @property
    def marked_dofs(self) -> NDArray[np.int64]:
        """Global DOFs marked for partial solves, sorted (see :meth:`mark`)."""
        inner = self._inner if self.free_body else np.arange(self.free.size)
        return np.sort(self.free[inner[self._marks]])

    @property
    def prescribed_rows(self) -> sp.csr_matrix:
        """Rows ``K21 | K22`` of the prescribed DOFs (kept): their reactions are ``K_p u - f_p``."""
        return sp.csr_matrix((0, self.n)) if self.free_body else self._k_pres

    @property
    def factored(self) -> bool:
        """Whether the stiffness is factored (a lazy solver is not until first used)."""
        return self._factorization is not None

    def mark_capacity(self, limit: int | None = None) -> int:
        """Most DOFs :meth:`mark` takes: ``limit`` (default :data:`MARK_LIMIT`), <= n / 2."""
        return min(MARK_LIMIT if limit is None else limit, self._to_factor.shape[0] // 2)

    def mark(self, dofs: ArrayLike, limit: int | None = None) -> bool:
        """Mark DOFs where constraint rows will act, for partial solves on them.

        Before the factorisation, free; after it, DOFs not marked yet cost a new
        factorisation with all marked. Prescribed DOFs and a free body's six support
        DOFs are skipped. Nothing is marked when the total would pass ``limit`` (the
        trailing block of the factor grows with its square) or when the backend has no
        partial solves.

        Returns
        -------
        bool
            Whether the marked DOFs cover ``dofs``.
        """
        d = np.asarray(dofs, dtype=np.int64).ravel()
        if d.size and (d.min() < 0 or d.max() >= self.n):
            raise SolverError(f"marked DOFs must lie in 0..{self.n - 1}")
        rows = self._frow_of(d)
        return self._mark_rows(rows[rows >= 0], limit)

    def _mark_rows(self, rows: NDArray[np.int64], limit: int | None = None) -> bool:
        """:meth:`mark` of rows of the factored matrix."""
        union = np.union1d(self._marks, rows)
        if self.backend != "pardiso" or union.size > self.mark_capacity(limit):
            return False
        if union.size == self._marks.size:
            return True
        self._marks = union
        if self._factorization is not None:
            log.debug("refactoring with %d marked DOFs", union.size)
            self._factorization = None
            self.factorize()
        return True

    def _frow_of(self, dofs: NDArray[np.int64]) -> NDArray[np.int64]:
        """Rows of the factored matrix of global DOFs (-1: prescribed or support)."""
        pos = self._pos[dofs]
        out = np.full(dofs.shape, -1, dtype=np.int64)
        ok = pos >= 0
        out[ok] = self._frow[pos[ok]]
        return out

    # --- the inverse on the free DOFs ----------------------------------------------

    def apply_inverse(self, r: NDArray[np.float64]) -> NDArray[np.float64]:
        """``K11^-1 r`` on the free DOFs (a free body: ``K^+ r``, rigid part removed).

        ``r`` has shape ``(n_free,)`` or ``(n_free, k)``.
        """
        r = np.asarray(r, dtype=np.float64)
        fact = self._fact  # factored now if not yet: anticipated loads solved with it
        known = self._anticipated
        if known is not None and known[1] is not None and np.array_equal(r, known[0]):
            return known[1].copy()
        return self._finish(r, fact.solve(self._to_solve(r)))

    def _to_solve(self, r: NDArray[np.float64]) -> NDArray[np.float64]:
        """The right-hand side of the factored matrix that :meth:`apply_inverse` solves."""
        if not self.free_body:
            return r
        if self._marks.size:
            # J P r = J r - (J Phi) a: r itself stays nonzero on the contact zone only
            # (marked: a short forward sweep), J Phi is kept for the partial solves
            return r[self._inner]
        return (r - self.modes @ (self.modes.T @ r))[self._inner]

    def _finish(self, r: NDArray[np.float64], z: NDArray[np.float64]) -> NDArray[np.float64]:
        """:meth:`apply_inverse` of ``r`` from the solution ``z`` of :meth:`_to_solve`."""
        if not self.free_body:
            return z
        phi = self.modes
        x = np.zeros_like(r)
        x[self._inner] = z
        if self._marks.size:
            x[self._inner] -= self.modes_response()[self._inner] @ (phi.T @ r)
        return x - phi @ (phi.T @ x)

    def anticipate(self, r: ArrayLike) -> None:
        """Solve ``r`` (over the free DOFs) with the coming factorisation.

        The factor is then read once for its test solve, ``J Phi`` and ``r`` (a body's
        own loads, whose answer every contact frame asks for first); :meth:`apply_inverse`
        of the same vector reads it back. Nothing is done once factored, or for a zero
        ``r``.
        """
        v = np.array(r, dtype=np.float64)
        if v.shape != (self.free.size,):
            raise SolverError(
                f"anticipated loads must have shape ({self.free.size},), got {v.shape}"
            )
        if self._factorization is None and v.any():
            self._anticipated = (v, None)

    # --- constraints -----------------------------------------------------------------

    def compliance(self, extra: ArrayLike | sp.spmatrix) -> NDArray[np.float64]:
        """The dense compliance ``E K11^-1 E^T`` (free body: ``E K^+ E^T``) of constraints.

        ``extra`` is a list of DOFs or a sparse ``(m, n)`` constraint matrix. The
        compliance of every row met is kept: only new rows cost back-solves.
        """
        e = constraint_matrix(extra, self.n, self.prescribed)
        return self._schur_of(e)[0]

    def _schur_of(self, e: sp.csr_matrix) -> tuple[NDArray, NDArray | None]:
        """Compliance of constraint rows (see :class:`fem.constraintrows.ConstraintRows`).

        Also, for a free body, the rows' values ``E Phi`` of the placing rigid modes.
        """
        rows = free_columns(e, self._pos, self.free.size)
        self.factorize()
        s = None  # None: rows off the marks widened them (refactored): ask again
        while s is None:
            if self._constraints is None:
                self._constraints = ConstraintRows(
                    self._counted_inverse, self._partial_solve, self._frow, self._fact.marked,
                    self._to_factor.shape[0], modes=self.modes if self.free_body else None,
                    j_phi=self.modes_response if self.free_body else None,
                    widen=self._mark_rows, buy=self._factor_cost(),
                    column=back_solve_cost(self._fact),
                )  # fmt: skip
            s = self._constraints.compliance(rows)
        return s, (e @ self.placing_modes) if self.free_body else None

    def _factor_cost(self) -> float:
        return factor_cost(self._fact)  # what widening the marks costs, in operations

    def _counted_inverse(self, r: NDArray[np.float64]) -> NDArray[np.float64]:
        """:meth:`apply_inverse` of columns ``(n_free, k)``, counted as back-solves."""
        z = self.apply_inverse(r)
        self.n_back_solves += r.shape[1]
        return z

    def _partial_solve(self, b: NDArray[np.float64]) -> NDArray[np.float64]:
        """The factor's solve of columns on the marked rows, counted as partial solves."""
        z = self._fact.solve_marked(b)  # type: ignore[attr-defined]
        self.n_partial_solves += z.shape[1]
        return z

    def modes_response(self) -> NDArray[np.float64]:
        """``J Phi``: a free body's inverse with its support held, of its rigid modes (kept)."""
        if self._jphi is None:
            x = np.zeros_like(self.modes)
            x[self._inner] = self._fact.solve(self.modes[self._inner])
            self.n_back_solves += self.modes.shape[1]
            self._jphi = x
        return self._jphi

    # --- the solve -------------------------------------------------------------------

    def solve(
        self,
        loads: ArrayLike | None = None,
        values: ArrayLike | None = None,
        *,
        extra: ArrayLike | sp.spmatrix | None = None,
        extra_values: ArrayLike | None = None,
    ) -> StaticSolution:
        """Solve ``K U = R`` with the base and optional extra prescribed DOFs.

        Parameters
        ----------
        loads : array_like, shape (n,), optional
            Known nodal loads ``R`` (zero by default). For a free body with no extra
            constraint they must be in balance.
        values : array_like, optional
            Values ``Uk`` of the base prescribed DOFs (shape ``(n_prescribed,)``, in
            sorted DOF order) or a full ``(n,)`` vector from which they are taken; zero
            by default.
        extra : array_like of int or sparse matrix, optional
            Extra prescribed DOFs, or an ``(m, n)`` constraint matrix ``E`` (``E U = g``).
        extra_values : array_like, shape (m,), optional
            Their values ``g``; zero by default.

        Returns
        -------
        StaticSolution

        Raises
        ------
        LoadError
            Unbalanced loads on a free body, or constraints that leave a rigid mode free
            while the load is out of balance in it.
        """
        n = self.n
        f = np.zeros(n) if loads is None else np.asarray(loads, dtype=np.float64)
        if f.shape != (n,):
            raise SolverError(f"loads must have shape ({n},), got {f.shape}")
        uk = self._values(values)
        u = np.zeros(n)
        u[self.prescribed] = uk
        rf = f[self.free]
        if self.prescribed.size:
            rf = rf - self._k12 @ uk
        rigid = np.zeros(0)
        lam = np.zeros(0)
        e = None
        if extra is None or (not sp.issparse(extra) and np.size(extra) == 0):
            if self.free_body:
                check_balance(f, self.points)
            u[self.free] = self.apply_inverse(rf)
        else:
            e = constraint_matrix(extra, self.n, self.prescribed)
            m = e.shape[0]
            g = np.zeros(m) if extra_values is None else np.asarray(extra_values, float)
            if g.shape != (m,):
                raise SolverError(f"extra_values must have shape ({m},), got {g.shape}")
            if self.prescribed.size:
                g = g - e[:, self.prescribed] @ uk
            s, e_phi = self._schur_of(e)
            ef = e[:, self.free]
            x0 = self.apply_inverse(rf)
            rhs = ef @ x0 - g
            if self.free_body:
                phi = self.placing_modes
                # [[S, -E Phi], [-(E Phi)^T, 0]] [lam; a] = [rhs; -Phi^T f]
                lam, a = solve_saddle(s, -e_phi, rhs, -(phi.T @ f), float(np.linalg.norm(f)))
                u[self.free] = self.apply_inverse(rf - ef.T @ lam) + phi @ a
                rigid = np.zeros(6)
                rigid[: a.size] = a
            else:
                lam = spd_solve(s, rhs)
                u[self.free] = self.apply_inverse(rf - ef.T @ lam)
        reactions = np.zeros(n)
        if self.prescribed.size:
            kr = self._k_pres
            reactions[self.prescribed] = kr @ u - f[self.prescribed]  # equation (8)
        if e is not None and lam.size:
            reactions -= e.T @ lam
        if self.free_body and rigid.size == 0:
            rigid = np.zeros(6)
        return StaticSolution(u=u, reactions=reactions, extra_reactions=-lam, rigid=rigid)

    def _values(self, values: ArrayLike | None) -> NDArray[np.float64]:
        npres = self.prescribed.size
        v = np.zeros(npres) if values is None else np.asarray(values, dtype=np.float64)
        if v.shape == (self.n,):
            return v[self.prescribed]
        if v.shape != (npres,):
            raise SolverError(
                f"prescribed values must have shape ({npres},) or ({self.n},), got {v.shape}"
            )
        return v
