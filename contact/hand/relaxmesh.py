"""The flesh relaxer's mesh: the rest shape of the tetrahedra and the patches around nodes.

What every part of the relaxation (:mod:`contact.hand.relax`, :mod:`contact.hand.restarts`)
reads: each tetrahedron's rest volume and ``D`` (its deformation gradient from the rest
shape is ``F = X^T D``), the node-to-tetrahedron incidence, the rings and connected parts
of a set of nodes, and the harmonic fill of a patch. Built once a mesh; only
:meth:`RelaxMesh.fill` moves nodes, in the positions it is given.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components
from scipy.sparse.linalg import splu

from .quality import tet_quality

__all__ = ["RelaxMesh", "cofactor"]


def cofactor(f: NDArray[np.float64]) -> NDArray[np.float64]:
    """Cofactor matrices of ``f`` (m, 3, 3): column k is column k+1 x column k+2."""
    a = np.moveaxis(f, 0, -1)
    c = np.empty_like(a)
    for k in range(3):
        k1, k2 = (k + 1) % 3, (k + 2) % 3
        for i in range(3):
            i1, i2 = (i + 1) % 3, (i + 2) % 3
            c[i, k] = a[i1, k1] * a[i2, k2] - a[i2, k1] * a[i1, k2]
    return np.moveaxis(c, -1, 0)


class RelaxMesh:
    """A tetrahedral mesh at rest, its fixed nodes, and the patches the relaxer works on.

    Parameters
    ----------
    points : array_like, shape (N, 3)
        Rest positions.
    tets : array_like of int, shape (M, 4)
        Positively oriented tetrahedra.
    fixed : array_like of bool, shape (N,)
        Nodes that never move (the bone nodes).
    bone_id : array_like of int, shape (N,), optional
        The bone each fixed node belongs to (-1 free).

    Attributes
    ----------
    rest, tets, fixed, bone_id
        The parameters as arrays.
    dmat : ndarray, shape (M, 4, 3)
        ``dF/dx``: ``F_ij = sum_a x_ai D_aj`` (node ``a``'s row of ``D``).
    ddt : ndarray, shape (M, 4, 4)
        ``D D^T``.
    vol : ndarray, shape (M,)
        Rest volumes.
    rest_quality : ndarray, shape (M,)
        :func:`contact.hand.quality.tet_quality` at rest.
    n2t : scipy.sparse.csr_matrix, shape (N, M)
        Node-to-tetrahedron incidence.
    laplacian : scipy.sparse.csr_matrix, shape (N, N)
        The P1 stiffness of the rest shape, ``sum V grad N_a . grad N_b`` (for :meth:`fill`).
    """

    def __init__(
        self,
        points: ArrayLike,
        tets: ArrayLike,
        fixed: ArrayLike,
        bone_id: ArrayLike | None = None,
    ) -> None:
        x = np.asarray(points, dtype=np.float64)
        self.rest = x
        self.tets = np.ascontiguousarray(tets, dtype=np.int64)
        self.fixed = np.asarray(fixed, dtype=bool)
        self.bone_id = None if bone_id is None else np.asarray(bone_id, dtype=np.int64)
        if self.bone_id is not None and (
            self.bone_id.shape != self.fixed.shape
            or not np.array_equal(self.bone_id >= 0, self.fixed)
        ):
            raise ValueError("bone_id must be >= 0 exactly on the fixed nodes")
        dm = np.transpose(x[self.tets[:, 1:]] - x[self.tets[:, :1]], (0, 2, 1))
        bm = np.linalg.inv(dm)
        # node a's row of D: the first node's is minus the sum of the others'
        self.dmat = np.concatenate([-bm.sum(axis=1, keepdims=True), bm], axis=1)
        self.ddt = self.dmat @ np.transpose(self.dmat, (0, 2, 1))
        self.vol = np.linalg.det(dm) / 6.0
        self.rest_quality = tet_quality(x, self.tets)
        m = len(self.tets)
        self.n2t = csr_matrix(
            (np.ones(4 * m), (self.tets.ravel(), np.repeat(np.arange(m), 4))),
            shape=(len(x), m),
        )
        pairs = (np.repeat(self.tets, 4, axis=1).ravel(), np.tile(self.tets, (1, 4)).ravel())
        self.laplacian = csr_matrix(
            ((self.ddt * self.vol[:, None, None]).ravel(), pairs), shape=(len(x), len(x))
        )
        self.laplacian.sum_duplicates()

    def cells(self, nodes: NDArray[np.int64]) -> NDArray[np.int64]:
        """The tetrahedra around ``nodes``, sorted.

        The incidence's rows gathered by their offsets and marked on a mask: much cheaper
        than slicing the sparse matrix and sorting.
        """
        ptr = self.n2t.indptr
        nodes = np.asarray(nodes, dtype=np.int64)
        start = ptr[nodes]
        counts = ptr[nodes + 1] - start
        offsets = np.repeat(start - np.cumsum(counts) + counts, counts)
        offsets += np.arange(len(offsets))
        mark = np.zeros(len(self.tets), dtype=bool)
        mark[self.n2t.indices[offsets]] = True
        return np.flatnonzero(mark)

    def ring(self, nodes: NDArray[np.int64], rings: int) -> NDArray[np.int64]:
        """``nodes`` and the nodes of the tetrahedra within ``rings`` rings of them."""
        for _ in range(rings):
            mark = np.zeros(len(self.rest), dtype=bool)
            mark[self.tets[self.cells(nodes)]] = True
            nodes = np.flatnonzero(mark)
        return nodes

    def parts(self, free: NDArray[np.int64]) -> list[NDArray[np.int64]]:
        """The connected parts of the nodes ``free`` (joined by a tetrahedron), sorted."""
        a = self.n2t[free]
        _, label = connected_components(a @ a.T, directed=False)
        order = np.argsort(label, kind="stable")
        split = np.flatnonzero(np.diff(label[order])) + 1
        return [np.sort(part) for part in np.split(free[order], split)]

    def gather(self, cells: NDArray[np.int64]) -> dict[str, NDArray]:
        """The per-tetrahedron data of ``cells``, taken once for a patch's Newton steps.

        Keys ``cells``, ``tets``, ``vol``, ``dmat``, ``ddt`` (``np.take`` along the first
        axis: cheaper than fancy indexing).
        """
        return {
            "cells": cells,
            "tets": np.take(self.tets, cells, axis=0),
            "vol": np.take(self.vol, cells),
            "dmat": np.take(self.dmat, cells, axis=0),
            "ddt": np.take(self.ddt, cells, axis=0),
        }

    def requality(
        self, q: NDArray[np.float64], x: NDArray[np.float64], nodes: NDArray[np.int64]
    ) -> None:
        """Update the qualities ``q`` of the tetrahedra around ``nodes`` (moved) in place.

        A pass, a restart or the polish moves a patch: the rest of the mesh keeps its
        quality, so only the patch's tetrahedra are measured again.
        """
        cells = self.cells(nodes)
        q[cells] = tet_quality(x, np.take(self.tets, cells, axis=0))

    def fill(self, x: NDArray[np.float64], nodes: NDArray[np.int64]) -> None:
        """Move free ``nodes`` to the harmonic extension of the displacement around them.

        The displacement ``u = x - rest`` of ``nodes`` minimises the Dirichlet energy
        ``sum V |grad u|^2`` of the tetrahedra around them (linear, on the rest shape),
        every other node held: ``K_ff u_f = -K_fb u_b``. A smooth start where the mapping
        folds the flesh: it has no folds of its own on a moderate rotation (it shrinks a
        deep one's volumes rather than turning them over). In place.

        ``K`` is the whole mesh's P1 stiffness (:attr:`laplacian`): a node's rows hold
        exactly the tetrahedra around it, so ``K_ff`` and ``K_fb`` are its rows sliced.
        Factored by SuperLU in symmetric mode on a minimum-degree ordering of ``K + K^T``
        (several times faster than its default column ordering, the same fill).
        """
        if len(nodes) == 0:
            return
        rows = self.laplacian[nodes]
        u = x - self.rest
        u[nodes] = 0.0
        rhs = -(rows @ u)
        kff = rows[:, nodes].tocsc()
        try:
            lu = splu(
                kff,
                permc_spec="MMD_AT_PLUS_A",
                diag_pivot_thresh=0.0,
                options={"SymmetricMode": True},
            )
        except RuntimeError:  # a part held by no node (singular): leave it
            return
        x[nodes] = self.rest[nodes] + lu.solve(rhs)
