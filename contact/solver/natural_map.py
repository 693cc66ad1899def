"""The Alart-Curnier natural map of Coulomb friction on a linearised contact set.

Its roots are the solutions of the frictional contact problem of
:mod:`contact.solver.friction` (Alart and Curnier 1991); its generalised Jacobian is that
of the primal-dual active set method of Hueber, Stadler and Wohlmuth (2008), with their
slip derivative.
"""

from __future__ import annotations

import copy

import numpy as np
from numpy.typing import NDArray

__all__ = ["DEGENERATE", "NaturalMap"]

#: A contact's tangential compliance block below this fraction of the largest diagonal
#: is taken as held both ways (no friction there).
DEGENERATE = 1e-10


class NaturalMap:
    """The natural map ``F`` of one contact set and its generalised Jacobian.

    The unknowns are the row forces ``lambda`` (M) and the rigid-mode amplitudes ``a``
    (r). With ``spring > 0`` each free body is held by a spring of that stiffness in its
    modes: the balance row reads ``G^T lambda - c - spring a = 0``, a problem that has a
    solution whether or not the contacts hold the body, and tends to the unsprung one as
    the spring vanishes (see :func:`contact.solver.friction.solve_friction`). ``h``: the
    modes' own stiffness, ``- h a`` in the balance row (None: zero). ``prox``: springs of
    their own on some amplitudes (in :attr:`unit`), kept by every variant of the problem:
    a Newton step's damping, part of the problem solved.
    """

    def __init__(self, w, g, rhs, c, mu, tangent, h=None, aux=None, prox=None) -> None:
        self.fixed: NDArray | None = None  # Tresca: each frictional contact's radius
        self.spring = 0.0
        self.exact = False  # the slip's exact derivative instead of the modified one
        self.w, self.g, self.rhs, self.c = w, g, rhs, c
        self.h = h if h is not None and np.size(h) and np.any(h) else None
        self.aux = aux  # a border's auxiliary amplitudes (solve_friction's aux)
        # springs hold the bodies' modes, not a border's auxiliaries (exact equations)
        self.sprung = np.ones(g.shape[1]) if aux is None else (~np.asarray(aux)).astype(float)
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
        # the springs' unit: the contacts' stiffness seen in the modes
        gm = g[:, self.sprung > 0]
        dg = float(np.mean(np.einsum("ij,ij->i", gm, gm))) if gm.size else 0.0
        self.unit = (dg if dg > 0 else 1.0) / max(float(d.mean()) if d.size else 1.0, 1e-300)
        self.prox = (
            None if prox is None or not np.any(prox) else np.asarray(prox, float) * self.unit
        )

    def scaled(
        self,
        factor: float,
        fixed: NDArray | None = None,
        spring: float | None = None,
        exact: bool | None = None,
    ) -> NaturalMap:
        """The same problem with its augmentation ``c_p, c_t`` times ``factor``.

        With ``fixed``, Tresca's law instead: each frictional contact's radius is given
        (where it is closed). With ``spring``, the free bodies held by springs of that
        stiffness (in :attr:`unit`); ``exact``, the slip's exact derivative in
        :meth:`jacobian`. None keeps this problem's.
        """
        out = copy.copy(self)
        if exact is not None:
            out.exact = exact
        out.cp = self.cp * factor
        out.ct = self.ct * factor
        out.fixed = fixed
        if spring is not None:
            out.spring = spring * self.unit
        return out

    def values(self, lam: NDArray, a: NDArray) -> NDArray:
        """The rows' values ``y = W lambda + G a - rhs``: gaps and slip increments."""
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
        f[self.m :] = self.g.T @ lam - self.c - self.spring * self.sprung * a
        if self.h is not None:
            f[self.m :] -= self.h @ a
        if self.prox is not None:
            f[self.m :] -= self.prox * a
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
        """A generalised Jacobian of ``F`` at the point :meth:`residual` described by ``s``."""
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
            # A = (cone q^T - r I) / |z|: the exact derivative has cone = r q, Hueber,
            # Stadler and Wohlmuth's the force projected on the cone; they agree at a
            # solution, lam_t = r q. Searched along, the exact one's steps descend on
            # |F|^2; taken whole, theirs cycle less
            sl = np.flatnonzero(~stick & (radius > 0))
            if sl.size:
                ts, ps, qs = t[sl], fr[sl], q[sl]
                lt = s["lt"][sl]
                size = np.linalg.norm(lt, axis=1)
                big = size > radius[sl]
                shrink = np.ones(sl.size)
                shrink[big] = radius[sl][big] / size[big]
                cone = lt * shrink[:, None]
                if self.exact:
                    cone = radius[sl, None] * qs
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
        if self.h is not None:
            j[m:, m:] = -self.h
        if self.spring:
            j[range(m, n), range(m, n)] -= self.spring * self.sprung
        if self.prox is not None:
            j[range(m, n), range(m, n)] -= self.prox
        return j
