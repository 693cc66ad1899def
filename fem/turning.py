"""A free body whose stiffness sees its turns: the exact inverse through the modes' border.

A free body's linear stiffness has its six rigid modes ``Phi`` as null space, and
:class:`fem.StaticSolver` applies its pseudo-inverse. A finite-strain tangent at a stressed
placement has none: turning the body turns its forces, ``S = K Phi != 0`` for the turns
(the translations still move nothing), and ``K`` is invertible, definite or not. With
``J`` the inverse with the six support DOFs of :func:`fem.saddle.determinate_support`
held (zero rows and columns there), every ``u`` is ``Phi a`` plus a part zero on the
support, and ``K u = f`` reads::

    u = J f + Psi a,     H a = Psi^T f,     Psi = Phi - J S,     H = Phi^T S - S^T J S

``H`` (6 x 6, symmetric) is the stiffness of the modes once the rest has relaxed: zero for
a linear body (then ``Psi = Phi`` and ``H a = 0`` is the loads' balance), negative along a
turn that the forces' arms would drive (a squeezed ball) and positive where they resist
it (a hanging one). The solver factors the matrix with that support held: its
pseudo-inverse is ``C = P J P`` (``P`` the projection off the modes), and with ``J Phi``
(:meth:`fem.StaticSolver.modes_response`) it gives::

    J = C + J Phi Phi^T + Phi (J Phi)^T - Phi (Phi^T J Phi) Phi^T

so that a constraint's compliance ``E J E^T`` is the solver's ``E C E^T`` (partial solves,
rows kept) plus ``Z N Z^T``, ``Z = [E J Phi, E Phi]`` and ``N = [[0, I], [I, -M]]``,
``M = Phi^T J Phi``. A contact solve keeps ``E C E^T`` (the linear body's, well scaled:
``J`` alone moves the body about its support) and borders it with twelve more columns
``Z``, whose amplitudes ``t`` solve ``Z^T lambda - N^-1 t = -N^-1 k`` (:meth:`extended`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from .errors import SolverError
from .statics import StaticSolver

__all__ = ["TurningInverse"]


class TurningInverse:
    """The exact inverse of a free body's stiffness that does not vanish on its turns.

    Parameters
    ----------
    solver : StaticSolver
        A free body's solver (no prescribed DOF), its stiffness a tangent.

    Attributes
    ----------
    psi : ndarray, shape (n, 6)
        The modes' columns ``Psi = Phi - J S``: a mode's motion with the rest relaxed.
    h : ndarray, shape (6, 6)
        The modes' stiffness ``H`` (symmetric; N per unit amplitude).
    phi_psi : ndarray, shape (6, 6)
        ``Phi^T Psi``: the rigid part of the modes' columns (the identity for a linear
        body).

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp, fem
    >>> mesh = fem.box_mesh((1, 1, 1), (1, 1, 1))
    >>> k = fem.assemble_stiffness(mesh, fem.LinearElastic(1e3, 0.3)) + sp.identity(24)
    >>> t = fem.TurningInverse(fem.StaticSolver(k, points=mesh.points))
    >>> f = np.arange(24.0)
    >>> u = t.inverse(f) + t.psi @ np.linalg.solve(t.h, t.psi.T @ f)
    >>> bool(np.allclose(k @ u, f))
    True
    """

    def __init__(self, solver: StaticSolver) -> None:
        if not solver.free_body:
            raise SolverError("a turning inverse is of a free body (no prescribed DOF)")
        self.solver = solver
        phi = solver.modes
        self._phi = phi
        self._jphi = solver.modes_response()
        self._m = phi.T @ self._jphi
        self._m = (self._m + self._m.T) / 2
        s = np.asarray(solver.k @ phi)
        js = self.inverse(s)
        self.psi = phi - js
        self.phi_psi = phi.T @ self.psi
        h = phi.T @ s - s.T @ js
        self.h = (h + h.T) / 2

    def inverse(self, r: ArrayLike) -> NDArray[np.float64]:
        """``J r``: the body's answer to loads ``r`` ``(n,)`` or ``(n, k)``, its support held."""
        r = np.asarray(r, dtype=np.float64)
        if not r.any():
            return np.zeros_like(r)
        phi, b = self._phi, self._jphi
        pr = phi.T @ r
        return self.solver.apply_inverse(r) + b @ pr + phi @ (b.T @ r - self._m @ pr)

    @property
    def width(self) -> int:
        """Columns of :meth:`extended`: the six modes and the twelve of ``Z``."""
        return 18

    def extended(
        self, e: sp.spmatrix, loads: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """The border of constraint rows ``E`` on the solver's compliance ``E C E^T``.

        With ``lambda`` the rows' forces, ``a`` the modes' amplitudes and ``t`` those of
        ``Z`` (see the module docstring), and ``rhs = -(g0 + E C b)`` for loads ``b``::

            E C E^T lambda + G x = rhs,   G^T lambda - H x = c,   x = [a; t]

        is ``K u = b + E^T lambda`` with the rows' values ``E u + g0`` and
        ``u = J (b + E^T lambda) + Psi a`` (:meth:`displacement`).

        Returns
        -------
        g : ndarray, shape (m, 18)
            ``[E Psi, E J Phi, E Phi]``.
        h : ndarray, shape (18, 18)
            ``H`` and ``N^-1 = [[M, I], [I, 0]]`` on the diagonal.
        c : ndarray, shape (18,)
            ``-Psi^T b`` and ``-N^-1 k``, ``k = [Phi^T b, (J Phi)^T b - M Phi^T b]``.
        """
        b = np.asarray(loads, dtype=np.float64)
        phi, jphi, m6 = self._phi, self._jphi, self._m
        e = sp.csr_matrix(e)
        g = np.hstack([np.asarray(e @ self.psi), np.asarray(e @ jphi), np.asarray(e @ phi)])
        n_inv = np.block([[m6, np.eye(6)], [np.eye(6), np.zeros((6, 6))]])
        h = np.zeros((18, 18))
        h[:6, :6] = self.h
        h[6:, 6:] = n_inv
        pb = phi.T @ b
        k = np.concatenate([pb, jphi.T @ b - m6 @ pb])
        return g, h, -np.concatenate([self.psi.T @ b, n_inv @ k])

    def displacement(self, f: ArrayLike, x: ArrayLike) -> NDArray[np.float64]:
        """``u = J f + Psi a`` under loads ``f``, ``x`` the amplitudes ``[a; t]`` or ``a``."""
        return self.inverse(f) + self.psi @ np.asarray(x, dtype=np.float64)[:6]

    def rigid_part(self, f: ArrayLike, a: ArrayLike) -> NDArray[np.float64]:
        """``Phi^T u`` of :meth:`displacement`: its part along the modes."""
        return self._jphi.T @ np.asarray(f, dtype=np.float64) + self.phi_psi @ np.asarray(a)[:6]

    def solve(self, f: ArrayLike) -> NDArray[np.float64]:
        """``K^-1 f`` (a check of the border: the contact solves use its parts)."""
        f = np.asarray(f, dtype=np.float64)
        return self.inverse(f) + self.psi @ np.linalg.solve(self.h, self.psi.T @ f)
