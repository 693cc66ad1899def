"""Posing the hand: bone transforms and the JLD-mapped flesh for given joint angles.

This is step 1 of the grasp algorithm (DESIGN.md): the contact solver poses the hand, then
builds the FE stiffness on the posed mesh and prescribes the bone nodes::

    from contact import load_hand, pose_hand

    hand = load_hand("coarse")
    pose = pose_hand(hand, {"index_mcp": 30.0, "index_pip": 20.0})
    pose.points          # (N, 3) posed flesh nodes (JLD mapping, bones rigid)
    pose.transforms      # bone name -> 4x4 rest-to-posed transform
    pose.mesh()          # fem.Mesh on the posed points (validated: positive volumes)

:class:`HandPoser` localises the nodes once (a few tenths of a second) and then poses
vectorised over nodes; :func:`pose_hand` keeps one poser per hand. A pose that inverts a
tetrahedron raises :class:`~contact.errors.PoseError` naming the joint and the element
(``check=False`` returns the pose with :attr:`Pose.inverted` filled instead).

The JLD mapping alone folds the flesh at deep flexions (the palmar flesh of a joint is
squeezed between the two bones, the skin of a joint's crease turns over): a final, bounded
correction, :class:`FleshRelaxer`, takes the free nodes around every tetrahedron the
mapping degraded (quality below :data:`RELAX_QUALITY` and below half its rest quality,
the rings of tetrahedra around them) and moves them, the bones and every other node held,
to the minimum of an untangling distortion energy measured from the rest shape. Where the
mapping keeps every tetrahedron fair, nothing moves (the rest pose is exact).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.sparse import csr_matrix

import fem
from fem.eigen3 import eigh3, rotation_svd3

from ..errors import PoseError
from . import relaxkernels
from .jld import JLDMap
from .shipped import Hand
from .skeleton import PIVOT_SUFFIX

__all__ = [
    "RELAX_QUALITY",
    "RELAX_RESTARTS",
    "RELAX_STALL",
    "RELAX_STOP",
    "RELAX_UNTANGLE",
    "FleshRelaxer",
    "HandPoser",
    "Pose",
    "pose_hand",
    "tet_quality",
    "tet_volumes",
]

#: A tetrahedron whose quality falls below this (and below half its rest quality) is
#: relaxed by :class:`FleshRelaxer`.
RELAX_QUALITY = 0.05
#: The relaxation stops once every tetrahedron it moves is above this fraction of that
#: threshold (a fifth: quality 0.01 at least).
RELAX_STOP = 0.2
#: ... or once three Newton steps in a row lower the patch's energy by less than this
#: fraction of it and leave as many tetrahedra inverted (stalled: typically a tetrahedron
#: no position of its free nodes mends).
RELAX_STALL = 1e-4
_LOG = logging.getLogger(__name__)

#: Rounds of restarts from a bone's rigid motion for the tetrahedra the passes leave
#: inverted (:meth:`FleshRelaxer.relax`).
RELAX_RESTARTS = 3
#: A restart first untangles its patch until every ``J = V / V_rest`` reaches this.
RELAX_UNTANGLE = 0.05


def _points_tets(points: ArrayLike, tets: ArrayLike) -> tuple[NDArray, NDArray]:
    """Points (N, 3) float and tetrahedra (M, 4) int64, contiguous, checked for the kernels."""
    pts = np.asarray(points, dtype=np.float64)
    t = np.asarray(tets)
    if pts.ndim != 2 or pts.shape[1] != 3 or t.ndim != 2 or t.shape[1] != 4:
        raise ValueError(
            f"expected points of shape (N, 3) and tetrahedra of shape (M, 4), got "
            f"{pts.shape} and {t.shape}"
        )
    t = np.ascontiguousarray(t, dtype=np.int64)
    if t.size and (t.min() < 0 or t.max() >= len(pts)):
        raise ValueError(f"tetrahedra refer to nodes outside 0..{len(pts) - 1}")
    return np.ascontiguousarray(pts), t


def tet_volumes(points: ArrayLike, tets: ArrayLike) -> NDArray[np.float64]:
    """Signed volumes of tetrahedra (positive for VTK's orientation), shape (M,)."""
    return relaxkernels.volumes_quality(*_points_tets(points, tets))[0]


def tet_quality(points: ArrayLike, tets: ArrayLike) -> NDArray[np.float64]:
    """Shape quality ``6 sqrt(2) V / l_rms^3`` of tetrahedra, shape (M,).

    1 for the regular tetrahedron, 0 for a flat one, negative for an inverted one
    (``l_rms`` is the root mean square of the six edge lengths).
    """
    return relaxkernels.volumes_quality(*_points_tets(points, tets))[1]


#: A warm start (:meth:`FleshRelaxer.relax_quality`) whose Newton run leaves a tetrahedron
#: of its part below this fraction of the stop floor is followed by the next start, the
#: better result kept. Measured on keyframed sequences of the fine hand at three quarters
#: of the limits (24 frames a second): without it, the warm frames' worst quality drifted
#: from frame to frame (0.0043, 0.0014, 0.0023 where cold frames gave 0.0048); retried
#: below the floor itself, the coarse hand's sequences took a fifth more Newton steps than
#: cold ones (109 against 95: its worst tetrahedra stay at 0.006 from any start); at half
#: the floor, 0.0048 and 86 steps.
_WARM_RETRY = 0.5
#: A warm start's mend (:meth:`FleshRelaxer._mend_locally`) that leaves a tetrahedron
#: inverted stops after this many Newton steps without a better iterate (fewer
#: inverted, then a better worst quality), and its fresh start follows. Measured on
#: 1,176 frames of the fine hand replayed at the full limits: a wrist mend of 545 free
#: nodes crept for 40 steps with one to three tetrahedra at quality -0.11, which the
#: fresh start over 82 nodes then mended in 13 (the frame 0.21 s, 65 steps; with the
#: stop 0.14 s, 45 steps); 4 frames changed, with the same qualities, 34 fewer steps in
#: all. At 4, 6 and 8 the slowest frame took 0.17-0.18 s, at 10 0.20 s.
_MEND_PATIENCE = 8
#: A tetrahedron whose ``J = det F`` is at most this takes the exact Hessian of its energy,
#: projected on its positive eigenvalues; a fairer one its convex part.
_EXACT_J = 0.25
#: The most unknowns (three a free node, and the least ``J``) of the dense max-min
#: untangling of a restart's fallback (:meth:`FleshRelaxer._maxmin`): its quadratic
#: subproblems are dense, their cost grows as the cube (measured: 136 unknowns and 464
#: tetrahedra, 0.1 to 2 s; a wider tangle, such as the wrist's, is left to the passes).
_MAXMIN_VARIABLES = 600
#: Relative residual of the conjugate gradients of a Newton step
#: (:func:`contact.hand.relaxkernels.block_cg`: an inexact Newton step).
#: Measured on the fine hand's random poses at half and three quarters of the limits
#: (80 each): as many Newton steps as at 1e-3 (334 and 1143 against 327 and 1165), a
#: fifth less time, the same worst qualities; at 1e-1 more steps at three quarters.
_CG_RTOL = 1e-2
#: ... or at most this many iterations (a Newton step of the fine hand's wrist takes 20-30).
_CG_MAXITER = 1000
#: For the 3 x 3 scaling block of :func:`_isotropic_eigen`: the index ``k`` third to
#: ``(p, q)`` and the off-diagonal mask (``d^2 det S / ds_p ds_q = s_k``).
_THIRD = np.array([[0, 2, 1], [2, 1, 0], [1, 0, 2]])
_OFF = 1.0 - np.eye(3)


def _cofactor(f: NDArray[np.float64]) -> NDArray[np.float64]:
    """Cofactor matrices of ``f`` (m, 3, 3): column k is column k+1 x column k+2."""
    a = np.moveaxis(f, 0, -1)
    c = np.empty_like(a)
    for k in range(3):
        k1, k2 = (k + 1) % 3, (k + 2) % 3
        for i in range(3):
            i1, i2 = (i + 1) % 3, (i + 2) % 3
            c[i, k] = a[i1, k1] * a[i2, k2] - a[i2, k1] * a[i1, k2]
    return np.moveaxis(c, -1, 0)


def _isotropic_eigen(
    f: NDArray[np.float64],
    a: NDArray[np.float64],
    cb: NDArray[np.float64],
    cj: NDArray[np.float64],
    c: NDArray[np.float64],
) -> tuple[NDArray[np.float64], ...]:
    """The eigensystem of an isotropic Hessian in ``vec F``, in factored form.

    The Hessian in ``vec F`` (row-major) of an energy of ``|F|^2`` and ``J = det F``,
    linear in ``|F|^2``: ``a I + 2 cb (F g^T + g F^T) + cj g g^T + c d^2 J / dF^2`` with
    ``g = cof F`` (``a`` twice the derivative in ``|F|^2``, ``cb`` the cross derivative,
    ``cj`` and ``c`` the second and first derivatives in ``J``). With ``F = U S V^T``
    (rotations ``U``, ``V``, the last singular value signed) its eigenvectors are ``U T
    V^T`` (Smith, de Goes and Kim 2019, "Analytic eigensystems for isotropic distortion
    energies"): for each pair ``(p, q)`` with third index ``k``, the twist ``(e_p e_q^T
    - e_q e_p^T) / sqrt 2`` with eigenvalue ``a + c s_k`` and the flip ``(e_p e_q^T +
    e_q e_p^T) / sqrt 2`` with ``a - c s_k``; and the eigenvectors ``E`` of the 3 x 3
    block on the scalings ``U e_p e_p^T V^T``, where ``F`` is ``s``, ``g`` is ``s_q s_k``
    and ``d^2 J`` is ``s_k`` off the diagonal. One SVD and one 3 x 3 eigenproblem a
    tetrahedron (closed forms, :mod:`fem.eigen3`), nothing of 9 x 9 built.

    Returns
    -------
    u, vt : ndarray, shape (m, 3, 3)
        The rotations of ``F``'s SVD.
    e : ndarray, shape (m, 3, 3)
        The scaling block's eigenvectors (columns).
    w : ndarray, shape (m, 9)
        The eigenvalues: the scalings', then a twist's and a flip's for each of the
        pairs (1, 2), (0, 2), (0, 1) (:func:`_eigenvectors` gives the vectors in that
        order, :func:`_eigen_gradients` their gradients in the nodes).
    """
    m = len(f)
    u, s, vt = rotation_svd3(f)
    g = s[:, [1, 0, 0]] * s[:, [2, 2, 1]]
    sg = s[:, :, None] * g[:, None, :]
    blk = (2.0 * cb)[:, None, None] * (sg + np.transpose(sg, (0, 2, 1)))
    blk += cj[:, None, None] * g[:, :, None] * g[:, None, :]
    blk += c[:, None, None] * s[:, _THIRD] * _OFF
    blk += a[:, None, None] * np.eye(3)
    w3, e = eigh3(blk)
    w = np.empty((m, 9))
    w[:, :3] = w3
    cs = c[:, None] * s  # the pairs' third indices are 0, 1, 2
    w[:, 3::2] = a[:, None] + cs
    w[:, 4::2] = a[:, None] - cs
    return u, vt, e, w


def _combine(
    outer: Callable[[list[int], list[int]], NDArray[np.float64]], e: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The nine eigenvectors' columns from ``outer(p, q)``, the images of ``e_p e_q^T``.

    ``outer`` maps index lists ``p``, ``q`` to an array whose last axis runs over the
    pairs; the result stacks the scalings (turned by ``e``), then a twist and a flip a
    pair, along the last axis.
    """
    scal = outer([0, 1, 2], [0, 1, 2]) @ e
    pq, qp = outer([1, 0, 0], [2, 2, 1]), outer([2, 2, 1], [1, 0, 0])
    out = np.empty((*scal.shape[:-1], 9))
    out[..., :3] = scal
    out[..., 3::2] = np.sqrt(0.5) * (pq - qp)
    out[..., 4::2] = np.sqrt(0.5) * (pq + qp)
    return out


def _eigenvectors(
    u: NDArray[np.float64], vt: NDArray[np.float64], e: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The eigenvectors (m, 9, 9 columns) ``vec(U T V^T)`` of :func:`_isotropic_eigen`."""

    def outer(p: list[int], q: list[int]) -> NDArray[np.float64]:  # (m, 9, pairs)
        return (u[:, :, None, p] * vt[:, q, None, :].transpose(0, 2, 3, 1)).reshape(
            len(u), 9, len(p)
        )

    return _combine(outer, e)


def _eigen_gradients(
    u: NDArray[np.float64],
    vt: NDArray[np.float64],
    e: NDArray[np.float64],
    dmat: NDArray[np.float64],
) -> NDArray[np.float64]:
    """``d (F : Q_k) / d x`` (m, 12, 9) of the eigenvectors ``Q_k`` of :func:`_isotropic_eigen`.

    ``F = X^T D`` (``D = dmat``, (m, 4, 3)), so ``d (F : U e_p e_q^T V^T) / d x_ni`` is
    ``U_ip (D V)_nq``: outer products of ``U``'s columns and ``D V``'s, 108 numbers a
    tetrahedron, without the eigenvectors themselves (the eigensystem and these on 2,600
    tetrahedra: 8.0 against 9.9 ms through the vectors and ``D^T``).
    """
    dv = dmat @ np.transpose(vt, (0, 2, 1))  # (m, 4, 3)

    def outer(p: list[int], q: list[int]) -> NDArray[np.float64]:  # (m, 12, pairs)
        return (dv[:, :, None, q] * u[:, None, :, p]).reshape(len(u), 12, len(p))

    return _combine(outer, e)


def _regularised(j: NDArray[np.float64], d2: float) -> tuple[NDArray, NDArray]:
    """``sqrt(j^2 + 4 d2)`` and Escobar's ``h = (j + sqrt(j^2 + 4 d2)) / 2`` of ``j``.

    Without cancellation where ``j << 0`` (inverted): ``(j + r)(r - j) = 4 d2``.
    """
    r = np.sqrt(j * j + 4.0 * d2)
    h = 0.5 * (j + r)
    neg = j < 0.0
    h[neg] = 2.0 * d2 / (r[neg] - j[neg])
    return r, h


def _density(
    nf: NDArray[np.float64], h23: NDArray[np.float64], h: NDArray[np.float64], kappa: float
) -> NDArray[np.float64]:
    """The energy density: ``|F|^2 h^(-2/3) / 3 + kappa (h + 1/h) / 2`` (``h23 = h^(-2/3)``)."""
    return nf * h23 / 3.0 + 0.5 * kappa * (h + 1.0 / h)


class FleshRelaxer:
    """Untangles and relaxes the free nodes around degraded tetrahedra of a posed mesh.

    The energy of a tetrahedron with deformation gradient ``F`` (from its rest shape),
    ``J = det F`` and rest volume ``V`` is ``V (|F|^2 / (3 h^(2/3)) + kappa (h + 1/h) / 2)``:
    the mean-ratio distortion (1 for a rotation, growing with any change of shape) and a
    volume term (least at the rest volume), with ``h = (J + sqrt(J^2 + 4 delta^2)) / 2``
    the regularised determinant of Escobar et al. (2003), positive even for an inverted
    tetrahedron, so the energy is finite and smooth on a tangled start and pushes every
    volume positive (it grows as ``1/h``, like ``|J| / delta^2``, on inverted ones).

    The free nodes of the tetrahedra within ``pass_rings`` rings of the degraded ones move to
    the energy's minimum, the bones and every other node held, by a projected Newton
    method: each tetrahedron's 12 x 12 Hessian made positive semi-definite (on a fair
    tetrahedron, ``J > 1/4``, the convex part of the energy: the distortion's
    ``a |dF|^2`` and the volume's curvature along ``cof F``; on a degenerate or inverted
    one, the exact Hessian in ``F`` projected on its positive eigenvalues), assembled on
    the patch's fixed sparsity pattern, the step solved by conjugate gradients to 1e-2
    (block Jacobi preconditioner), then a backtracking line search. Escobar's ``delta``
    follows the most inverted tetrahedron of the patch, ``sqrt(eps (eps - J_min))``
    with ``eps`` the ``delta`` given: a gentle barrier on a tangled patch, a steep one
    (``eps / 10``) once every ``J`` exceeds ``eps``. A pass keeps its iterate with the
    fewest inverted tetrahedra (then the best worst quality): the gentle barrier of a
    tangled patch can let the count grow on the way. It stops when its energy stalls
    (:data:`RELAX_STALL`). A patch still inverted at the minimum is widened by a ring
    around its inverted tetrahedra (``rounds``), as long as the wider patch mends more
    (the fair ones left below the floor are the final relaxation's); a pass that leaves more
    inverted than before is undone. Each connected part of a patch is minimised on its
    own; in the first pass, from the lower-energy of two starts, the mapping and the
    harmonic fill of its folds (:meth:`_first_pass`). With ``bone_id``, a tetrahedron
    still inverted after the passes (a fold Newton's method cannot leave) restarts its
    neighbourhood from a nearby bone's rigid motion,
    untangled by a penalty on the volumes or, failing that, by maximising the least
    volume (:meth:`relax_quality`); last, the positive tetrahedra left below the stop floor are
    relaxed once more on their own. A Newton step's element terms, assembly, line
    search and conjugate gradients are compiled loops over the tetrahedra
    (:mod:`contact.hand.relaxkernels`); the rest is vectorised over them.

    Parameters
    ----------
    points : array_like, shape (N, 3)
        Rest positions.
    tets : array_like of int, shape (M, 4)
        Positively oriented tetrahedra.
    fixed : array_like of bool, shape (N,)
        Nodes that never move (the bone nodes).
    kappa, delta : float
        Weight of the volume term and the regularisation of the determinant.
    rings : int
        Rings of tetrahedra around the degraded ones whose free nodes move in a restart
        and in the final relaxation (:meth:`relax_quality`).
    pass_rings : int
        The same in the first pass (one ring more a pass). Measured on the fine hand's
        poses of ``benchmarks.posing`` at half and three quarters of the limits (80
        each), from the first pass's two starts: one ring instead of two, a quarter and
        two fifths less time, as few inverted poses (none; none either at the full
        limits, nor on the coarse hand) and as good a worst quality (0.0100 and 0.0052
        against 0.0101 and 0.0034).
    rounds : int
        At most this many passes (each on the tetrahedra still inverted, one ring more).
    maxiter : int
        Newton iterations per pass.
    bone_id : array_like of int, shape (N,), optional
        The bone each fixed node belongs to (-1 free). With it, a tetrahedron still
        inverted after the passes restarts its neighbourhood from a bone's rigid motion
        (see :meth:`relax`).
    """

    def __init__(
        self,
        points: ArrayLike,
        tets: ArrayLike,
        fixed: ArrayLike,
        *,
        kappa: float = 1.0,
        delta: float = 1e-2,
        rings: int = 2,
        pass_rings: int = 1,
        rounds: int = 3,
        maxiter: int = 40,
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
        self._bm = np.linalg.inv(dm)
        self._bmt = np.ascontiguousarray(np.transpose(self._bm, (0, 2, 1)))
        # dF/dx: F_ij = sum_a x_a,i D_aj (D: node a's row, the first one minus the others)
        self._dmat = np.concatenate([-self._bm.sum(axis=1, keepdims=True), self._bm], axis=1)
        self._ddt = self._dmat @ np.transpose(self._dmat, (0, 2, 1))
        self._vol = np.linalg.det(dm) / 6.0
        self.rest_quality = tet_quality(x, self.tets)
        # the stop floor of every tetrahedron (RELAX_STOP of its degraded threshold)
        self._floor = RELAX_STOP * np.minimum(RELAX_QUALITY, 0.5 * self.rest_quality)
        self.kappa, self.delta = float(kappa), float(delta)
        self.rings, self.rounds, self.maxiter = int(rings), int(rounds), int(maxiter)
        self.pass_rings = int(pass_rings)
        m = len(self.tets)
        self._n2t = csr_matrix(
            (np.ones(4 * m), (self.tets.ravel(), np.repeat(np.arange(m), 4))),
            shape=(len(x), m),
        )
        # the P1 stiffness of the rest shape (sum V grad N_a . grad N_b), for _fill
        pairs = (np.repeat(self.tets, 4, axis=1).ravel(), np.tile(self.tets, (1, 4)).ravel())
        self._laplacian = csr_matrix(
            ((self._ddt * self._vol[:, None, None]).ravel(), pairs), shape=(len(x), len(x))
        )
        self._laplacian.sum_duplicates()
        self.stats: dict[str, int] = {}

    def degraded(
        self, x: NDArray[np.float64], quality: NDArray[np.float64] | None = None
    ) -> NDArray[np.int64]:
        """Tetrahedra below :data:`RELAX_QUALITY` and below half their rest quality.

        ``quality``: every tetrahedron's quality at ``x``, if known (else computed).
        """
        q = tet_quality(x, self.tets) if quality is None else quality
        return np.flatnonzero((q < RELAX_QUALITY) & (q < 0.5 * self.rest_quality))

    def _cells(self, nodes: NDArray[np.int64]) -> NDArray[np.int64]:
        """The tetrahedra around ``nodes``, sorted.

        The rows of the node-to-tetrahedron incidence gathered by their offsets and
        marked on a mask: a tenth of the time of slicing the sparse matrix and sorting
        (0.2 against 2.3 ms around 800 nodes of the fine hand).
        """
        ptr = self._n2t.indptr
        nodes = np.asarray(nodes, dtype=np.int64)
        start = ptr[nodes]
        counts = ptr[nodes + 1] - start
        offsets = np.repeat(start - np.cumsum(counts) + counts, counts)
        offsets += np.arange(len(offsets))
        mark = np.zeros(len(self.tets), dtype=bool)
        mark[self._n2t.indices[offsets]] = True
        return np.flatnonzero(mark)

    def _requality(
        self, q: NDArray[np.float64], x: NDArray[np.float64], nodes: NDArray[np.int64]
    ) -> None:
        """Update the qualities ``q`` of the tetrahedra around ``nodes`` (moved) in place.

        A pass, a restart or the polish moves a patch: the rest of the mesh keeps its
        quality, so only the patch's tetrahedra are measured again (on the fine hand a
        whole-mesh quality costs several times a mild pose's Newton steps).
        """
        cells = self._cells(nodes)
        q[cells] = tet_quality(x, np.take(self.tets, cells, axis=0))

    def energy(
        self, x: NDArray[np.float64], cells: NDArray[np.int64] | None = None
    ) -> tuple[float, NDArray[np.float64]]:
        """Energy of the tetrahedra ``cells`` (default all) and its gradient, shape (N, 3)."""
        cells = np.arange(len(self.tets)) if cells is None else cells
        e, g, _, _ = self._terms(x, self._gather(cells), self.delta, hessian=False)
        grad = np.zeros_like(x)
        t = self.tets[cells]
        for k in range(3):
            grad[:, k] = np.bincount(t.ravel(), g[..., k].ravel(), minlength=len(x))
        return float(e.sum()), grad

    def _gather(self, cells: NDArray[np.int64]) -> dict[str, NDArray]:
        """The per-tetrahedron data of ``cells``, taken once for a patch's Newton steps.

        ``np.take`` along the first axis: 0.10 against 0.26 ms for indexing with
        ``cells`` (5,000 of 200,000 tetrahedra).
        """
        return {
            "cells": cells,
            "tets": np.take(self.tets, cells, axis=0),
            "vol": np.take(self._vol, cells),
            "dmat": np.take(self._dmat, cells, axis=0),
            "ddt": np.take(self._ddt, cells, axis=0),
        }

    def _energy(self, x: NDArray[np.float64], patch: dict[str, NDArray], delta: float) -> float:
        """The energy of a patch's tetrahedra alone (the line search's); see :meth:`_gather`."""
        return relaxkernels.patch_energy(
            x, patch["tets"], patch["dmat"], patch["vol"], delta * delta, self.kappa
        )

    def _terms(self, x, patch, delta, hessian=True):
        """Energy per tetrahedron, gradient per node (m, 4, 3) and Hessian, in numpy.

        The reference of the Newton step's compiled kernel
        (:func:`contact.hand.relaxkernels.step_terms`, tested equal to round-off), and the
        terms of :meth:`energy`.
        The Hessian in two parts, their sum: ``hk`` (m, 12, 12) and ``lap`` (m, 4, 4),
        whose ``lap x I3`` (the distortion's ``a |dF|^2`` on a fair tetrahedron, the same
        for the three components) is assembled on node pairs
        (:func:`contact.hand.relaxkernels.block_pattern`), a third of the work of adding it
        into ``hk``'s diagonal blocks. ``patch``: the tetrahedra's data
        (:meth:`_gather`). Without ``hessian``: ``hk`` and ``lap`` None.
        """
        tets, vol, dmat = patch["tets"], patch["vol"], patch["dmat"]
        cells = patch["cells"]
        f = np.transpose(np.take(x, tets, axis=0), (0, 2, 1)) @ dmat
        cof = _cofactor(f)
        j = np.einsum("ij,ij->i", f[:, :, 0], cof[:, :, 0])
        d2 = delta * delta
        r, h = _regularised(j, d2)
        nf = np.einsum("mij,mij->m", f, f)
        k = self.kappa
        h23 = h ** (-2.0 / 3.0)
        e = vol * _density(nf, h23, h, k)
        h1 = h / r  # dh/dJ
        wj = -(2.0 / 9.0) * nf * h23 / h + 0.5 * k * (1.0 - 1.0 / (h * h))  # dW/dh
        c = wj * h1  # dW/dJ
        pk = (2.0 / 3.0) * h23[:, None, None] * f + c[:, None, None] * cof  # dW/dF
        dmt = np.transpose(dmat, (0, 2, 1))
        grad = vol[:, None, None] * np.transpose(pk @ dmt, (0, 2, 1))
        if not hessian:
            return e, grad, None, None
        a = (2.0 / 3.0) * h23
        wjj = (10.0 / 27.0) * nf * h23 / (h * h) + k / h**3  # d^2 W / dh^2
        cj = wjj * h1 * h1 + wj * 2.0 * d2 / r**3  # d^2 W / dJ^2
        m = len(cells)
        # a fair tetrahedron: the convex part of the energy's Hessian in F, the
        # distortion's a |dF|^2 and the volume's curvature along cof F (the rest is
        # indefinite): a (D D^T) x I3 + max(cj, 0) u u^T with u = d J / d x (written for
        # every tetrahedron, then replaced on the others), times the rest volume
        u = np.transpose(cof @ dmt, (0, 2, 1)).reshape(m, 12)
        u *= np.sqrt(vol * np.maximum(cj, 0.0))[:, None]
        hk = u[:, :, None] * u[:, None, :]
        # a degenerate or inverted one: the exact Hessian in F projected on its positive
        # eigenvalues (in hk, with its share of a |dF|^2: no Laplacian part)
        bad = j <= _EXACT_J
        lap = vol * a
        lap[bad] = 0.0
        lap = patch["ddt"] * lap[:, None, None]
        if bad.any():
            cb = -(2.0 / 9.0) * h23[bad] / h[bad] * h1[bad]  # d^2 W / d(nf) dJ
            u, vt, ev, w = _isotropic_eigen(f[bad], a[bad], cb, cj[bad], c[bad])
            w = np.maximum(w, 1e-8 * a[bad, None]) * vol[bad, None]
            gq = _eigen_gradients(u, vt, ev, dmat[bad])
            hk[bad] = (gq * w[:, None, :]) @ np.transpose(gq, (0, 2, 1))
        return e, grad, hk, lap

    def relax(self, x: ArrayLike) -> tuple[NDArray[np.float64], int]:
        """Move the free nodes around the degraded tetrahedra of the posed points ``x``.

        See :meth:`relax_quality`, which also returns the qualities of the result.

        Returns
        -------
        points : ndarray, shape (N, 3)
            ``x`` itself (not copied) when no tetrahedron is degraded.
        moved : int
            Free nodes moved.
        """
        points, moved, _ = self.relax_quality(x)
        return points, moved

    def relax_quality(
        self, x: ArrayLike, warm: ArrayLike | None = None
    ) -> tuple[NDArray[np.float64], int, NDArray[np.float64]]:
        """Move the free nodes around the degraded tetrahedra of the posed points ``x``.

        Passes of Newton's method over the degraded tetrahedra and ``pass_rings`` rings
        around them, then over the tetrahedra still inverted (one ring more a pass, up to
        ``rounds``). Measured on keyframed sequences of the fine hand at its full limits
        (24 sequences, 1,176 frames), against later passes over every tetrahedron still
        degraded: the same mean, tail and qualities, but its worst frame 0.66 against
        1.05 s (a second pass over 1,643 nodes, 15 Newton steps, had mended nothing that
        the restart then mended over 119). Then, with ``bone_id``, restarts
        of the clusters left inverted from a bone's rigid motion (:meth:`_restart`);
        then one relaxation around the positive tetrahedra left below the stop floor
        (:meth:`_polish`). ``stats`` counts the Newton iterations, passes, stalls,
        restarts (of which ``feasible``: the max-min fallback's, :meth:`_feasible_restart`),
        the tetrahedra polished and the warm starts mended locally (:meth:`_mend_locally`).

        ``warm``, shape (N, 3), optional: a third start for the first pass (next to the
        mapping and its harmonic fill), typically the mapping plus the previous frame's
        correction (a warm start, :meth:`HandPoser.pose`). Only its free nodes in the
        patch around the tetrahedra ``x`` degrades are used, and only where its energy is
        the lowest: a warm start never moves a node the mapping alone leaves in place.

        Returns
        -------
        points : ndarray, shape (N, 3)
            ``x`` itself (not copied) when no tetrahedron is degraded.
        moved : int
            Free nodes moved.
        quality : ndarray, shape (M,)
            :func:`tet_quality` of every tetrahedron at ``points`` (its sign is the
            volume's: a caller needs no other pass over the mesh to find inverted ones).
        """
        x = np.asarray(x, dtype=np.float64)
        q = tet_quality(x, self.tets)
        bad = self.degraded(x, q)
        self.stats = {
            "iterations": 0,
            "passes": 0,
            "stalled": 0,
            "restarts": 0,
            "feasible": 0,
            "polished": 0,
            "mended": 0,
        }
        if len(bad) == 0:
            return x, 0, q
        x = x.copy()
        moved = np.zeros(len(x), dtype=bool)
        inverted = int((q[bad] <= 0.0).sum())
        for k in range(self.rounds):
            nodes = self._ring(np.unique(self.tets[bad]), self.pass_rings + k)
            free = nodes[~self.fixed[nodes]]
            if len(free) == 0:
                break
            moved[free] = True
            self.stats["passes"] += 1
            before = x[free].copy()
            if k == 0:
                left = self._first_pass(x, free, bad, q, warm)
            else:
                self._minimise(x, free)
                self._requality(q, x, free)
                left = int((q <= 0.0).sum())
            # a wider pass is for what is left inverted (the tetrahedra left fair but below
            # the floor are the polish's)
            bad = np.flatnonzero(q <= 0.0)
            if left > inverted:  # worse than before the pass: undo it
                x[free] = before
                self._requality(q, x, free)
                break
            # done, or a wider patch did not help: what is left is reported by the caller
            if left == 0 or (k > 0 and left == inverted):
                break
            inverted = left
        if self.bone_id is not None:
            self._restart(x, moved, q)
        self._polish(x, moved, q)
        return x, int(moved.sum()), q

    def _first_pass(
        self,
        x: NDArray[np.float64],
        free: NDArray[np.int64],
        bad: NDArray[np.int64],
        q: NDArray[np.float64],
        warm: ArrayLike | None = None,
    ) -> int:
        """The first pass: Newton's method from the best of two or three starts (in place).

        The mapping's positions, or the harmonic fill (:meth:`_fill`) of the free nodes
        of the degraded tetrahedra ``bad`` and one ring around them, where the mapping
        folds the flesh. Each connected part of the patch ``free`` (see
        :meth:`_minimise`) starts from the one of lower energy; should Newton's method
        leave a tetrahedron of the part inverted, it is run again from the other start
        and the better result kept (fewer inverted, then the better worst quality).
        Measured on the fine hand's wrist at three quarters of its limits: from the
        mapping's fold (536 inverted tetrahedra) 27 Newton steps, from its fill (320
        inverted, a third of the energy) 4. ``warm``: a third start (see
        :meth:`relax_quality`), competing on energy with the two others: where it is
        the lowest, it is mended around its degraded tetrahedra alone
        (:meth:`_mend_locally`). Where those reach across the whole part, Newton's
        method runs on the part from the starts in order of energy, and a run from the
        warm start that leaves a tetrahedron below :data:`_WARM_RETRY` of the floor is
        followed by the next start. (Mending the warm start wherever it is below the
        mapping's energy, without making the fill, saved about 12 ms a frame at the
        full limits, but carried stale corrections at a quarter of them: worst quality
        0.010 where the fill, taken as it is, gave 0.030.) ``q``: the qualities at
        ``x``, kept up to date. Returns the tetrahedra left inverted.
        """
        start = x[free].copy()
        core = self._ring(np.unique(self.tets[bad]), 1)
        self._fill(x, core[~self.fixed[core]])
        filled = x[free].copy()
        warm = None if warm is None else np.asarray(warm, dtype=np.float64)
        for part in self._parts(free):
            at = np.searchsorted(free, part)
            cells = self._cells(part)
            floor = self._floor[cells]
            patch = self._gather(cells)
            starts = [filled[at], start[at]]
            if warm is not None:
                starts.append(warm[part])
            energies = []
            for y in starts:
                x[part] = y
                energies.append(self._energy(x, patch, self.delta))
            order = np.argsort(energies, kind="stable")
            if order[0] == 2:
                # the warm start the lowest: mended where it is degraded (a part left
                # inverted goes to the next, wider pass)
                x[part] = starts[2]
                if self._mend_locally(x, part, patch, floor) is not None:
                    continue
            best = None
            for i in order:
                x[part] = starts[i]
                self._newton(x, part)
                qp = tet_quality(x, patch["tets"])
                key = (int((qp <= 0.0).sum()), -float(qp.min()))
                if best is None or key < best[0]:
                    best = (key, x[part].copy())
                # a warm start that leaves a tetrahedron well below the floor may keep
                # the previous frame's worst one: the next start is tried too, the best
                # kept (see _WARM_RETRY)
                if key[0] == 0 and not (i == 2 and (qp <= _WARM_RETRY * floor).any()):
                    break
            assert best is not None
            x[part] = best[1]
        self._requality(q, x, free)
        return int((q <= 0.0).sum())

    def _mend_locally(
        self,
        x: NDArray[np.float64],
        part: NDArray[np.int64],
        patch: dict[str, NDArray],
        floor: NDArray[np.float64],
    ) -> tuple[int, float] | None:
        """Mend a warm start around its degraded tetrahedra alone (in place).

        A warm start (the previous frame's correction on the new mapping) is fair almost
        everywhere: the tetrahedra the frame's motion turned over or flattened are what
        is left to mend, not the whole part (a wrist's thousand nodes). Newton's method
        moves the free nodes within ``rings`` rings of the tetrahedra of the part below
        the stop floor. Where that leaves some below :data:`_WARM_RETRY` of the floor
        (or inverted), the free nodes within ``rings`` of those start afresh from their
        harmonic fill inside the warm start (so that a fold is not carried from frame to
        frame) and Newton's method runs there again; the better of the two is kept. A
        part still inverted is left so: the next pass widens the patch around what is
        left (the whole part's starts, each a Newton run over the part, untangle no more
        than that: measured on the frames that needed them, 11, 24 and 25 steps over
        1,254 nodes, where the wider pass took 8).

        ``patch`` and ``floor``: the part's tetrahedra (:meth:`_gather`) and their stop
        floors. Measured on three keyframed sequences of the fine hand from rest (147
        frames each, 24 a second), against Newton runs over the whole part from the
        warm start and, below half the floor, from the two others: at the full limits a
        frame 0.13 against 0.31 s on average, 0.42 against 2.8 s at most, worst quality
        0.0016 against 0.0015; at three quarters of them 0.054 against 0.073 s, at most
        0.13 against 0.20 s, worst quality 0.0043 against 0.0048.

        Returns
        -------
        tuple or None
            ``(inverted, -worst quality)`` of the part (``x`` holds it); None where the
            warm start's degraded tetrahedra reach across the whole part (``x``
            untouched: the part's own Newton run is no dearer).
        """
        tets, cells = patch["tets"], patch["cells"]
        q = tet_quality(x, tets)
        low = cells[q <= floor]
        if not low.size:
            return 0, -float(q.min())
        near = self._around(low, part)
        if not near.size or near.size == part.size:  # nothing to move, or no smaller patch
            return None
        self.stats["mended"] += 1
        self._newton(x, near, _MEND_PATIENCE)
        q = tet_quality(x, tets)
        key = (int((q <= 0.0).sum()), -float(q.min()))
        still = q <= _WARM_RETRY * floor
        if not still.any():
            return key
        # a fresh start around what is left
        kept = x[part].copy()
        near = self._around(cells[still], part)
        self._fill(x, near)
        self._newton(x, near)
        q = tet_quality(x, tets)
        fresh = (int((q <= 0.0).sum()), -float(q.min()))
        if key <= fresh:
            x[part] = kept
            return key
        return fresh

    def _around(self, cells: NDArray[np.int64], part: NDArray[np.int64]) -> NDArray[np.int64]:
        """The nodes of ``part`` within ``rings`` rings of the tetrahedra ``cells``, sorted."""
        near = self._ring(np.unique(self.tets[cells]), self.rings)
        return np.intersect1d(near, part, assume_unique=True)

    def _fill(self, x: NDArray[np.float64], nodes: NDArray[np.int64]) -> None:
        """Move free ``nodes`` to the harmonic extension of the displacement around them.

        The displacement ``u = x - rest`` of ``nodes`` minimises the Dirichlet energy
        ``sum V |grad u|^2`` of the tetrahedra around them (linear, on the rest shape),
        every other node held: ``K_ff u_f = -K_fb u_b``. A smooth start where the mapping
        folds the flesh: it has no folds of its own on a moderate rotation (it shrinks a
        deep one's volumes rather than turning them over). In place.

        ``K`` is the whole mesh's P1 stiffness, assembled once (:attr:`_laplacian`): a
        node's rows hold exactly the tetrahedra around it, so ``K_ff`` and ``K_fb`` are
        its rows sliced. Factored by SuperLU in symmetric mode on a minimum-degree
        ordering of ``K + K^T``. Measured on 2,936 nodes of the fine hand at its full
        limits: 7.6 against 26.6 ms assembling it from the tetrahedra and factoring it on
        SuperLU's default column ordering, the same fill to 2e-16.
        """
        from scipy.sparse.linalg import splu

        if len(nodes) == 0:
            return
        rows = self._laplacian[nodes]
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

    def _polish(
        self, x: NDArray[np.float64], moved: NDArray[np.bool_], q: NDArray[np.float64]
    ) -> None:
        """Relax once more around the positive tetrahedra left below the stop floor.

        A pass over a wide patch ends when its energy no longer falls by a thousandth:
        one nearly flat tetrahedron among thousands passes that test (measured: quality
        1e-4, a split tetrahedron by a bone node). Around those alone (``rings`` rings),
        the same energy is dominated by them. Kept only if the patch's worst quality
        improves and nothing more is inverted. ``q``: the qualities at ``x``.
        """
        floor = self._floor
        low = np.flatnonzero((q > 0.0) & (q < floor))
        if len(low) == 0:
            return
        free = self._ring(np.unique(self.tets[low]), self.rings)
        free = free[~self.fixed[free]]
        if len(free) == 0:
            return
        cells = self._cells(free)
        q0 = q[cells]
        before = x[free].copy()
        self.stats["polished"] = len(low)
        self._minimise(x, free)
        q1 = tet_quality(x, self.tets[cells])
        if (q1 <= 0.0).sum() > (q0 <= 0.0).sum() or q1[q1 > 0.0].min() < q0[q0 > 0.0].min():
            x[free] = before
            return
        q[cells] = q1
        moved[free] = True

    def _rigid(
        self, x: NDArray[np.float64], bone: int
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The rest-to-posed rigid motion of a bone, from its nodes: rotation, translation.

        The least-squares fit (Kabsch) of the bone's rest nodes to their posed places,
        exact for nodes that move rigidly (to round-off).
        """
        nodes = np.flatnonzero(self.bone_id == bone)
        p, q = self.rest[nodes], x[nodes]
        pc, qc = p.mean(axis=0), q.mean(axis=0)
        u, _, vt = np.linalg.svd((p - pc).T @ (q - qc))
        d = np.sign(np.linalg.det(vt.T @ u.T))
        rot = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
        return rot, qc - pc @ rot.T

    def _ring(self, nodes: NDArray[np.int64], rings: int) -> NDArray[np.int64]:
        """``nodes`` and the nodes of the tetrahedra within ``rings`` rings of them."""
        for _ in range(rings):
            mark = np.zeros(len(self.rest), dtype=bool)
            mark[self.tets[self._cells(nodes)]] = True
            nodes = np.flatnonzero(mark)
        return nodes

    def _restart(
        self, x: NDArray[np.float64], moved: NDArray[np.bool_], q: NDArray[np.float64]
    ) -> None:
        """Restart the neighbourhood of every tetrahedron left inverted (in place).

        A tetrahedron the passes leave inverted sits in a fold that Newton's method on
        the regularised energy cannot leave (measured on the fine hand: a split joint-gap
        tetrahedron folded over its bone node; the untangling energy alone, with five
        rings of free nodes, keeps it inverted, yet its rest shape carried rigidly by
        that bone is positive). Each cluster of inverted tetrahedra (joined by a node)
        restarts the free nodes of the tetrahedra around it from a bone's rigid motion,
        where their rest shape is fair: the bone of the cluster's fixed nodes, or else
        the one with most fixed nodes within two rings of it, then the next; one ring of
        tetrahedra around the cluster, then none, then two. The free nodes within
        ``rings + 1`` rings of the cluster (then ``rings + 2``) are untangled from there
        (:meth:`_untangle`), then relaxed; a restart is kept
        when fewer tetrahedra of that patch are inverted, undone otherwise (Newton's
        path from a restart is sensitive to its start: the variants are tried in turn,
        about a tenth of a second each). A cluster none of them mends falls back on
        maximising the least ``J`` of a smaller patch (:meth:`_feasible_restart`). Up to
        :data:`RELAX_RESTARTS` rounds. ``q``: the
        qualities at ``x``, kept up to date.
        """
        from scipy.sparse.csgraph import connected_components

        for _ in range(RELAX_RESTARTS):
            inv = np.flatnonzero(q <= 0.0)
            if len(inv) == 0:
                return
            # clusters: inverted tetrahedra joined by a node
            a = self._n2t[:, inv]
            _, label = connected_components(a.T @ a, directed=False)
            mended = False
            for c in range(label.max() + 1):
                cluster = inv[label == c]
                mended |= self._restart_cluster(x, moved, cluster)
                # every patch a restart moves lies within rings + 2 rings of the cluster
                self._requality(q, x, self._ring(np.unique(self.tets[cluster]), self.rings + 2))
            if not mended:
                return

    def _restart_cluster(
        self, x: NDArray[np.float64], moved: NDArray[np.bool_], cluster: NDArray[np.int64]
    ) -> bool:
        """Restart one cluster of inverted tetrahedra (see :meth:`_restart`): mended or not."""
        core = np.unique(self.tets[cluster])
        # candidate bones: the cluster's own, then the others within two rings of it
        own = self.bone_id[core]
        near = self.bone_id[self._ring(core, 2)]
        own, near = own[own >= 0], near[near >= 0]
        if len(near) == 0:
            return False
        count = np.bincount(near) + len(near) * np.bincount(own, minlength=near.max() + 1)
        candidates = np.argsort(-count, kind="stable")[: min(2, int((count > 0).sum()))]
        for patch in (self.rings + 1, self.rings + 2):
            free = self._ring(core, patch)
            free = free[~self.fixed[free]]
            if self._restarts(x, moved, core, free, candidates, (1, 0, 2), self._untangle):
                return True
        return self._feasible_restart(x, moved, cluster, core, candidates)

    def _restarts(
        self,
        x: NDArray[np.float64],
        moved: NDArray[np.bool_],
        core: NDArray[np.int64],
        free: NDArray[np.int64],
        candidates: NDArray[np.int64],
        reaches: tuple[int, ...],
        untangle: Callable[[NDArray[np.float64], NDArray[np.int64]], object],
    ) -> bool:
        """Restart a fold from the candidate bones' rigid motions; keep the first that helps.

        The nodes within each of ``reaches`` rings of ``core`` are carried by each
        candidate bone, the ``free`` patch untangled (``untangle``) and relaxed; the
        first that leaves fewer of the patch's tetrahedra inverted is kept (True),
        otherwise the patch is put back.
        """
        cells = self._cells(free)
        n_before = int((tet_volumes(x, self.tets[cells]) <= 0.0).sum())
        before = x[free].copy()
        for reach in reaches:
            inner = self._ring(core, reach)
            inner = inner[~self.fixed[inner]]
            for b in candidates.tolist():
                rot, shift = self._rigid(x, b)
                x[inner] = self.rest[inner] @ rot.T + shift
                self.stats["restarts"] += 1
                untangle(x, free)
                self._minimise(x, free)
                if int((tet_volumes(x, self.tets[cells]) <= 0.0).sum()) < n_before:
                    moved[free] = True
                    return True
                x[free] = before
        return False

    def _feasible_restart(
        self,
        x: NDArray[np.float64],
        moved: NDArray[np.bool_],
        cluster: NDArray[np.int64],
        core: NDArray[np.int64],
        candidates: NDArray[np.int64],
    ) -> bool:
        """The fallback of a restart: untangle by maximising the patch's least ``J``.

        The penalty of :meth:`_untangle` sums the shortfalls of every tetrahedron: where
        the free nodes of a fold cannot mend one tetrahedron without denting its
        neighbours, its minimum keeps that one just inverted (measured on the fine
        hand's index MCP split tetrahedron in a random full-limits pose, seed 7: every
        restart variant left ``J`` about -0.002, however wide the patch). The least
        ``J`` itself, maximised with the others as constraints (:meth:`_maxmin`), leaves
        that trade: from the cluster's own free nodes carried rigidly by a candidate
        bone, it reaches ``J`` = :data:`RELAX_UNTANGLE` on every tetrahedron of the
        patch (``rings`` rings around the cluster). The cluster's own nodes are
        restarted, then one ring and two rings around it; the patch is then relaxed as
        any other, and kept when fewer of its tetrahedra are inverted.
        """
        free = self._ring(core, self.rings)
        free = free[~self.fixed[free]]
        if len(free) == 0 or 3 * len(free) > _MAXMIN_VARIABLES:
            return False

        def maxmin(x: NDArray[np.float64], free: NDArray[np.int64]) -> None:
            self.stats["feasible"] += 1
            self._maxmin(x, free)

        return self._restarts(x, moved, core, free, candidates, (0, 1, 2), maxmin)

    def _maxmin(self, x: NDArray[np.float64], free: NDArray[np.int64]) -> None:
        """Move ``free`` to maximise the least ``J = V / V_rest`` around them (in place).

        ``max t`` subject to ``J_i >= t`` for every tetrahedron ``i`` around ``free`` and
        ``t <=`` :data:`RELAX_UNTANGLE`, by sequential quadratic programming (SLSQP,
        dense: a small patch only, :data:`_MAXMIN_VARIABLES`), in the displacements
        scaled by the patch's mean edge length so that the problem is of order one.
        """
        from scipy.optimize import minimize

        cells = self._cells(free)
        tets, dmat = self.tets[cells], self._dmat[cells]
        dmt = np.transpose(dmat, (0, 2, 1))
        local = np.full(len(x), -1, dtype=np.int64)
        local[free] = np.arange(len(free))
        lt = local[tets]
        at = lt >= 0
        rows = np.broadcast_to(np.arange(len(cells))[:, None, None], (len(cells), 4, 3))[at]
        cols = (3 * lt[:, :, None] + np.arange(3))[at]
        h = float(np.cbrt(self._vol[cells].mean()))
        x0 = x[free].copy()
        n = 3 * len(free)

        def volumes(z: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
            x[free] = x0 + h * z[:n].reshape(-1, 3)
            f = np.transpose(x[tets], (0, 2, 1)) @ dmat
            cof = _cofactor(f)
            return np.einsum("ij,ij->i", f[:, :, 0], cof[:, :, 0]), cof

        def margin(z: NDArray[np.float64]) -> NDArray[np.float64]:
            return volumes(z)[0] - z[n]

        def margin_jac(z: NDArray[np.float64]) -> NDArray[np.float64]:
            _, cof = volumes(z)
            g = h * np.transpose(cof @ dmt, (0, 2, 1))  # dJ / dz, (m, 4, 3)
            jac = np.zeros((len(cells), n + 1))
            jac[rows, cols] = g[at]
            jac[:, n] = -1.0
            return jac

        z0 = np.zeros(n + 1)
        z0[n] = volumes(z0)[0].min() - 0.01
        objective = np.zeros(n + 1)
        objective[n] = -1.0
        res = minimize(
            lambda z: -z[n],
            z0,
            jac=lambda z: objective,
            bounds=[(None, None)] * n + [(None, RELAX_UNTANGLE)],
            constraints=[{"type": "ineq", "fun": margin, "jac": margin_jac}],
            method="SLSQP",
            options={"maxiter": 200},
        )
        volumes(res.x)

    def _untangle(self, x: NDArray[np.float64], free: NDArray[np.int64]) -> None:
        """Move ``free`` until every ``J = V / V_rest`` around them is positive (in place).

        Minimises ``sum V_rest max(0, t - J)^2`` over the tetrahedra around ``free`` by
        L-BFGS (``t`` :data:`RELAX_UNTANGLE`): the volumes alone, no distortion, so that a
        restart is untangled before the relaxation's energy, whose barrier is gentle
        while a tetrahedron is inverted, shapes it. Measured on the fine hand's index MCP
        split tetrahedron in a random full-limits pose: relaxed directly from a restart it
        stayed inverted in 30 of 34 variants; untangled first, it was mended from its own
        bone's motion in all 4 tried. The energy and gradient are one compiled call
        (:func:`contact.hand.relaxkernels.untangle_terms`; numpy took 0.3 ms a call, and a
        cold full-limits pose's restarts up to 1,700 calls).
        """
        from scipy.optimize import minimize

        cells = self._cells(free)
        patch = self._gather(cells)
        local = np.full(len(x), -1, dtype=np.int64)
        local[free] = np.arange(len(free))
        lt = local[patch["tets"]]

        def fun(z: NDArray[np.float64]) -> tuple[float, NDArray[np.float64]]:
            x[free] = z.reshape(-1, 3)
            return relaxkernels.untangle_terms(
                x, patch["tets"], lt, patch["dmat"], patch["vol"], RELAX_UNTANGLE, len(free)
            )

        opts = {"maxiter": 3000, "ftol": 1e-15, "gtol": 1e-12}
        res = minimize(fun, x[free].ravel(), jac=True, method="L-BFGS-B", options=opts)
        x[free] = res.x.reshape(-1, 3)

    def _minimise(self, x: NDArray[np.float64], free: NDArray[np.int64]) -> None:
        """Newton's method on the energy of the tetrahedra around ``free`` (in place).

        Each connected part of the free nodes (joined by a tetrahedron) is minimised on
        its own: the parts share no tetrahedron, so the energy is their sum, and a part
        that converges early (a finger's joint) does not ride along while a deeper one
        (the wrist) takes its Newton steps and line searches.
        """
        for part in self._parts(free):
            self._newton(x, part)

    def _parts(self, free: NDArray[np.int64]) -> list[NDArray[np.int64]]:
        """The connected parts of the nodes ``free`` (joined by a tetrahedron), sorted."""
        from scipy.sparse.csgraph import connected_components

        a = self._n2t[free]
        _, label = connected_components(a @ a.T, directed=False)
        order = np.argsort(label, kind="stable")
        split = np.flatnonzero(np.diff(label[order])) + 1
        return [np.sort(part) for part in np.split(free[order], split)]

    def _newton(self, x: NDArray[np.float64], free: NDArray[np.int64], patience: int = 0) -> None:
        """Newton's method on the tetrahedra around one connected part ``free``.

        Nothing to do when every tetrahedron of the part is already above the stop floor
        (a warm start from the previous frame often is): no step is taken. ``patience``
        (0: none): stop after that many steps without a better iterate while a
        tetrahedron is still inverted (see :data:`_MEND_PATIENCE`).
        """
        cells = self._cells(free)
        tets = np.take(self.tets, cells, axis=0)
        floor = self._floor[cells]
        vols, q = relaxkernels.volumes_quality(x, tets)  # then from each step's
        if (q > floor).all():
            return
        vol = np.take(self._vol, cells)
        dmat = np.take(self._dmat, cells, axis=0)
        ddt = np.take(self._ddt, cells, axis=0)
        local = np.full(len(x), -1, dtype=np.int64)
        local[free] = np.arange(len(free))
        lt = local[tets]
        dof = (3 * lt[:, :, None] + np.arange(3)).reshape(-1, 12)
        dof[np.repeat(lt < 0, 3, axis=1)] = -1
        n = 3 * len(free)
        # the sparsity pattern once (entries on a held node dropped)
        indptr, indices, diag, pair_slot, pair_diag = relaxkernels.block_pattern(lt, len(free))
        gslot = dof.ravel()
        eps = self.delta
        e_prev, n_prev = np.inf, len(cells)
        stalled = since = 0
        best, x_best = (int((q <= 0.0).sum()), -q.min()), x[free].copy()
        for _ in range(self.maxiter):
            # Escobar's regularisation follows the most inverted tetrahedron: a gentle
            # barrier on a tangled patch, a steep one (delta -> 0) once it is untangled
            jmin = float(np.min(vols / vol))
            delta = np.sqrt(eps * (eps - jmin)) if jmin < eps else eps * 0.1
            d2 = delta * delta
            e0, grad, data = relaxkernels.step_terms(
                x, tets, dmat, ddt, vol, d2, self.kappa, _EXACT_J,
                gslot, pair_slot, pair_diag, n, len(indices),
            )  # fmt: skip
            step = -relaxkernels.block_cg(indptr, indices, data, diag, grad, _CG_RTOL, _CG_MAXITER)
            decrease = float(grad @ step)
            self.stats["iterations"] += 1
            x0 = x[free].copy()
            t = 1.0
            while True:
                x[free] = x0 + t * step.reshape(-1, 3)
                e1 = relaxkernels.patch_energy(x, tets, dmat, vol, d2, self.kappa)
                if e1 <= e0 + 1e-4 * t * decrease or t < 1e-6:
                    break
                t *= 0.5
            vols, q = relaxkernels.volumes_quality(x, tets)
            n_inv = int((q <= 0.0).sum())
            if (n_inv, -q.min()) < best:
                best, x_best = (n_inv, -q.min()), x[free].copy()
                since = 0
            else:
                since += 1
            if _LOG.isEnabledFor(logging.DEBUG):
                _LOG.debug(
                    "newton: %d free, step %.3g, energy %.6g, %d inverted, %d below the "
                    "floor, min quality %.4f",
                    len(free),
                    t,
                    e1,
                    n_inv,
                    int((q <= floor).sum()),
                    q.min(),
                )
            if (q > floor).all():
                break
            # converged: nothing more to gain (a tetrahedron held down by the bones)
            if q.min() > 0.0 and -decrease < 1e-3 * e0 and e_prev - e1 < 1e-3 * e0:
                break
            # stalled: the energy no longer falls (a tetrahedron no position of the free
            # nodes can mend, or one the patch is too small for)
            slow = e0 - e1 < RELAX_STALL * e0 and n_inv >= n_prev
            stalled = stalled + 1 if slow else 0
            if stalled >= 3:
                self.stats["stalled"] += 1
                break
            e_prev, n_prev = e1, min(n_inv, n_prev)
            if patience and since >= patience and best[0] > 0:
                break  # creeping: no better iterate for ``patience`` steps, still inverted
        # the iterate with the fewest inverted tetrahedra (then the best worst quality):
        # a tangled patch's gentle barrier can let the count grow before it falls
        x[free] = x_best


@dataclass(frozen=True)
class Pose:
    """The hand in one pose.

    Attributes
    ----------
    angles : dict of str to float
        Every angle (degrees), omitted ones 0.
    points : ndarray, shape (N, 3)
        Posed flesh nodes.
    displacement : ndarray, shape (N, 3)
        ``points - rest``; exactly 0 at rest. Rows of bone nodes are their prescribed
        displacements (``Uk`` of the seed).
    transforms : dict of str to ndarray (4, 4)
        Rest-to-posed rigid transform of every bone.
    tets : ndarray, shape (M, 4)
        The flesh tetrahedra (for :meth:`mesh` and the quality).
    regions : ndarray, shape (M,)
    inverted : ndarray of int
        Tetrahedra with a non-positive volume (empty unless posed with ``check=False``).
    relaxed : int
        Free nodes the :class:`FleshRelaxer` moved off their JLD positions.
    correction : ndarray, shape (N, 3), optional
        ``points`` minus their JLD mapping: non-zero on the relaxed nodes alone (the
        next frame's warm start, see :meth:`HandPoser.pose`).
    """

    angles: dict[str, float]
    points: NDArray[np.float64]
    displacement: NDArray[np.float64]
    transforms: dict[str, NDArray[np.float64]]
    tets: NDArray[np.int64]
    regions: NDArray[np.int64]
    inverted: NDArray[np.int64]
    relaxed: int = 0
    correction: NDArray[np.float64] | None = None

    @cached_property
    def quality(self) -> NDArray[np.float64]:
        """Shape quality of every tetrahedron (see :func:`tet_quality`)."""
        return tet_quality(self.points, self.tets)

    @property
    def min_quality(self) -> float:
        """Worst tetrahedron quality of the pose."""
        return float(self.quality.min())

    def mesh(self) -> fem.Mesh:
        """The posed flesh as a validated :class:`fem.Mesh` (raises on inverted cells)."""
        return fem.Mesh(self.points, {"tetra": self.tets}, {"tetra": self.regions})


class HandPoser:
    """Poses one hand: JLD mapping of its flesh (and skin) localised once.

    Parameters
    ----------
    hand : Hand
        From :func:`contact.load_hand`.
    relax : bool
        Relax the flesh around the tetrahedra the JLD mapping degrades
        (:class:`FleshRelaxer`); False: the JLD mapping alone.

    Examples
    --------
    >>> poser = HandPoser(load_hand("coarse"))  # doctest: +SKIP
    >>> pose = poser.pose({"index_mcp": 30.0})  # doctest: +SKIP
    >>> skin = poser.skin_points({"index_mcp": 30.0})  # doctest: +SKIP
    """

    def __init__(self, hand: Hand, relax: bool = True) -> None:
        self.hand = hand
        self.flesh_map = JLDMap(hand.skeleton, hand.flesh.points, hand.bone_id)
        self._tets = np.ascontiguousarray(hand.flesh.cells["tetra"])
        self._regions = np.asarray(hand.flesh.regions["tetra"])
        self.relaxer = (
            FleshRelaxer(hand.flesh.points, self._tets, hand.bone_id >= 0, bone_id=hand.bone_id)
            if relax
            else None
        )

    @cached_property
    def skin_map(self) -> JLDMap:
        """JLD mapping of the skin surface's vertices (``hand.skin``)."""
        h = self.hand
        return JLDMap(
            h.skeleton,
            np.asarray(h.skin.points),
            reference=(h.flesh.points, h.bone_id),
        )

    def pose(
        self,
        angles: Mapping[str, float] | None = None,
        check: bool = True,
        start: Pose | None = None,
    ) -> Pose:
        """Pose the flesh for joint angles.

        Parameters
        ----------
        angles : mapping of str to float, optional
            Degrees by angle name; omitted angles stay at 0 (rest).
        check : bool
            Raise :class:`PoseError` if a tetrahedron inverts; otherwise record them.
        start : Pose, optional
            A nearby pose, typically the previous frame of a sequence (a warm start): its
            :attr:`Pose.correction` added to this pose's mapping is one more start of the
            relaxer's first pass, used on each patch the mapping degrades where its energy
            is lowest (:meth:`FleshRelaxer.relax_quality`). The mapping and the nodes it
            leaves in place do not depend on it; at rest the pose is still the identity.

        Returns
        -------
        Pose

        Raises
        ------
        RigError
            An unknown angle, or one outside its limits.
        PoseError
            With ``check``, naming the joint and the first inverted element.
        ValueError
            A ``start`` pose of another mesh.
        """
        sk = self.hand.skeleton
        full = {k: float(v) for k, v in sk.check_angles(angles).items()}
        rest = self.hand.flesh.points
        points = rest + self.flesh_map.displacement(full)
        tf = sk.forward_kinematics(full)
        moved = 0
        correction = None
        if self.relaxer is not None:
            warm = None
            if start is not None and start.correction is not None:
                if start.correction.shape != points.shape:
                    raise ValueError(
                        f"start: a pose of another mesh ({len(start.correction)} nodes; "
                        f"this hand's flesh has {len(points)})"
                    )
                warm = points + self._carried(start, tf)
            mapped = points
            points, moved, q = self.relaxer.relax_quality(points, warm)
            correction = points - mapped
        else:
            q = tet_quality(points, self._tets)
        disp = points - rest
        inverted = np.flatnonzero(q <= 0.0)
        if check and len(inverted):
            raise self.inversion_error(full, inverted)
        return Pose(full, points, disp, tf, self._tets, self._regions, inverted, moved, correction)

    def _carried(
        self, start: Pose, transforms: Mapping[str, NDArray[np.float64]]
    ) -> NDArray[np.float64]:
        """``start``'s correction carried to a pose of bone ``transforms``: the warm start.

        A correction is a local reshaping of the flesh around a joint: it turns with the
        node's segment (its JLD assignment). Each node's correction is turned by its
        segment's rotation from ``start`` to this pose. Measured on keyframed sequences
        of the fine hand at its full limits (12 sequences, 588 frames, 24 a second),
        against the correction taken as it is: a frame 0.080 against 0.091 s on average,
        0.17 against 0.22 s at the 95th percentile, 15 against 34 frames above 0.2 s,
        10,529 against 11,778 Newton steps in all, the same qualities. (Turned by the
        mapping's own local rotation between the two frames instead, the start was much
        worse: 0.17 s a frame. The mapping is distorted exactly where there is a
        correction.)
        """
        names = self.flesh_map.topology.names
        turn = np.stack([transforms[b][:3, :3] @ start.transforms[b][:3, :3].T for b in names])
        return np.einsum("nij,nj->ni", turn[self.flesh_map.segment], start.correction)

    def skin_points(self, angles: Mapping[str, float] | None = None) -> NDArray[np.float64]:
        """Posed vertices of the skin surface ``hand.skin``, shape (n_skin, 3)."""
        return self.skin_map.map(angles)

    def culprit(self, angles: Mapping[str, float], element: int) -> str:
        """The joint blamed for an inverted element.

        Each bent joint in turn is put back to rest (flexion and pivot) and the element's
        four nodes re-mapped; the joint whose return gives the element the largest volume
        is the culprit (ties go to the most bent).
        """
        h = self.hand
        nodes = self._tets[element]
        m = JLDMap(h.skeleton, h.flesh.points[nodes], h.bone_id[nodes], (h.flesh.points, h.bone_id))
        bent = {
            j: abs(angles.get(j, 0.0)) + abs(angles.get(j + PIVOT_SUFFIX, 0.0))
            for j in h.skeleton.joint_names
        }
        best, best_key = h.skeleton.joint_names[0], (-np.inf, -np.inf)
        for j, b in bent.items():
            if b == 0.0:
                continue
            trial = dict(angles)
            trial[j] = 0.0
            if j + PIVOT_SUFFIX in trial:
                trial[j + PIVOT_SUFFIX] = 0.0
            v = tet_volumes(m.map(trial), np.arange(4)[None])[0]
            if (v, b) > best_key:
                best, best_key = j, (v, b)
        return best

    def inversion_error(self, angles: Mapping[str, float], inverted: NDArray) -> PoseError:
        """The :class:`PoseError` for a pose that inverts ``inverted`` elements."""
        first = int(inverted[0])
        joint = self.culprit(angles, first)
        nodes = self._tets[first]
        fixed = self.hand.bone_id[nodes]
        names = self.hand.skeleton.bone_names
        bones = sorted({names[b] for b in fixed if b >= 0})
        how = (
            f"all four nodes are fixed to bones ({', '.join(bones)}): the mesh cannot take "
            "this rotation"
            if (fixed >= 0).all()
            else f"nodes {nodes.tolist()}"
        )
        bent = angles.get(joint, 0.0)
        return PoseError(
            f"pose inverts {len(inverted)} tetrahedra; the first, element {first} "
            f"({how}), at joint {joint} (flexion {bent:g} deg)",
            joint,
            first,
            tuple(int(i) for i in inverted),
        )


def pose_hand(hand: Hand, angles: Mapping[str, float] | None = None, check: bool = True) -> Pose:
    """Pose a hand for joint angles (degrees); see :meth:`HandPoser.pose`.

    The hand's :class:`HandPoser` is built on the first call and kept with the hand
    (:attr:`Hand.derived`), so posing frame after frame costs only the mapping.
    """
    poser = hand.derived.get("poser")
    if poser is None:
        poser = hand.derived["poser"] = HandPoser(hand)
    return poser.pose(angles, check=check)
