"""Compiled kernels of the flesh relaxer's Newton steps (:mod:`contact.hand.relax`).

A Newton step on a patch of a few hundred tetrahedra is a few hundred numpy calls on small
arrays, whose overhead rather than arithmetic would set its time. Here, compiled by numba,
each tetrahedron's energy, gradient and projected Hessian are computed and added into the
patch's matrix in one pass (no (m, 12, 12) element matrices in between); the line search's
energy, the volumes and qualities, and the restarts' untangling energy with its gradient
are one call each. The matrix pattern and the conjugate gradients are
:mod:`contact.hand.blockcg`'s, a tetrahedron's small linear algebra
:mod:`contact.hand.tetkernels`'.

The arithmetic is that of the numpy reference (:mod:`contact.hand.relax_reference`, tested
equal to round-off); the order of some sums differs. A degenerate or inverted
tetrahedron's eigensystem is computed per tetrahedron: the signed SVD of ``F`` from the
eigenvectors of ``F^T F`` and Gram-Schmidt, its 3 x 3 symmetric eigenproblems by cyclic
Jacobi rotations.

The first call compiles (seconds); the machine code is cached next to this module (numba's
``cache=True``), so later processes load it in a fraction of a second.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from .blockcg import pair_rows
from .tetkernels import (
    cofactor3,
    deformation_gradient,
    regularised,
    rotation_svd,
    sym_eig3,
)

__all__ = [
    "EXACT_J",
    "patch_energy",
    "step_terms",
    "untangle_terms",
    "volumes_quality",
]

#: A tetrahedron whose ``J = det F`` is at most this takes the exact Hessian of its energy,
#: projected on its positive eigenvalues; a fairer one its convex part.
EXACT_J = 0.25


@njit(cache=True)
def patch_energy(
    x: NDArray[np.float64],
    tets: NDArray[np.int64],
    dmat: NDArray[np.float64],
    vol: NDArray[np.float64],
    d2: float,
    kappa: float,
) -> float:
    """The relaxer's energy of the tetrahedra ``tets`` at ``x`` (:mod:`contact.hand.relax`)."""
    f = np.empty((3, 3))
    e = 0.0
    for t in range(tets.shape[0]):
        deformation_gradient(x, tets[t], dmat, t, f)
        j = (
            f[0, 0] * (f[1, 1] * f[2, 2] - f[2, 1] * f[1, 2])
            - f[0, 1] * (f[1, 0] * f[2, 2] - f[2, 0] * f[1, 2])
            + f[0, 2] * (f[1, 0] * f[2, 1] - f[2, 0] * f[1, 1])
        )
        _, h = regularised(j, d2)
        nf = 0.0
        for i in range(3):
            for k in range(3):
                nf += f[i, k] * f[i, k]
        e += vol[t] * (nf * h ** (-2.0 / 3.0) / 3.0 + 0.5 * kappa * (h + 1.0 / h))
    return e


@njit(cache=True)
def step_terms(
    x: NDArray[np.float64],
    tets: NDArray[np.int64],
    dmat: NDArray[np.float64],
    ddt: NDArray[np.float64],
    vol: NDArray[np.float64],
    d2: float,
    kappa: float,
    exact_j: float,
    gslot: NDArray[np.int64],
    pair_slot: NDArray[np.int64],
    pair_diag: NDArray[np.int64],
    n: int,
    ndata: int,
) -> tuple[float, NDArray[np.float64], NDArray[np.float64]]:
    """Energy, gradient and projected Hessian of a patch, assembled in one pass.

    Per tetrahedron, as :func:`contact.hand.relax_reference.terms` (its reference): a fair
    one (``J > exact_j``) adds ``vol (a (D D^T) x I3 + max(cj, 0) u u^T)``, ``u = dJ/dx``;
    a degenerate or inverted one its exact Hessian in ``F`` projected on its positive
    eigenvalues, from the analytic eigensystem (Smith, de Goes and Kim 2019; see
    :func:`contact.hand.relax_reference.isotropic_eigen`): a signed SVD of ``F`` and a
    3 x 3 eigenproblem.

    Parameters
    ----------
    x : ndarray, shape (N, 3)
        Positions.
    tets, dmat, ddt, vol
        The patch's tetrahedra, ``D`` (m, 4, 3), ``D D^T`` (m, 4, 4) and rest volumes.
    d2, kappa, exact_j : float
        ``delta^2``, the volume weight, and the ``J`` at or below which a tetrahedron
        takes its exact projected Hessian.
    gslot : ndarray, shape (m * 12,)
        The unknown of each element DOF (-1 held).
    pair_slot, pair_diag
        The node pair of each entry of a 4 x 4 ``L`` (one past the last: dropped), and
        the data indices of each pair's block diagonal (``L x I3`` assembly).
    n, ndata : int
        Unknowns and matrix entries.

    Returns
    -------
    energy : float
    grad : ndarray, shape (n,)
    data : ndarray, shape (ndata,)
        The assembled matrix's values.
    """
    m = tets.shape[0]
    npairs = pair_diag.shape[0]
    grad = np.zeros(n)
    data = np.zeros(ndata + 1)
    lap_pairs = np.zeros(pair_diag.shape[0] + 1)
    f = np.empty((3, 3))
    cof = np.empty((3, 3))
    u = np.empty(12)
    # the degenerate tetrahedra's scratch
    ru = np.empty((3, 3))
    rs = np.empty(3)
    rvt = np.empty((3, 3))
    work = np.empty((3, 3))
    w3 = np.empty(3)
    ev = np.empty((3, 3))
    blk = np.empty((3, 3))
    gs = np.empty(3)
    dv = np.empty((4, 3))
    wk = np.empty(9)
    gq = np.empty((12, 9))
    energy = 0.0
    r2 = np.sqrt(0.5)
    for t in range(m):
        deformation_gradient(x, tets[t], dmat, t, f)
        cofactor3(f, cof)
        j = f[0, 0] * cof[0, 0] + f[1, 0] * cof[1, 0] + f[2, 0] * cof[2, 0]
        r, h = regularised(j, d2)
        nf = 0.0
        for i in range(3):
            for k in range(3):
                nf += f[i, k] * f[i, k]
        h23 = h ** (-2.0 / 3.0)
        v = vol[t]
        energy += v * (nf * h23 / 3.0 + 0.5 * kappa * (h + 1.0 / h))
        h1 = h / r  # dh/dJ
        wj = -(2.0 / 9.0) * nf * h23 / h + 0.5 * kappa * (1.0 - 1.0 / (h * h))  # dW/dh
        c = wj * h1  # dW/dJ
        a = (2.0 / 3.0) * h23
        wjj = (10.0 / 27.0) * nf * h23 / (h * h) + kappa / (h * h * h)
        cj = wjj * h1 * h1 + wj * 2.0 * d2 / (r * r * r)  # d^2 W / dJ^2
        # the gradient: vol (dW/dF) D^T, dW/dF = a F + c cof F
        for p in range(4):
            for i in range(3):
                s = 0.0
                for k in range(3):
                    s += (a * f[i, k] + c * cof[i, k]) * dmat[t, p, k]
                g = gslot[12 * t + 3 * p + i]
                if g >= 0:
                    grad[g] += v * s
        if j > exact_j:
            # a fair tetrahedron: a (D D^T) x I3 + max(cj, 0) u u^T, u = dJ/dx, times vol
            wu = np.sqrt(v * max(cj, 0.0))
            for p in range(4):
                for i in range(3):
                    s = 0.0
                    for k in range(3):
                        s += cof[i, k] * dmat[t, p, k]
                    u[3 * p + i] = wu * s
            for pa in range(4):
                for pb in range(4):
                    pp = pair_slot[16 * t + 4 * pa + pb]
                    if pp < npairs:
                        b0, wd = pair_rows(pair_diag, pp)
                        for i in range(3):
                            uq = u[3 * pa + i]
                            row = b0 + i * wd
                            for j in range(3):
                                data[row + j] += uq * u[3 * pb + j]
            va = v * a
            for p in range(4):
                for q in range(4):
                    lap_pairs[pair_slot[16 * t + 4 * p + q]] += va * ddt[t, p, q]
            continue
        # a degenerate one: the analytic eigensystem of the Hessian in F, projected
        cb = -(2.0 / 9.0) * h23 / h * h1  # d^2 W / d(nf) dJ
        rotation_svd(f, ru, rs, rvt, work, w3, ev)
        gs[0] = rs[1] * rs[2]
        gs[1] = rs[0] * rs[2]
        gs[2] = rs[0] * rs[1]
        for p in range(3):
            for q in range(3):
                b = 2.0 * cb * (rs[p] * gs[q] + gs[p] * rs[q]) + cj * gs[p] * gs[q]
                if p == q:
                    b += a
                else:
                    b += c * rs[3 - p - q]
                blk[p, q] = b
        sym_eig3(blk, w3, ev)
        floor = 1e-8 * a
        for k in range(3):
            wk[k] = max(w3[k], floor) * v
            wk[3 + 2 * k] = max(a + c * rs[k], floor) * v  # twist of the pair without k
            wk[4 + 2 * k] = max(a - c * rs[k], floor) * v  # flip
        # d (F : U e_p e_q^T V^T) / d x_ni = U_ip (D V)_nq
        for nn in range(4):
            for q in range(3):
                dv[nn, q] = (
                    dmat[t, nn, 0] * rvt[q, 0]
                    + dmat[t, nn, 1] * rvt[q, 1]
                    + dmat[t, nn, 2] * rvt[q, 2]
                )
        for nn in range(4):
            for i in range(3):
                row = 3 * nn + i
                for col in range(3):
                    gq[row, col] = (
                        dv[nn, 0] * ru[i, 0] * ev[0, col]
                        + dv[nn, 1] * ru[i, 1] * ev[1, col]
                        + dv[nn, 2] * ru[i, 2] * ev[2, col]
                    )
                for k in range(3):
                    p = 1 if k == 0 else 0
                    q = 1 if k == 2 else 2
                    pq = dv[nn, q] * ru[i, p]
                    qp = dv[nn, p] * ru[i, q]
                    gq[row, 3 + 2 * k] = r2 * (pq - qp)
                    gq[row, 4 + 2 * k] = r2 * (pq + qp)
        for pa in range(4):
            for pb in range(4):
                pp = pair_slot[16 * t + 4 * pa + pb]
                if pp < npairs:
                    b0, wd = pair_rows(pair_diag, pp)
                    for i in range(3):
                        q = 3 * pa + i
                        row = b0 + i * wd
                        for j in range(3):
                            s_ = 3 * pb + j
                            hv = 0.0
                            for k in range(9):
                                hv += gq[q, k] * wk[k] * gq[s_, k]
                            data[row + j] += hv
    for pr in range(pair_diag.shape[0]):
        for i in range(3):
            data[pair_diag[pr, i]] += lap_pairs[pr]
    return energy, grad, data[:ndata]


@njit(cache=True)
def volumes_quality(
    x: NDArray[np.float64], tets: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Signed volumes and shape qualities ``6 sqrt(2) V / l_rms^3`` of tetrahedra."""
    m = tets.shape[0]
    vols = np.empty(m)
    qual = np.empty(m)
    e = np.empty((6, 3))
    for t in range(m):
        n0, n1, n2, n3 = tets[t, 0], tets[t, 1], tets[t, 2], tets[t, 3]
        for i in range(3):
            e[0, i] = x[n1, i] - x[n0, i]
            e[1, i] = x[n2, i] - x[n0, i]
            e[2, i] = x[n3, i] - x[n0, i]
            e[3, i] = e[1, i] - e[0, i]
            e[4, i] = e[2, i] - e[0, i]
            e[5, i] = e[2, i] - e[1, i]
        sq = 0.0
        for k in range(6):
            for i in range(3):
                sq += e[k, i] * e[k, i]
        v6 = (
            e[0, 0] * (e[1, 1] * e[2, 2] - e[1, 2] * e[2, 1])
            + e[0, 1] * (e[1, 2] * e[2, 0] - e[1, 0] * e[2, 2])
            + e[0, 2] * (e[1, 0] * e[2, 1] - e[1, 1] * e[2, 0])
        )
        vols[t] = v6 / 6.0
        sq /= 6.0
        qual[t] = v6 * np.sqrt(2.0) / (sq * np.sqrt(sq))
    return vols, qual


@njit(cache=True)
def untangle_terms(
    x: NDArray[np.float64],
    tets: NDArray[np.int64],
    lt: NDArray[np.int64],
    dmat: NDArray[np.float64],
    vol: NDArray[np.float64],
    target: float,
    nfree: int,
) -> tuple[float, NDArray[np.float64]]:
    """The untangling energy ``sum V_rest max(0, target - J)^2`` and its gradient.

    Over the tetrahedra ``tets`` at ``x`` (see :func:`contact.hand.restarts.untangle`); the gradient
    on the free nodes alone, ``lt`` (m, 4) each tetrahedron's nodes numbered among them
    (-1 held), shape ``(3 nfree,)``. ``dJ/dx_a = cof(F) D_a``.
    """
    grad = np.zeros(3 * nfree)
    f = np.empty((3, 3))
    cof = np.empty((3, 3))
    energy = 0.0
    for t in range(tets.shape[0]):
        deformation_gradient(x, tets[t], dmat, t, f)
        cofactor3(f, cof)
        j = f[0, 0] * cof[0, 0] + f[1, 0] * cof[1, 0] + f[2, 0] * cof[2, 0]
        short = target - j
        if short <= 0.0:
            continue
        energy += vol[t] * short * short
        w = -2.0 * vol[t] * short
        for a in range(4):
            node = lt[t, a]
            if node < 0:
                continue
            for i in range(3):
                s = 0.0
                for k in range(3):
                    s += cof[i, k] * dmat[t, a, k]
                grad[3 * node + i] += w * s
    return energy, grad
