"""Compiled kernels of the flesh relaxer's Newton steps (:class:`contact.hand.posing.FleshRelaxer`).

A Newton step on a patch of a few hundred tetrahedra was a few hundred numpy calls on
small arrays, whose overhead rather than arithmetic set its time (1.4-1.7 ms on a
50-node patch: the element terms 43 %, the conjugate gradients 22 %, the assembly 14 %).
Here, compiled by numba, each tetrahedron's energy, gradient and projected Hessian are
computed and added into the patch's matrix in one pass (no (m, 12, 12) element matrices
in between); the line search's energy, the volumes and qualities, the patch's matrix
pattern (by node pairs) and the preconditioned conjugate gradients (the product by 3 x 3
blocks) are one call each, and so is the restarts' untangling energy with its gradient.

The arithmetic is that of the numpy reference, ``FleshRelaxer._terms`` (tested equal to
round-off); the order of some sums differs. A degenerate or inverted tetrahedron's
eigensystem is computed per tetrahedron: the signed SVD of ``F`` from the eigenvectors
of ``F^T F`` and Gram-Schmidt (as :func:`fem.rotation_svd3`), its 3 x 3 symmetric
eigenproblems by cyclic Jacobi rotations.

The first call compiles (about 9 s); the machine code is cached next to this module
(numba's ``cache=True``), so later processes load it in a fraction of a second.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = [
    "block_cg",
    "block_pattern",
    "patch_energy",
    "step_terms",
    "untangle_terms",
    "volumes_quality",
]


@njit(cache=True, inline="always")
def _gradient(
    x: NDArray[np.float64],
    tet: NDArray[np.int64],
    dmat: NDArray[np.float64],
    t: int,
    f: NDArray[np.float64],
) -> None:
    """``F = X^T D`` of tetrahedron ``t`` into ``f`` (3, 3)."""
    for i in range(3):
        for k in range(3):
            s = 0.0
            for a in range(4):
                s += x[tet[a], i] * dmat[t, a, k]
            f[i, k] = s


@njit(cache=True, inline="always")
def _cof(f: NDArray[np.float64], c: NDArray[np.float64]) -> None:
    """Cofactor matrix of ``f``: column k is column k+1 x column k+2."""
    for k in range(3):
        k1 = (k + 1) % 3
        k2 = (k + 2) % 3
        for i in range(3):
            i1 = (i + 1) % 3
            i2 = (i + 2) % 3
            c[i, k] = f[i1, k1] * f[i2, k2] - f[i2, k1] * f[i1, k2]


@njit(cache=True, inline="always")
def _regularised(j: float, d2: float) -> tuple[float, float]:
    """``sqrt(j^2 + 4 d2)`` and Escobar's ``h``, without cancellation for ``j << 0``."""
    r = np.sqrt(j * j + 4.0 * d2)
    h = 2.0 * d2 / (r - j) if j < 0.0 else 0.5 * (j + r)
    return r, h


@njit(cache=True, inline="always")
def _sym_eig3(a: NDArray[np.float64], w: NDArray[np.float64], v: NDArray[np.float64]) -> None:
    """Eigenvalues ``w`` (ascending) and vectors ``v`` (columns) of symmetric ``a`` (3, 3).

    Cyclic Jacobi rotations (``a`` is overwritten): each sweep squares the off-diagonal
    part's relative size; converged to round-off in 4 to 6 sweeps, and accurate for
    nearly repeated eigenvalues (their vectors are then any orthonormal pair).
    """
    for i in range(3):
        for j in range(3):
            v[i, j] = 1.0 if i == j else 0.0
    for _ in range(32):
        off = a[0, 1] * a[0, 1] + a[0, 2] * a[0, 2] + a[1, 2] * a[1, 2]
        scale = a[0, 0] * a[0, 0] + a[1, 1] * a[1, 1] + a[2, 2] * a[2, 2] + 2.0 * off
        if off <= 1e-34 * scale:
            break
        for pq in range(3):
            p = 0 if pq < 2 else 1
            q = 2 if pq > 0 else 1
            apq = a[p, q]
            if apq == 0.0:
                continue
            theta = (a[q, q] - a[p, p]) / (2.0 * apq)
            if abs(theta) > 1e150:
                t = 0.5 / theta
            else:
                t = 1.0 / (abs(theta) + np.sqrt(theta * theta + 1.0))
                if theta < 0.0:
                    t = -t
            c = 1.0 / np.sqrt(t * t + 1.0)
            s = t * c
            for k in range(3):
                akp = a[k, p]
                akq = a[k, q]
                a[k, p] = c * akp - s * akq
                a[k, q] = s * akp + c * akq
            for k in range(3):
                apk = a[p, k]
                aqk = a[q, k]
                a[p, k] = c * apk - s * aqk
                a[q, k] = s * apk + c * aqk
            a[p, q] = 0.0
            a[q, p] = 0.0
            for k in range(3):
                vkp = v[k, p]
                vkq = v[k, q]
                v[k, p] = c * vkp - s * vkq
                v[k, q] = s * vkp + c * vkq
    for i in range(3):
        w[i] = a[i, i]
    # ascending (three elements: a small sort network)
    for i, j in ((0, 1), (1, 2), (0, 1)):
        if w[j] < w[i]:
            w[i], w[j] = w[j], w[i]
            for k in range(3):
                v[k, i], v[k, j] = v[k, j], v[k, i]


@njit(cache=True, inline="always")
def _orthogonal(v: NDArray[np.float64], out: NDArray[np.float64]) -> None:
    """A unit vector orthogonal to the unit vector ``v``, into ``out``."""
    if abs(v[0]) > abs(v[1]):
        out[0], out[1], out[2] = -v[2], 0.0, v[0]
    else:
        out[0], out[1], out[2] = 0.0, v[2], -v[1]
    n = np.sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2])
    for i in range(3):
        out[i] /= n


@njit(cache=True, inline="always")
def _rotation_svd(
    f: NDArray[np.float64],
    u: NDArray[np.float64],
    s: NDArray[np.float64],
    vt: NDArray[np.float64],
    work: NDArray[np.float64],
    w: NDArray[np.float64],
    ev: NDArray[np.float64],
) -> None:
    """``f = u diag(s) vt`` with rotations and ``s[2]`` signed (:func:`fem.rotation_svd3`).

    ``v`` from the eigenvectors of ``f^T f``, ``u`` by Gram-Schmidt (twice) from ``f v``;
    ``work`` (3, 3), ``w`` (3,), ``ev`` (3, 3) scratch.
    """
    for i in range(3):
        for j in range(3):
            t = 0.0
            for k in range(3):
                t += f[k, i] * f[k, j]
            work[i, j] = t
    _sym_eig3(work, w, ev)
    # v: descending singular values, a rotation
    for i in range(3):
        vt[0, i] = ev[i, 2]
        vt[1, i] = ev[i, 1]
    vt[2, 0] = vt[0, 1] * vt[1, 2] - vt[0, 2] * vt[1, 1]
    vt[2, 1] = vt[0, 2] * vt[1, 0] - vt[0, 0] * vt[1, 2]
    vt[2, 2] = vt[0, 0] * vt[1, 1] - vt[0, 1] * vt[1, 0]
    # f v (columns of work)
    for c in range(3):
        for i in range(3):
            work[i, c] = f[i, 0] * vt[c, 0] + f[i, 1] * vt[c, 1] + f[i, 2] * vt[c, 2]
    n0 = np.sqrt(work[0, 0] ** 2 + work[1, 0] ** 2 + work[2, 0] ** 2)
    if n0 <= 1e-300:
        _orthogonal(vt[0], w)
        for i in range(3):
            u[i, 0] = w[i]
    else:
        for i in range(3):
            u[i, 0] = work[i, 0] / n0
    n1 = np.sqrt(work[0, 1] ** 2 + work[1, 1] ** 2 + work[2, 1] ** 2)
    if n1 <= 1e-12 * n0:
        _orthogonal(u[:, 0], w)
        for i in range(3):
            u[i, 1] = w[i]
    else:
        for i in range(3):
            u[i, 1] = work[i, 1]
        for _ in range(2):
            d = u[0, 0] * u[0, 1] + u[1, 0] * u[1, 1] + u[2, 0] * u[2, 1]
            for i in range(3):
                u[i, 1] -= d * u[i, 0]
            n = np.sqrt(u[0, 1] ** 2 + u[1, 1] ** 2 + u[2, 1] ** 2)
            for i in range(3):
                u[i, 1] /= n
    u[0, 2] = u[1, 0] * u[2, 1] - u[2, 0] * u[1, 1]
    u[1, 2] = u[2, 0] * u[0, 1] - u[0, 0] * u[2, 1]
    u[2, 2] = u[0, 0] * u[1, 1] - u[1, 0] * u[0, 1]
    for c in range(3):
        s[c] = u[0, c] * work[0, c] + u[1, c] * work[1, c] + u[2, c] * work[2, c]


@njit(cache=True)
def patch_energy(
    x: NDArray[np.float64],
    tets: NDArray[np.int64],
    dmat: NDArray[np.float64],
    vol: NDArray[np.float64],
    d2: float,
    kappa: float,
) -> float:
    """The energy of the tetrahedra ``tets`` at ``x`` (see ``FleshRelaxer``)."""
    f = np.empty((3, 3))
    e = 0.0
    for t in range(tets.shape[0]):
        _gradient(x, tets[t], dmat, t, f)
        j = (
            f[0, 0] * (f[1, 1] * f[2, 2] - f[2, 1] * f[1, 2])
            - f[0, 1] * (f[1, 0] * f[2, 2] - f[2, 0] * f[1, 2])
            + f[0, 2] * (f[1, 0] * f[2, 1] - f[2, 0] * f[1, 1])
        )
        _, h = _regularised(j, d2)
        nf = 0.0
        for i in range(3):
            for k in range(3):
                nf += f[i, k] * f[i, k]
        e += vol[t] * (nf * h ** (-2.0 / 3.0) / 3.0 + 0.5 * kappa * (h + 1.0 / h))
    return e


@njit(cache=True, inline="always")
def _pair_rows(pair_diag: NDArray[np.int64], p: int) -> tuple[int, int]:
    """Where node pair ``p``'s 3 x 3 block lies in the CSR values (see :func:`block_pattern`).

    Its entry ``(i, j)`` is at ``b0 + i w + j``: ``b0`` its first, ``w`` the step
    between its rows (the block row's width less 3), read off its diagonal's indices.
    """
    b0 = pair_diag[p, 0]
    return b0, pair_diag[p, 1] - b0 - 1


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

    Per tetrahedron, as ``FleshRelaxer._terms`` (its reference): a fair one (``J >
    exact_j``) adds ``vol (a (D D^T) x I3 + max(cj, 0) u u^T)``, ``u = dJ/dx``; a
    degenerate or inverted one its exact Hessian in ``F`` projected on its positive
    eigenvalues, from the analytic eigensystem (Smith, de Goes and Kim 2019; see
    ``contact.hand.posing._isotropic_eigen``): a signed SVD of ``F`` and a 3 x 3 eigenproblem.

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
        _gradient(x, tets[t], dmat, t, f)
        _cof(f, cof)
        j = f[0, 0] * cof[0, 0] + f[1, 0] * cof[1, 0] + f[2, 0] * cof[2, 0]
        r, h = _regularised(j, d2)
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
                        b0, wd = _pair_rows(pair_diag, pp)
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
        _rotation_svd(f, ru, rs, rvt, work, w3, ev)
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
        _sym_eig3(blk, w3, ev)
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
                    b0, wd = _pair_rows(pair_diag, pp)
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


@njit(cache=True, inline="always")
def _precondition(inv: NDArray[np.float64], r: NDArray[np.float64], z: NDArray[np.float64]) -> None:
    """``z = P r``: each node's 3 x 3 block inverse, stored transposed in ``inv``."""
    for k in range(inv.shape[0]):
        for i in range(3):
            z[3 * k + i] = (
                inv[k, 0, i] * r[3 * k] + inv[k, 1, i] * r[3 * k + 1] + inv[k, 2, i] * r[3 * k + 2]
            )


@njit(cache=True, inline="always")
def _block_product(
    indptr: NDArray[np.int64],
    indices: NDArray[np.int64],
    data: NDArray[np.float64],
    x: NDArray[np.float64],
    y: NDArray[np.float64],
) -> None:
    """``y = A x`` for a CSR matrix of full 3 x 3 blocks (as :func:`block_pattern` makes).

    Block row ``r`` is rows ``3r .. 3r+2``, each the same block columns in the same
    order, three values a block: one column index read a block (not one a value), the
    three values of ``x`` it meets used by all three rows.
    """
    for r in range(y.shape[0] // 3):
        k0 = indptr[3 * r]
        k1 = indptr[3 * r + 1]
        k2 = indptr[3 * r + 2]
        s0 = 0.0
        s1 = 0.0
        s2 = 0.0
        for o in range(0, k1 - k0, 3):
            c = indices[k0 + o]
            x0 = x[c]
            x1 = x[c + 1]
            x2 = x[c + 2]
            s0 += data[k0 + o] * x0 + data[k0 + o + 1] * x1 + data[k0 + o + 2] * x2
            s1 += data[k1 + o] * x0 + data[k1 + o + 1] * x1 + data[k1 + o + 2] * x2
            s2 += data[k2 + o] * x0 + data[k2 + o + 1] * x1 + data[k2 + o + 2] * x2
        y[3 * r] = s0
        y[3 * r + 1] = s1
        y[3 * r + 2] = s2


@njit(cache=True)
def block_cg(
    indptr: NDArray[np.int64],
    indices: NDArray[np.int64],
    data: NDArray[np.float64],
    diag: NDArray[np.int64],
    b: NDArray[np.float64],
    rtol: float,
    maxiter: int,
) -> NDArray[np.float64]:
    """Solve ``A x = b`` by conjugate gradients preconditioned by ``A``'s 3 x 3 diagonal blocks.

    ``A`` is symmetric positive definite, given by its CSR arrays (``indptr``,
    ``indices``, ``data``) of full 3 x 3 blocks (:func:`block_pattern`); ``diag`` (9 a
    node): the data indices of every node's diagonal block, row-major. Stops at a
    relative residual ``rtol`` (of ``|b|``) or after ``maxiter`` iterations. The Newton
    step of the relaxer (an inexact Newton method). Block Jacobi against the plain
    diagonal: a tenth fewer Newton steps on the fine hand's deep poses; an exact solve
    (PARDISO) takes fewer steps still but more time (a factorisation costs about two
    of these solves).
    """
    n = b.shape[0]
    nodes = n // 3
    if n % 3 or indptr.shape[0] != n + 1:
        raise ValueError("block_cg: the matrix must have 3 rows a node and b one value a row")
    for r in range(nodes):
        w = indptr[3 * r + 1] - indptr[3 * r]
        if (
            w % 3
            or indptr[3 * r + 2] - indptr[3 * r + 1] != w
            or indptr[3 * r + 3] - indptr[3 * r + 2] != w
        ):
            raise ValueError(
                "block_cg: the matrix is not made of full 3 x 3 blocks (block_pattern)"
            )
    inv = np.empty((nodes, 3, 3))  # transposed: inv[k].T is the inverse of block k
    blk = np.empty((3, 3))
    for k in range(nodes):
        for i in range(3):
            for j in range(3):
                blk[i, j] = data[diag[9 * k + 3 * i + j]]
        _cof(blk, inv[k])
        det = blk[0, 0] * inv[k, 0, 0] + blk[1, 0] * inv[k, 1, 0] + blk[2, 0] * inv[k, 2, 0]
        for i in range(3):
            for j in range(3):
                inv[k, i, j] /= det
    x = np.zeros(n)
    r = b.copy()
    z = np.empty(n)
    q = np.empty(n)
    _precondition(inv, r, z)
    p = z.copy()
    rz = 0.0
    bb = 0.0
    for i in range(n):
        rz += r[i] * z[i]
        bb += b[i] * b[i]
    stop = rtol * np.sqrt(bb)
    for _ in range(maxiter):
        rr = 0.0
        for i in range(n):
            rr += r[i] * r[i]
        if np.sqrt(rr) <= stop:
            break
        _block_product(indptr, indices, data, p, q)
        pq = 0.0
        for i in range(n):
            pq += p[i] * q[i]
        alpha = rz / pq
        for i in range(n):
            x[i] += alpha * p[i]
            r[i] -= alpha * q[i]
        _precondition(inv, r, z)
        rz_old = rz
        rz = 0.0
        for i in range(n):
            rz += r[i] * z[i]
        beta = rz / rz_old
        for i in range(n):
            p[i] = z[i] + beta * p[i]
    return x


@njit(cache=True)
def block_pattern(
    lt: NDArray[np.int64], nodes: int
) -> tuple[
    NDArray[np.int64],
    NDArray[np.int64],
    NDArray[np.int64],
    NDArray[np.int64],
    NDArray[np.int64],
]:
    """The CSR pattern of the (3 ``nodes``)-square matrix assembled from 12 x 12 blocks.

    ``lt`` (m, 4): each tetrahedron's nodes numbered among the unknowns' (-1 held). The
    node pairs are found row by row (the tetrahedra around each node, their nodes
    marked once and sorted) and spread to their 3 x 3 blocks. Entry ``(a, i, b, j)``
    of tetrahedron ``t``'s 12 x 12 matrix (node ``a``, component ``i``; node ``b``,
    component ``j``) adds to the value at ``pair_diag[p, 0] + i w + j``, ``p =
    pair_slot[16 t + 4 a + b]`` and ``w = pair_diag[p, 1] - pair_diag[p, 0] - 1``
    (dropped where ``p`` is one past the last pair: a held node). An index per node pair
    rather than per entry: a ninth of the memory the Newton step reads (on a
    5,162-tetrahedron patch of the fine hand its terms took 2.0 against 3.1 ms with an
    index per entry).

    Returns
    -------
    indptr, indices : ndarray
        The pattern (columns sorted in every row).
    diag : ndarray
        The data indices of every node's diagonal 3 x 3 block (nodes in a tetrahedron
        only, in order, each row-major).
    pair_slot : ndarray, shape (m * 16,)
        For element matrices ``L x I3`` (``L`` (m, 4, 4)): the node pair of every entry
        of ``L`` (pairs in the pattern's order; one past the last for a held node).
    pair_diag : ndarray, shape (pairs, 3)
        The data indices of each pair's block diagonal.
    """
    m = lt.shape[0]
    # the tetrahedra around each node (CSR)
    count = np.zeros(nodes + 1, dtype=np.int64)
    for t in range(m):
        for a in range(4):
            if lt[t, a] >= 0:
                count[lt[t, a] + 1] += 1
    for r in range(nodes):
        count[r + 1] += count[r]
    around = np.empty(count[nodes], dtype=np.int64)
    fill = count[:-1].copy()
    for t in range(m):
        for a in range(4):
            r = lt[t, a]
            if r >= 0:
                around[fill[r]] = t
                fill[r] += 1
    # each row's columns: the nodes of its tetrahedra, marked once, sorted
    bptr = np.zeros(nodes + 1, dtype=np.int64)
    mark = np.full(nodes, -1, dtype=np.int64)
    for r in range(nodes):
        k = 0
        for s in range(count[r], count[r + 1]):
            t = around[s]
            for b in range(4):
                c = lt[t, b]
                if c >= 0 and mark[c] != r:
                    mark[c] = r
                    k += 1
        bptr[r + 1] = bptr[r] + k
    npairs = bptr[nodes]
    bcol = np.empty(npairs, dtype=np.int64)
    mark[:] = -1
    where = np.empty(nodes, dtype=np.int64)  # a column's pair in the current row
    pslot = np.full((m, 4, 4), npairs, dtype=np.int64)  # held: one past the last pair
    for r in range(nodes):
        k = bptr[r]
        for s in range(count[r], count[r + 1]):
            t = around[s]
            for b in range(4):
                c = lt[t, b]
                if c >= 0 and mark[c] != r:
                    mark[c] = r
                    bcol[k] = c
                    k += 1
        row = bcol[bptr[r] : bptr[r + 1]]
        row.sort()
        for p in range(bptr[r], bptr[r + 1]):
            where[bcol[p]] = p
        for s in range(count[r], count[r + 1]):
            t = around[s]
            for a in range(4):
                if lt[t, a] == r:
                    for b in range(4):
                        c = lt[t, b]
                        if c >= 0:
                            pslot[t, a, b] = where[c]
    # entry (pair p of block row r, i, j) lies at 9 bptr[r] + i width[r] + 3 (p - bptr[r]) + j
    ndata = 9 * npairs
    indices = np.empty(ndata, dtype=np.int64)
    indptr = np.empty(3 * nodes + 1, dtype=np.int64)
    pair_diag = np.empty((npairs, 3), dtype=np.int64)
    present = 0  # nodes in a tetrahedron: each has its own pair, the diagonal block
    for r in range(nodes):
        if bptr[r + 1] > bptr[r]:
            present += 1
    diag = np.empty(9 * present, dtype=np.int64)
    k = 0
    for r in range(nodes):
        width = 3 * (bptr[r + 1] - bptr[r])
        for i in range(3):
            indptr[3 * r + i] = 9 * bptr[r] + i * width
        for p in range(bptr[r], bptr[r + 1]):
            base = 9 * bptr[r] + 3 * (p - bptr[r])
            for i in range(3):
                pair_diag[p, i] = base + i * width + i
                for j in range(3):
                    indices[base + i * width + j] = 3 * bcol[p] + j
            if bcol[p] == r:
                for i in range(3):
                    for j in range(3):
                        diag[k] = base + i * width + j
                        k += 1
    indptr[3 * nodes] = ndata
    return indptr, indices, diag, pslot.ravel(), pair_diag


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

    Over the tetrahedra ``tets`` at ``x`` (see ``FleshRelaxer._untangle``); the gradient
    on the free nodes alone, ``lt`` (m, 4) each tetrahedron's nodes numbered among them
    (-1 held), shape ``(3 nfree,)``. ``dJ/dx_a = cof(F) D_a``.
    """
    grad = np.zeros(3 * nfree)
    f = np.empty((3, 3))
    cof = np.empty((3, 3))
    energy = 0.0
    for t in range(tets.shape[0]):
        _gradient(x, tets[t], dmat, t, f)
        _cof(f, cof)
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
