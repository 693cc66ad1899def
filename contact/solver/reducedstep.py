"""A semismooth Newton step of the frictional contact problem, on its active rows.

The step of :mod:`contact.solver.friction`: the open contacts' forces step to zero; the
rest is a small system of the closed contacts and the free bodies' modes, with the modes
that nothing determines (no closed contact moves them, no stiffness of their own holds
them, no load drives them) set to zero rather than left to round-off.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.linalg as sla
from numpy.typing import NDArray

from fem.saddle import RANK_TOL

from .natural_map import NaturalMap

__all__ = ["OWN", "SHIFT", "reduced_step"]

#: The shift, over the largest Jacobian entry, of a singular Newton system.
SHIFT = 1e-10
#: A mode no closed contact moves is held by its own stiffness where that is more than
#: this fraction of the closed contacts' in the modes.
OWN = 1e-3


def reduced_step(
    j: NDArray, f: NDArray, inactive: NDArray[np.bool_], a: NDArray, prob: NaturalMap
) -> NDArray:
    """Newton step ``J d = -F`` with the open contacts' rows (``J`` = identity) taken out.

    Their forces step to zero (``d = -F`` there); the rest is a system of the closed
    contacts and the free bodies' modes only: a few rows where the candidates are many.
    A mode that no closed contact moves, no stiffness of its own holds and no load drives
    (a ball held at two points turning about the line through them) is not determined by
    the step: its amplitude is set to zero (the body where the frame started), not left
    to round-off. Springs on the free bodies (``prob``'s) hold every mode.
    """
    d = np.empty_like(f)
    d[inactive] = -f[inactive]
    act = ~inactive
    if not act.any():
        return d
    r = a.size
    m = f.size - r
    v0 = _unseen(j, act, m, prob.c, prob.aux) if r and not prob.spring else np.zeros((r, 0))
    if not v0.shape[1]:
        ja = j[np.ix_(act, act)]
        d[act] = _step(ja, f[act] + j[np.ix_(act, inactive)] @ d[inactive])
        return d
    # the unseen modes' amplitudes go to zero; the rest solved on the modes seen (v1),
    # the balance in the unseen modes (no load there, no closed row moving them) dropped
    v1 = np.linalg.svd(v0.T, full_matrices=True)[2][v0.shape[1] :].T
    d[m:] = -v0 @ (v0.T @ a)
    rows = np.flatnonzero(act[:m])
    known = np.concatenate([np.flatnonzero(inactive), np.arange(m, m + r)])
    rest = f + j[:, known] @ d[known]
    mat = np.block(
        [
            [j[np.ix_(rows, rows)], j[rows, m:] @ v1],
            [v1.T @ j[m:, rows], v1.T @ j[m:, m:] @ v1],
        ]
    )
    x = _step(mat, np.concatenate([rest[rows], v1.T @ rest[m:]]))
    d[rows] = x[: rows.size]
    d[m:] += v1 @ x[rows.size :]
    return d


def _unseen(
    j: NDArray, act: NDArray[np.bool_], m: int, c: NDArray, aux: NDArray | None
) -> NDArray:
    """An orthonormal basis ``(r, q)`` of the modes no closed row moves and no load drives.

    A mode is moved where the closed contacts' rows of ``J`` (and a border's auxiliaries'
    own, ``aux``) have a part along it above :data:`fem.saddle.RANK_TOL` of the largest,
    or where its own stiffness is more than :data:`OWN` of theirs: a ball balanced on one
    stuck node turns about it against its weight's arm alone, some 1e-5 of the contact's
    stiffness, which decides nothing. A load's part along the unseen ones is kept out (a
    body that falls or slides is not gauged: the step moves it).
    """
    r = j.shape[0] - m
    own = j[m:, m:]
    rows = j[np.flatnonzero(act[:m]), m:]
    top = float(np.linalg.norm(rows, 2)) if rows.size else 0.0  # the contacts' stiffness
    if aux is not None and aux.any():
        rows = np.vstack([rows, own[aux]])
    if rows.size:
        _, sv, vt = np.linalg.svd(rows, full_matrices=True)
        big = float(sv.max(initial=0.0))
        rank = int((sv > RANK_TOL * big).sum()) if big > 0 else 0
        v0 = vt[rank:].T
    else:
        v0 = np.eye(r)
    if v0.shape[1] and own.any():
        val, vec = np.linalg.eigh(v0.T @ ((own + own.T) / 2) @ v0)
        v0 = v0 @ vec[:, np.abs(val) <= OWN * top]
    load = v0.T @ c
    if v0.shape[1] and np.abs(load).max() > 1e-8 * max(float(np.abs(c).max()), 1e-300):
        # the loaded direction among the unseen modes stays in the step
        keep = np.linalg.svd(load[None, :], full_matrices=True)[2][1:].T
        v0 = v0 @ keep
    return v0


def _step(j: NDArray, f: NDArray) -> NDArray:
    """Newton step ``J d = -F``.

    Where ``J`` is singular (rows that repeat one another, a mode nothing holds), the
    step of ``J + delta I`` (a tiny shift) where it solves ``J d = -F`` nearly as well,
    else least squares.
    """
    size = max(float(np.linalg.norm(f)), 1e-300)
    for shift in (0.0, SHIFT * max(float(np.abs(j).max(initial=0.0)), 1e-300)):
        try:
            with warnings.catch_warnings():  # a singular J is looked at below
                warnings.simplefilter("ignore", sla.LinAlgWarning)
                lu = sla.lu_factor(
                    j + shift * np.eye(j.shape[0]) if shift else j, check_finite=False
                )
                d = sla.lu_solve(lu, -f, check_finite=False)
        except (np.linalg.LinAlgError, ValueError):
            continue
        if (
            np.isfinite(d).all()
            and np.linalg.norm(j @ d + f) <= (1e-8 if not shift else 1e-6) * size
        ):
            return d
    return np.linalg.lstsq(j, -f, rcond=1e-12)[0]
