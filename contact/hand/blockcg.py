"""The relaxer's patch matrix: its block pattern and block-preconditioned conjugate gradients.

A Newton step's matrix has a full 3 x 3 block for every pair of free nodes that share a
tetrahedron. :func:`block_pattern` builds its CSR pattern once a patch, with an index a
node pair (not a value) for the assembly (:func:`pair_rows`); :func:`block_cg` solves with
it by conjugate gradients preconditioned by its 3 x 3 diagonal blocks, reading one column
index a block. Compiled by numba and cached next to this module.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from .tetkernels import cofactor3

__all__ = ["block_cg", "block_pattern", "pair_rows"]


@njit(cache=True, inline="always")
def pair_rows(pair_diag: NDArray[np.int64], p: int) -> tuple[int, int]:
    """Where node pair ``p``'s 3 x 3 block lies in the CSR values (see :func:`block_pattern`).

    Its entry ``(i, j)`` is at ``b0 + i w + j``: ``b0`` its first, ``w`` the step
    between its rows (the block row's width less 3), read off its diagonal's indices.
    """
    b0 = pair_diag[p, 0]
    return b0, pair_diag[p, 1] - b0 - 1


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
    rather than per entry: a ninth of the memory the Newton step reads.

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
    step of the relaxer (an inexact Newton method). Block Jacobi rather than the plain
    diagonal: fewer Newton steps on deep poses; an exact solve takes fewer steps still,
    but a factorisation costs more than the steps it saves.
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
        cofactor3(blk, inv[k])
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
