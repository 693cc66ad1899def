"""The relaxer's energy in numpy: the reference of its compiled Newton-step kernel.

The energy density of :class:`contact.hand.relax.FleshRelaxer`, ``|F|^2 h^(-2/3) / 3 +
kappa (h + 1/h) / 2`` with Escobar's regularised determinant ``h`` of ``J = det F``, its
gradient, and its Hessian made positive semi-definite per tetrahedron: on a fair one the
convex part, on a degenerate or inverted one the exact Hessian in ``F`` projected on its
positive eigenvalues through the analytic eigensystem of Smith, de Goes and Kim (2019).
:func:`terms` is what :func:`contact.hand.relaxkernels.step_terms` computes, vectorised
over the tetrahedra; the tests hold the kernel equal to it to round-off. The relaxer itself
does not use this module.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from fem.eigen3 import eigh3, rotation_svd3

from .relaxkernels import EXACT_J
from .relaxmesh import cofactor

__all__ = [
    "density",
    "eigen_gradients",
    "eigenvectors",
    "isotropic_eigen",
    "regularised",
    "terms",
]

#: For the 3 x 3 scaling block of :func:`isotropic_eigen`: the index ``k`` third to
#: ``(p, q)`` and the off-diagonal mask (``d^2 det S / ds_p ds_q = s_k``).
_THIRD = np.array([[0, 2, 1], [2, 1, 0], [1, 0, 2]])
_OFF = 1.0 - np.eye(3)




def isotropic_eigen(
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
        pairs (1, 2), (0, 2), (0, 1) (:func:`eigenvectors` gives the vectors in that
        order, :func:`eigen_gradients` their gradients in the nodes).
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


def eigenvectors(
    u: NDArray[np.float64], vt: NDArray[np.float64], e: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The eigenvectors (m, 9, 9 columns) ``vec(U T V^T)`` of :func:`isotropic_eigen`."""

    def outer(p: list[int], q: list[int]) -> NDArray[np.float64]:  # (m, 9, pairs)
        return (u[:, :, None, p] * vt[:, q, None, :].transpose(0, 2, 3, 1)).reshape(
            len(u), 9, len(p)
        )

    return _combine(outer, e)


def eigen_gradients(
    u: NDArray[np.float64],
    vt: NDArray[np.float64],
    e: NDArray[np.float64],
    dmat: NDArray[np.float64],
) -> NDArray[np.float64]:
    """``d (F : Q_k) / d x`` (m, 12, 9) of the eigenvectors ``Q_k`` of :func:`isotropic_eigen`.

    ``F = X^T D`` (``D = dmat``, (m, 4, 3)), so ``d (F : U e_p e_q^T V^T) / d x_ni`` is
    ``U_ip (D V)_nq``: outer products of ``U``'s columns and ``D V``'s, 108 numbers a
    tetrahedron, without forming the eigenvectors themselves.
    """
    dv = dmat @ np.transpose(vt, (0, 2, 1))  # (m, 4, 3)

    def outer(p: list[int], q: list[int]) -> NDArray[np.float64]:  # (m, 12, pairs)
        return (dv[:, :, None, q] * u[:, None, :, p]).reshape(len(u), 12, len(p))

    return _combine(outer, e)


def regularised(j: NDArray[np.float64], d2: float) -> tuple[NDArray, NDArray]:
    """``sqrt(j^2 + 4 d2)`` and Escobar's ``h = (j + sqrt(j^2 + 4 d2)) / 2`` of ``j``.

    Without cancellation where ``j << 0`` (inverted): ``(j + r)(r - j) = 4 d2``.
    """
    r = np.sqrt(j * j + 4.0 * d2)
    h = 0.5 * (j + r)
    neg = j < 0.0
    h[neg] = 2.0 * d2 / (r[neg] - j[neg])
    return r, h


def density(
    nf: NDArray[np.float64], h23: NDArray[np.float64], h: NDArray[np.float64], kappa: float
) -> NDArray[np.float64]:
    """The energy density: ``|F|^2 h^(-2/3) / 3 + kappa (h + 1/h) / 2`` (``h23 = h^(-2/3)``)."""
    return nf * h23 / 3.0 + 0.5 * kappa * (h + 1.0 / h)


def terms(
    x: NDArray[np.float64],
    patch: dict[str, NDArray],
    delta: float,
    kappa: float,
    exact_j: float = EXACT_J,
) -> tuple[NDArray[np.float64], ...]:
    """Energy per tetrahedron, gradient per node (m, 4, 3) and Hessian of a patch.

    ``patch``: the tetrahedra's data (:meth:`contact.hand.relaxmesh.RelaxMesh.gather`);
    ``delta`` and ``kappa`` the regularisation and the volume weight; a tetrahedron with
    ``J <= exact_j`` takes its exact projected Hessian. The Hessian in two parts, their
    sum: ``hk`` (m, 12, 12) and ``lap`` (m, 4, 4), whose ``lap x I3`` (the distortion's
    ``a |dF|^2`` on a fair tetrahedron, the same for the three components) is assembled on
    node pairs (:func:`contact.hand.blockcg.block_pattern`), a third of the work of adding
    it into ``hk``'s diagonal blocks.

    Returns
    -------
    e : ndarray, shape (m,)
    grad : ndarray, shape (m, 4, 3)
    hk : ndarray, shape (m, 12, 12)
    lap : ndarray, shape (m, 4, 4)
    """
    tets, vol, dmat = patch["tets"], patch["vol"], patch["dmat"]
    cells = patch["cells"]
    f = np.transpose(np.take(x, tets, axis=0), (0, 2, 1)) @ dmat
    cof = cofactor(f)
    j = np.einsum("ij,ij->i", f[:, :, 0], cof[:, :, 0])
    d2 = delta * delta
    r, h = regularised(j, d2)
    nf = np.einsum("mij,mij->m", f, f)
    k = kappa
    h23 = h ** (-2.0 / 3.0)
    e = vol * density(nf, h23, h, k)
    h1 = h / r  # dh/dJ
    wj = -(2.0 / 9.0) * nf * h23 / h + 0.5 * k * (1.0 - 1.0 / (h * h))  # dW/dh
    c = wj * h1  # dW/dJ
    pk = (2.0 / 3.0) * h23[:, None, None] * f + c[:, None, None] * cof  # dW/dF
    dmt = np.transpose(dmat, (0, 2, 1))
    grad = vol[:, None, None] * np.transpose(pk @ dmt, (0, 2, 1))
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
    bad = j <= exact_j
    lap = vol * a
    lap[bad] = 0.0
    lap = patch["ddt"] * lap[:, None, None]
    if bad.any():
        cb = -(2.0 / 9.0) * h23[bad] / h[bad] * h1[bad]  # d^2 W / d(nf) dJ
        u, vt, ev, w = isotropic_eigen(f[bad], a[bad], cb, cj[bad], c[bad])
        w = np.maximum(w, 1e-8 * a[bad, None]) * vol[bad, None]
        gq = eigen_gradients(u, vt, ev, dmat[bad])
        hk[bad] = (gq * w[:, None, :]) @ np.transpose(gq, (0, 2, 1))
    return e, grad, hk, lap
