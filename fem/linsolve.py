"""Sparse direct solvers behind one small interface, selectable by name.

``"pardiso"``: Intel MKL PARDISO through pypardiso (Cholesky for symmetric positive
definite matrices, multithreaded, METIS ordering); the default where it is installed.
``"superlu"``: scipy's SuperLU, always available; the fallback.
``"auto"``: the first of these that is available.
"""

from __future__ import annotations

import glob
import importlib.util
import logging
import os
import sys
from typing import Protocol

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import NDArray

from .errors import SolverError

__all__ = ["BACKENDS", "Factorization", "available_backends", "factorize"]

log = logging.getLogger(__name__)


class Factorization(Protocol):
    """A factorised square matrix that solves for many right-hand sides."""

    n: int
    backend: str

    def solve(self, b: NDArray[np.float64]) -> NDArray[np.float64]:
        """Solve ``A x = b`` for ``b`` of shape ``(n,)`` or ``(n, k)``."""
        ...


class _Pardiso:
    """MKL PARDISO, real symmetric positive definite (mtype 2), upper triangle stored."""

    backend = "pardiso"

    def __init__(self, a: sp.csr_matrix) -> None:
        import pypardiso

        self.n = a.shape[0]
        self._a = sp.triu(a, format="csr")
        self._a.sort_indices()
        if not np.diff(self._a.indptr).all():
            row = int(np.flatnonzero(np.diff(self._a.indptr) == 0)[0])
            raise SolverError(f"matrix is singular: row {row} is empty (an unconnected DOF?)")
        self._s = _new_pardiso(pypardiso)
        self._s.set_phase(12)
        try:
            self._s._call_pardiso(self._a, np.zeros((self.n, 1)))
        except pypardiso.pardiso_wrapper.PyPardisoError as exc:
            raise SolverError(
                f"PARDISO could not factor the matrix ({exc}): it is singular or not positive "
                "definite; is the body free to move? prescribe displacements that hold it, "
                "or solve it as a free body"
            ) from exc
        self._s.set_phase(33)

    def solve(self, b: NDArray[np.float64]) -> NDArray[np.float64]:
        b = np.asfortranarray(b, dtype=np.float64)
        x = self._s._call_pardiso(self._a, b)
        return x

    def __del__(self) -> None:
        s = getattr(self, "_s", None)
        if s is not None:
            try:
                s.free_memory(everything=True)
            except Exception:  # never raise from a destructor
                pass


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

    def __init__(self, a: sp.csr_matrix) -> None:
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
        piv = np.abs(self._lu.U.diagonal())
        if piv.size and piv.min() <= 1e-12 * piv.max():
            raise SolverError(
                f"SuperLU found the matrix singular (pivot ratio {piv.min() / piv.max():.2e}): "
                "is the body free to move? prescribe displacements that hold it, or solve it "
                "as a free body"
            )

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


def factorize(a: sp.spmatrix, backend: str = "auto") -> Factorization:
    """Factor a sparse symmetric positive definite matrix.

    Parameters
    ----------
    a : scipy.sparse matrix, shape (n, n)
        Symmetric positive definite.
    backend : {"auto", "pardiso", "superlu"}
        Which solver; ``"auto"`` takes the first available in :func:`available_backends`.

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
    names = available_backends()
    if backend == "auto":
        backend = names[0]
    if backend not in BACKENDS:
        raise SolverError(
            f"unknown linear solver {backend!r}; choose from auto, {', '.join(BACKENDS)}"
        )
    if backend not in names:
        raise SolverError(f"linear solver {backend!r} is not available here; available: {names}")
    a = sp.csr_matrix(a, dtype=np.float64)
    if a.shape[0] == 0:
        return _Empty()
    log.debug("factoring %d x %d matrix (%d nonzeros) with %s", *a.shape, a.nnz, backend)
    return BACKENDS[backend](a)


class _Empty:
    """The factorisation of a 0x0 matrix (everything prescribed)."""

    n = 0
    backend = "none"

    def solve(self, b: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.zeros_like(np.asarray(b, dtype=np.float64))
