"""Inline helpers of the relaxer's compiled kernels: one tetrahedron's small linear algebra.

The deformation gradient ``F = X^T D``, its cofactor, Escobar's regularised determinant, a
3 x 3 symmetric eigensolver (cyclic Jacobi) and the signed SVD of ``F`` (as
:func:`fem.rotation_svd3`). All are ``inline="always"``: compiled into the kernels of
:mod:`contact.hand.relaxkernels` and :mod:`contact.hand.blockcg` that call them.

numba's cache (``cache=True``) checks only the source file of the kernel it compiled: after
editing a helper here, clear the ``__pycache__`` of this package (or touch the kernels'
modules) so that the kernels are compiled again.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = [
    "cofactor3",
    "deformation_gradient",
    "orthogonal",
    "regularised",
    "rotation_svd",
    "sym_eig3",
]


@njit(cache=True, inline="always")
def deformation_gradient(
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
def cofactor3(f: NDArray[np.float64], c: NDArray[np.float64]) -> None:
    """Cofactor matrix of ``f``: column k is column k+1 x column k+2."""
    for k in range(3):
        k1 = (k + 1) % 3
        k2 = (k + 2) % 3
        for i in range(3):
            i1 = (i + 1) % 3
            i2 = (i + 2) % 3
            c[i, k] = f[i1, k1] * f[i2, k2] - f[i2, k1] * f[i1, k2]


@njit(cache=True, inline="always")
def regularised(j: float, d2: float) -> tuple[float, float]:
    """``sqrt(j^2 + 4 d2)`` and Escobar's ``h``, without cancellation for ``j << 0``."""
    r = np.sqrt(j * j + 4.0 * d2)
    h = 2.0 * d2 / (r - j) if j < 0.0 else 0.5 * (j + r)
    return r, h


@njit(cache=True, inline="always")
def sym_eig3(a: NDArray[np.float64], w: NDArray[np.float64], v: NDArray[np.float64]) -> None:
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
def orthogonal(v: NDArray[np.float64], out: NDArray[np.float64]) -> None:
    """A unit vector orthogonal to the unit vector ``v``, into ``out``."""
    if abs(v[0]) > abs(v[1]):
        out[0], out[1], out[2] = -v[2], 0.0, v[0]
    else:
        out[0], out[1], out[2] = 0.0, v[2], -v[1]
    n = np.sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2])
    for i in range(3):
        out[i] /= n


@njit(cache=True, inline="always")
def rotation_svd(
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
    sym_eig3(work, w, ev)
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
        orthogonal(vt[0], w)
        for i in range(3):
            u[i, 0] = w[i]
    else:
        for i in range(3):
            u[i, 0] = work[i, 0] / n0
    n1 = np.sqrt(work[0, 1] ** 2 + work[1, 1] ** 2 + work[2, 1] ** 2)
    if n1 <= 1e-12 * n0:
        orthogonal(u[:, 0], w)
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
