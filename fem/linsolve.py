"""Sparse direct solvers behind one small interface, selectable by name.

``"pardiso"``: Intel MKL PARDISO through pypardiso (Cholesky for symmetric positive
definite matrices, multithreaded, METIS ordering); the default where it is installed.
``"superlu"``: scipy's SuperLU, always available; the fallback.
``"auto"``: the first of these that is available.
"""

from __future__ import annotations

import ctypes
import glob
import importlib.util
import logging
import os
import sys
from typing import Protocol

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import ArrayLike, NDArray

from .errors import SolverError

__all__ = ["BACKENDS", "Factorization", "available_backends", "factorize", "resolve_backend"]

log = logging.getLogger(__name__)

#: Largest relative residual of the test solve after a factorisation (see
#: ``_Pardiso._check_regular``).
REGULAR_RESIDUAL = 1e-6
#: Most values of each full-length work array a partial solve keeps (see
#: ``_Pardiso.solve_marked``): 4 M values, 32 MB.
PARTIAL_WORK = 4_000_000
#: Most columns of one partial solve call. The work arrays are fresh memory for each
#: factorisation, and wide ones cost page faults (in PARDISO too) on their first call:
#: narrow chunks are several times faster on a large body's first contact set.
PARTIAL_COLUMNS = 64
#: Most marked DOFs whose Schur complement PARDISO returns with the factorisation
#: (``iparm[35] = 2``): its dense Cholesky then answers every partial solve (``m^3 / 3``
#: flops once, ``m^2`` a column after, in BLAS 3), where a partial solve per column walks
#: the factor's trailing block. Above it the dense block (``8 m^2`` bytes) is too big.
SCHUR_MAX = 6000


class Factorization(Protocol):
    """A factorised square matrix that solves for many right-hand sides."""

    n: int
    backend: str
    #: DOFs whose partial solves :meth:`solve_marked` serves (empty: none).
    marked: NDArray[np.int64]
    #: Solutions of the right-hand sides handed to :func:`factorize` (None: none given).
    first: NDArray[np.float64] | None
    #: Nonzeros of the factor, and floating-point operations of the factorisation: what a
    #: back-solve and a factorisation cost, the same on any machine.
    factor_nnz: int
    factor_flops: float

    def solve(self, b: NDArray[np.float64]) -> NDArray[np.float64]:
        """Solve ``A x = b`` for ``b`` of shape ``(n,)`` or ``(n, k)``."""
        ...


class _Pardiso:
    """MKL PARDISO, real symmetric positive definite (mtype 2), upper triangle stored.

    ``marked`` DOFs (optional) are ordered last by the reordering, so that a right-hand
    side nonzero only on them whose solution is wanted only on them is a partial solve
    (``iparm[30] = 1``) through the trailing block of the factor: its cost grows with
    the square of the marked count, not with the factor's size (see :meth:`solve_marked`).
    """

    backend = "pardiso"

    def __init__(
        self,
        a: sp.csr_matrix,
        marked: NDArray[np.int64] | None = None,
        rhs: NDArray[np.float64] | None = None,
    ) -> None:
        import pypardiso

        self.n = a.shape[0]
        self._a = sp.triu(a, format="csr")
        self._a.sort_indices()
        if not np.diff(self._a.indptr).all():
            row = int(np.flatnonzero(np.diff(self._a.indptr) == 0)[0])
            raise SolverError(f"matrix is singular: row {row} is empty (an unconnected DOF?)")
        # one-based CSR index arrays for MKL, made once (pypardiso remakes them every call)
        self._ia = (self._a.indptr + 1).astype(np.int32)
        self._ja = (self._a.indices + 1).astype(np.int32)
        self._s = _new_pardiso(pypardiso)
        iparm = self._s.iparm
        iparm[:] = 0
        iparm[0] = 1  # the values below, not MKL's defaults
        iparm[1] = 2  # METIS nested dissection
        iparm[17] = -1  # report the factor's nonzeros
        iparm[18] = -1  # and its Gflop
        self.marked = np.zeros(0, np.int64) if marked is None else np.unique(marked)
        # full-length arrays of the partial solves, kept between calls (_partial_work)
        self._work: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
        self._mask = np.zeros(self.n, dtype=np.int32)
        m = self.marked.size
        # the marked block's Schur complement, dense, and its Cholesky (made on first use),
        # then its inverse (once the columns asked pass a third of its size)
        self._schur: NDArray[np.float64] | None = None
        self._schur_cho: tuple[NDArray[np.float64], bool] | None = None
        self._schur_inv: NDArray[np.float64] | None = None
        self._schur_cols = 0
        out = np.zeros(self.n)
        if m:
            self._mask[self.marked] = 1
            iparm[30] = 1
            if m <= SCHUR_MAX:
                iparm[35] = 2  # the Schur complement, the whole factor kept too
                out = np.zeros(max(self.n, m * m))
        perm = self._mask.copy()  # the reordering overwrites it
        try:
            self._call(12, np.zeros(self.n), out, perm)
        except pypardiso.pardiso_wrapper.PyPardisoError as exc:
            raise SolverError(
                f"PARDISO could not factor the matrix ({exc}): it is singular or not positive "
                "definite; is the body free to move? prescribe displacements that hold it, "
                "or solve it as a free body"
            ) from exc
        self.factor_nnz = int(iparm[17])
        self.factor_flops = 1e6 * float(iparm[18])  # reported in MFlop
        if iparm[35] == 2:
            self._schur = out[: m * m].reshape(m, m)
            iparm[35] = 0
        self.first = self._check_regular(a, rhs)

    def _check_regular(
        self, a: sp.csr_matrix, rhs: NDArray[np.float64] | None = None
    ) -> NDArray[np.float64] | None:
        """Refuse a singular matrix whose pivots round to tiny positive values.

        Cholesky stops at a zero or negative pivot, but a free mode of a stiffness (a
        body held at one node, free to turn) can leave pivots of round-off size and
        either sign. Their inverse floods a solve: the residual of one solve with a
        fixed right-hand side tells (about 1e-12 for a regular stiffness, order one
        for a singular one), at the cost of one solve. Right-hand sides ``rhs`` wanted
        right after the factorisation share its sweeps through the factor (read once for
        all): their solutions are returned.
        """
        b = np.random.default_rng(0).standard_normal(self.n)
        first = None
        if rhs is None:
            x = self.solve(b)
        else:
            both = self.solve(np.column_stack([b, rhs.reshape(self.n, -1)]))
            x, first = both[:, 0], both[:, 1:].reshape(rhs.shape)
        res = float(np.linalg.norm(a @ x - b)) / float(np.linalg.norm(b))
        if not (res <= REGULAR_RESIDUAL):
            raise SolverError(
                f"matrix is singular: a test solve leaves a residual of {res:.1e} (PARDISO "
                "met round-off pivots); is the body free to move? prescribe displacements "
                "that hold it, or solve it as a free body"
            )
        return first

    def _call(self, phase: int, b: NDArray, x: NDArray, perm: NDArray[np.int32]) -> None:
        import pypardiso

        s = self._s
        err = ctypes.c_int32(0)
        i32 = ctypes.POINTER(ctypes.c_int32)
        f64 = ctypes.POINTER(ctypes.c_double)
        nrhs = 1 if b.ndim == 1 else b.shape[1]
        s._mkl_pardiso(
            s.pt.ctypes.data_as(ctypes.POINTER(s._pt_type[0])),
            ctypes.byref(ctypes.c_int32(1)),  # maxfct
            ctypes.byref(ctypes.c_int32(1)),  # mnum
            ctypes.byref(ctypes.c_int32(2)),  # mtype: real SPD
            ctypes.byref(ctypes.c_int32(phase)),
            ctypes.byref(ctypes.c_int32(self.n)),
            self._a.data.ctypes.data_as(f64),
            self._ia.ctypes.data_as(i32),
            self._ja.ctypes.data_as(i32),
            perm.ctypes.data_as(i32),
            ctypes.byref(ctypes.c_int32(nrhs)),
            s.iparm.ctypes.data_as(i32),
            ctypes.byref(ctypes.c_int32(0)),  # no messages
            b.ctypes.data_as(f64),
            x.ctypes.data_as(f64),
            ctypes.byref(err),
        )
        if err.value != 0:
            raise pypardiso.pardiso_wrapper.PyPardisoError(err.value)

    def solve(self, b: NDArray[np.float64]) -> NDArray[np.float64]:
        """Solve ``A x = b``; a ``b`` nonzero on marked DOFs only skips most of the forward sweep.

        Such a right-hand side (contact forces on a marked contact zone) touches only the
        trailing block of the factor in the forward substitution (``iparm[30] = 2``); the
        backward substitution is the full one.
        """
        b = np.asfortranarray(b, dtype=np.float64)
        x = np.zeros_like(b, order="F")
        sparse = False
        if self.marked.size:
            nz = b != 0 if b.ndim == 1 else np.any(b != 0, axis=1)
            sparse = not np.any(nz & (self._mask == 0))
        self._s.iparm[30] = 2 if sparse else 0
        try:
            self._call(33, b, x, self._mask)
        finally:
            self._s.iparm[30] = 0
        return np.ascontiguousarray(x)

    def solve_marked(self, b: NDArray[np.float64] | sp.spmatrix) -> NDArray[np.float64]:
        """The solution on the marked DOFs of a right-hand side nonzero only on them.

        ``b`` has shape ``(m,)`` or ``(m, k)``, one row per marked DOF (in the sorted
        order of :attr:`marked`), dense or sparse; the result is dense, of its shape.

        PARDISO reads and writes full-length vectors even here: they are kept between
        calls (the columns taken in chunks of at most :data:`PARTIAL_COLUMNS`, and of
        :data:`PARTIAL_WORK` values), so a call touches little fresh memory and writes
        only the marked rows of a right-hand side that stays zero elsewhere.
        """
        if not sp.issparse(b):
            b = np.asarray(b, dtype=np.float64)
        m = self.marked.size
        if b.shape[0] != m or b.ndim not in (1, 2):
            raise SolverError(f"partial solve: expected {m} rows (the marked DOFs), got {b.shape}")
        if self._schur is not None:
            return self._schur_solve(b)
        if sp.issparse(b):
            b = b.toarray()
        cols = b.reshape(m, -1)
        k = cols.shape[1]
        out = np.empty((m, k))
        chunk = max(1, min(k, PARTIAL_COLUMNS, PARTIAL_WORK // max(self.n, 1)))
        rhs, x = self._partial_work(chunk)
        self._s.iparm[30] = 1
        try:
            for j in range(0, k, chunk):
                c = min(chunk, k - j)
                rb, xb = rhs[:, :c], x[:, :c]
                rb[self.marked] = cols[:, j : j + c]
                self._call(33, rb, xb, self._mask)
                out[:, j : j + c] = xb[self.marked]
        finally:
            self._s.iparm[30] = 0
        return out[:, 0] if b.ndim == 1 else out

    def _schur_solve(self, b: NDArray[np.float64] | sp.spmatrix) -> NDArray[np.float64]:
        """``S^-1 b`` from the marked block's Schur complement ``S`` (kept, replaced in place).

        Its Cholesky answers a column in ``2 m^2`` flops. Once the columns asked pass
        ``m / 3`` (their cost that of the inverse, ``2 m^3 / 3``), the inverse is made
        from it and kept: a sparse column (a contact row: a few entries) then costs a
        gather of as many of its columns.
        """
        import scipy.linalg as sla

        if self._schur_inv is None:
            if self._schur_cho is None:  # in place: one dense block kept
                self._schur_cho = sla.cho_factor(
                    self._schur, lower=True, overwrite_a=True, check_finite=False
                )
            self._schur_cols += 1 if b.ndim == 1 else b.shape[1]
            m = self.marked.size
            if 3 * self._schur_cols <= m:
                dense = b.toarray() if sp.issparse(b) else b
                return sla.cho_solve(self._schur_cho, dense, check_finite=False)
            low, info = sla.lapack.dpotri(self._schur_cho[0], lower=1, overwrite_c=1)
            if info != 0:
                raise SolverError(f"the marked block's inverse failed (LAPACK info {info})")
            full = _lower_to_full(low)  # LAPACK's column order: its transpose is C order
            self._schur_inv = self._schur = full.T if full.flags.f_contiguous else full
            self._schur_cho = None
        if sp.issparse(b):
            out = (sp.csr_matrix(b.T) @ self._schur_inv).T  # S^-1 symmetric
            return np.ascontiguousarray(out).reshape(b.shape)
        return self._schur_inv @ b

    def _partial_work(self, k: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Kept right-hand side (zero off the marks) and solution arrays, ``(n, >= k)``."""
        work = self._work
        if work is None or work[0].shape[1] < k:
            work = (np.zeros((self.n, k), order="F"), np.zeros((self.n, k), order="F"))
            self._work = work
        return work

    def __del__(self) -> None:
        s = getattr(self, "_s", None)
        if s is not None:
            try:
                s.free_memory(everything=True)
            except Exception:  # never raise from a destructor
                pass


def _lower_to_full(a: NDArray[np.float64], block: int = 512) -> NDArray[np.float64]:
    """The symmetric matrix whose lower triangle ``a`` holds, made in place (by blocks)."""
    m = a.shape[0]
    for j in range(0, m, block):
        e = min(j + block, m)
        d = a[j:e, j:e]
        d[np.triu_indices(e - j, 1)] = d.T[np.triu_indices(e - j, 1)]
        a[j:e, e:] = a[e:, j:e].T
    return a


def _new_pardiso(pypardiso: object) -> object:
    """A PyPardisoSolver for real SPD matrices (mtype 2).

    pypardiso searches the environment tree for the MKL runtime on every construction
    (about 0.4 s); the path found first is handed to later ones via PYPARDISO_MKL_RT.
    """
    solver = pypardiso.PyPardisoSolver(mtype=2)  # type: ignore[attr-defined]
    name = getattr(solver.libmkl, "_name", None)
    if name and "PYPARDISO_MKL_RT" not in os.environ:
        os.environ["PYPARDISO_MKL_RT"] = name
    return solver


class _SuperLU:
    """scipy's SuperLU with a symmetric ordering."""

    backend = "superlu"
    marked = np.zeros(0, np.int64)

    def __init__(self, a: sp.csr_matrix, rhs: NDArray[np.float64] | None = None) -> None:
        self.n = a.shape[0]
        try:
            self._lu = spla.splu(
                sp.csc_matrix(a),
                permc_spec="MMD_AT_PLUS_A",
                diag_pivot_thresh=0.0,
                options={"SymmetricMode": True},
            )
        except RuntimeError as exc:
            raise SolverError(
                f"SuperLU could not factor the matrix ({exc}): it is singular; is the body "
                "free to move? prescribe displacements that hold it, or solve it as a free body"
            ) from exc
        lower, upper = self._lu.L.tocsc(), self._lu.U.tocsr()
        self.factor_nnz = int(lower.nnz + upper.nnz)
        # a column's update: its entries below the diagonal times its row's to the right
        self.factor_flops = 2.0 * float(np.diff(lower.indptr) @ np.diff(upper.indptr))
        piv = np.abs(self._lu.U.diagonal())
        if piv.size and piv.min() <= 1e-12 * piv.max():
            raise SolverError(
                f"SuperLU found the matrix singular (pivot ratio {piv.min() / piv.max():.2e}): "
                "is the body free to move? prescribe displacements that hold it, or solve it "
                "as a free body"
            )
        self.first = None if rhs is None else self.solve(rhs)

    def solve(self, b: NDArray[np.float64]) -> NDArray[np.float64]:
        x = self._lu.solve(np.asarray(b, dtype=np.float64))
        if not np.isfinite(x).all():
            raise SolverError("SuperLU returned non-finite values: the matrix is singular")
        return x


BACKENDS: dict[str, type] = {"pardiso": _Pardiso, "superlu": _SuperLU}


def _locate_mkl_runtime() -> None:
    """Point pypardiso at the MKL runtime of this environment, if it is where pip puts it.

    Otherwise pypardiso walks the whole environment tree with a recursive glob on import
    and on every solver it creates (about 0.4 s each).
    """
    if "PYPARDISO_MKL_RT" in os.environ:
        return
    for prefix in dict.fromkeys((sys.prefix, sys.base_prefix)):
        found = sorted(glob.glob(os.path.join(prefix, "lib", "libmkl_rt.so*")), key=len)
        if found:
            os.environ["PYPARDISO_MKL_RT"] = found[0]
            return


def available_backends() -> list[str]:
    """Names of the backends usable here, in order of preference."""
    out = []
    _locate_mkl_runtime()
    if importlib.util.find_spec("pypardiso") is not None:
        try:
            import pypardiso  # noqa: F401

            out.append("pardiso")
        except ImportError:  # MKL runtime missing
            pass
    out.append("superlu")
    return out


def resolve_backend(backend: str = "auto") -> str:
    """The backend ``backend`` names (``"auto"``: the first available).

    Raises
    ------
    SolverError
        Unknown or unavailable backend.
    """
    names = available_backends()
    if backend == "auto":
        backend = names[0]
    if backend not in BACKENDS:
        raise SolverError(
            f"unknown linear solver {backend!r}; choose from auto, {', '.join(BACKENDS)}"
        )
    if backend not in names:
        raise SolverError(f"linear solver {backend!r} is not available here; available: {names}")
    return backend


def factorize(
    a: sp.spmatrix,
    backend: str = "auto",
    marked: NDArray[np.int64] | None = None,
    rhs: ArrayLike | None = None,
) -> Factorization:
    """Factor a sparse symmetric positive definite matrix.

    Parameters
    ----------
    a : scipy.sparse matrix, shape (n, n)
        Symmetric positive definite.
    backend : {"auto", "pardiso", "superlu"}
        Which solver; ``"auto"`` takes the first available in :func:`available_backends`.
    marked : array_like of int, optional
        Rows whose partial solves are wanted (``solve_marked``: right-hand sides and
        solutions on them only); PARDISO orders them last. Ignored by SuperLU (its
        ``marked`` stays empty).
    rhs : array_like, shape (n,) or (n, k), optional
        Right-hand sides to solve at once: their solutions are the result's ``first``
        (PARDISO solves them in the sweeps of its test solve: the factor is read once).

    Returns
    -------
    Factorization
        Reusable for any number of right-hand sides.

    Raises
    ------
    SolverError
        Unknown or unavailable backend, or a singular matrix.
    """
    if a.shape[0] != a.shape[1]:
        raise SolverError(f"matrix must be square, got shape {a.shape}")
    backend = resolve_backend(backend)
    a = sp.csr_matrix(a, dtype=np.float64)
    b = None if rhs is None else np.asarray(rhs, dtype=np.float64)
    if b is not None and (b.ndim not in (1, 2) or b.shape[0] != a.shape[0]):
        raise SolverError(f"right-hand sides must have {a.shape[0]} rows, got shape {b.shape}")
    if a.shape[0] == 0:
        return _Empty(b)
    log.debug("factoring %d x %d matrix (%d nonzeros) with %s", *a.shape, a.nnz, backend)
    if backend == "pardiso":
        m = None if marked is None or not np.size(marked) else np.asarray(marked, dtype=np.int64)
        return _Pardiso(a, m, b)
    return BACKENDS[backend](a, b)


class _Empty:
    """The factorisation of a 0x0 matrix (everything prescribed)."""

    n = 0
    backend = "none"
    marked = np.zeros(0, np.int64)
    factor_nnz = 0
    factor_flops = 0.0

    def __init__(self, rhs: NDArray[np.float64] | None = None) -> None:
        self.first = None if rhs is None else np.zeros_like(rhs)

    def solve(self, b: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.zeros_like(np.asarray(b, dtype=np.float64))
