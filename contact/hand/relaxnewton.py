"""Newton's method on a patch of the flesh relaxer's energy (:mod:`contact.hand.relax`).

A projected Newton method: each tetrahedron's Hessian made positive semi-definite
(:func:`contact.hand.relaxkernels.step_terms`), assembled on the patch's fixed block
pattern, the step solved inexactly by block-preconditioned conjugate gradients
(:mod:`contact.hand.blockcg`), then a backtracking line search on the energy. Escobar's
regularisation of the determinant follows the most inverted tetrahedron of the patch. The
run keeps its iterate with the fewest inverted tetrahedra, then the best worst quality.
"""

from __future__ import annotations

import logging

import numpy as np
from numpy.typing import NDArray

from . import blockcg, relaxkernels
from .relaxmesh import RelaxMesh

__all__ = ["RELAX_STALL", "newton"]

#: A run stops once three Newton steps in a row lower the patch's energy by less than this
#: fraction of it and leave as many tetrahedra inverted (stalled: typically a tetrahedron
#: no position of its free nodes mends).
RELAX_STALL = 1e-4
#: Relative residual of the conjugate gradients of a Newton step (an inexact Newton step):
#: as many Newton steps as a tighter tolerance, less time; a looser one takes more steps.
_CG_RTOL = 1e-2
#: ... or at most this many iterations.
_CG_MAXITER = 1000
_LOG = logging.getLogger(__name__)


def newton(
    mesh: RelaxMesh,
    x: NDArray[np.float64],
    free: NDArray[np.int64],
    floor: NDArray[np.float64],
    kappa: float,
    delta: float,
    maxiter: int,
    stats: dict[str, int],
    patience: int = 0,
) -> None:
    """Newton's method on the tetrahedra around one connected part ``free`` (in place).

    Nothing to do when every tetrahedron of the part is already above its stop floor (a
    warm start from the previous frame often is): no step is taken. The run ends when
    every tetrahedron is above its floor, when it has converged (all positive, the
    decrease below a thousandth of the energy), when it stalls (:data:`RELAX_STALL`), or
    after ``maxiter`` steps.

    Parameters
    ----------
    mesh : RelaxMesh
    x : ndarray, shape (N, 3)
        Positions; the free nodes ``free`` move.
    free : ndarray of int
        One connected part of free nodes (:meth:`RelaxMesh.parts`).
    floor : ndarray, shape (M,)
        Every tetrahedron's stop floor of quality.
    kappa, delta : float
        The volume weight and Escobar's regularisation (its least value).
    maxiter : int
        Newton steps at most.
    stats : dict of str to int
        ``iterations`` and ``stalled`` are counted here.
    patience : int
        0: none; else stop after that many steps without a better iterate while a
        tetrahedron is still inverted (a creeping run).
    """
    cells = mesh.cells(free)
    tets = np.take(mesh.tets, cells, axis=0)
    floor = floor[cells]
    vols, q = relaxkernels.volumes_quality(x, tets)  # then from each step's
    if (q > floor).all():
        return
    vol = np.take(mesh.vol, cells)
    dmat = np.take(mesh.dmat, cells, axis=0)
    ddt = np.take(mesh.ddt, cells, axis=0)
    local = np.full(len(x), -1, dtype=np.int64)
    local[free] = np.arange(len(free))
    lt = local[tets]
    dof = (3 * lt[:, :, None] + np.arange(3)).reshape(-1, 12)
    dof[np.repeat(lt < 0, 3, axis=1)] = -1
    n = 3 * len(free)
    # the sparsity pattern once (entries on a held node dropped)
    indptr, indices, diag, pair_slot, pair_diag = blockcg.block_pattern(lt, len(free))
    gslot = dof.ravel()
    eps = delta
    e_prev, n_prev = np.inf, len(cells)
    stalled = since = 0
    best, x_best = (int((q <= 0.0).sum()), -q.min()), x[free].copy()
    for _ in range(maxiter):
        # Escobar's regularisation follows the most inverted tetrahedron: a gentle
        # barrier on a tangled patch, a steep one (delta -> 0) once it is untangled
        jmin = float(np.min(vols / vol))
        delta = np.sqrt(eps * (eps - jmin)) if jmin < eps else eps * 0.1
        d2 = delta * delta
        e0, grad, data = relaxkernels.step_terms(
            x, tets, dmat, ddt, vol, d2, kappa, relaxkernels.EXACT_J,
            gslot, pair_slot, pair_diag, n, len(indices),
        )  # fmt: skip
        step = -blockcg.block_cg(indptr, indices, data, diag, grad, _CG_RTOL, _CG_MAXITER)
        decrease = float(grad @ step)
        stats["iterations"] += 1
        x0 = x[free].copy()
        t = 1.0
        while True:
            x[free] = x0 + t * step.reshape(-1, 3)
            e1 = relaxkernels.patch_energy(x, tets, dmat, vol, d2, kappa)
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
            stats["stalled"] += 1
            break
        e_prev, n_prev = e1, min(n_inv, n_prev)
        if patience and since >= patience and best[0] > 0:
            break  # creeping: no better iterate for ``patience`` steps, still inverted
    # the iterate with the fewest inverted tetrahedra (then the best worst quality):
    # a tangled patch's gentle barrier can let the count grow before it falls
    x[free] = x_best
