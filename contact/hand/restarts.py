"""Restarts of the folds the relaxer's Newton passes leave inverted, from a bone's rigid motion.

A tetrahedron the passes of :class:`contact.hand.relax.FleshRelaxer` leave inverted sits in a
fold that Newton's method on the regularised energy cannot leave (typically a split
joint-gap tetrahedron folded over its bone node: the untangling energy alone, however wide
its patch, keeps it inverted, yet its rest shape carried rigidly by that bone is positive).
Each cluster of inverted tetrahedra restarts the free nodes around it from a nearby bone's
rigid motion (:func:`rigid_motion`), untangles them by a penalty on the volumes
(:func:`untangle`) or, failing that, by maximising the least volume (:func:`maxmin`), and
relaxes them again (:class:`Restarts`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize
from scipy.sparse.csgraph import connected_components

from . import relaxkernels
from .quality import tet_volumes
from .relaxmesh import RelaxMesh, cofactor

__all__ = [
    "RELAX_RESTARTS",
    "RELAX_UNTANGLE",
    "Restarts",
    "maxmin",
    "rigid_motion",
    "untangle",
]

#: Rounds of restarts from a bone's rigid motion for the tetrahedra the passes leave
#: inverted (:meth:`Restarts.run`).
RELAX_RESTARTS = 3
#: A restart first untangles its patch until every ``J = V / V_rest`` reaches this.
RELAX_UNTANGLE = 0.05
#: The most unknowns (three a free node, and the least ``J``) of the dense max-min
#: untangling (:func:`maxmin`): its quadratic subproblems are dense, their cost grows as
#: the cube; a wider tangle, such as the wrist's, is left to the passes.
_MAXMIN_VARIABLES = 600


def rigid_motion(
    mesh: RelaxMesh, x: NDArray[np.float64], bone: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The rest-to-posed rigid motion of a bone, from its nodes: rotation, translation.

    The least-squares fit (Kabsch) of the bone's rest nodes to their posed places ``x``,
    exact for nodes that move rigidly (to round-off).
    """
    nodes = np.flatnonzero(mesh.bone_id == bone)
    p, q = mesh.rest[nodes], x[nodes]
    pc, qc = p.mean(axis=0), q.mean(axis=0)
    u, _, vt = np.linalg.svd((p - pc).T @ (q - qc))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    rot = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return rot, qc - pc @ rot.T


def untangle(mesh: RelaxMesh, x: NDArray[np.float64], free: NDArray[np.int64]) -> None:
    """Move ``free`` until every ``J = V / V_rest`` around them is positive (in place).

    Minimises ``sum V_rest max(0, t - J)^2`` over the tetrahedra around ``free`` by L-BFGS
    (``t`` :data:`RELAX_UNTANGLE`): the volumes alone, no distortion, so that a restart is
    untangled before the relaxation's energy, whose barrier is gentle while a tetrahedron
    is inverted, shapes it. The energy and gradient are one compiled call
    (:func:`contact.hand.relaxkernels.untangle_terms`).
    """
    cells = mesh.cells(free)
    patch = mesh.gather(cells)
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


def maxmin(mesh: RelaxMesh, x: NDArray[np.float64], free: NDArray[np.int64]) -> None:
    """Move ``free`` to maximise the least ``J = V / V_rest`` around them (in place).

    ``max t`` subject to ``J_i >= t`` for every tetrahedron ``i`` around ``free`` and
    ``t <=`` :data:`RELAX_UNTANGLE`, by sequential quadratic programming (SLSQP, dense: a
    small patch only, :data:`_MAXMIN_VARIABLES`), in the displacements scaled by the
    patch's mean edge length so that the problem is of order one.
    """
    cells = mesh.cells(free)
    tets, dmat = mesh.tets[cells], mesh.dmat[cells]
    dmt = np.transpose(dmat, (0, 2, 1))
    local = np.full(len(x), -1, dtype=np.int64)
    local[free] = np.arange(len(free))
    lt = local[tets]
    at = lt >= 0
    rows = np.broadcast_to(np.arange(len(cells))[:, None, None], (len(cells), 4, 3))[at]
    cols = (3 * lt[:, :, None] + np.arange(3))[at]
    h = float(np.cbrt(mesh.vol[cells].mean()))
    x0 = x[free].copy()
    n = 3 * len(free)

    def volumes(z: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
        x[free] = x0 + h * z[:n].reshape(-1, 3)
        f = np.transpose(x[tets], (0, 2, 1)) @ dmat
        cof = cofactor(f)
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


class Restarts:
    """Restarts of the inverted tetrahedra of one relaxation (see the module docstring).

    Parameters
    ----------
    mesh : RelaxMesh
        The mesh, with its ``bone_id``.
    rings : int
        Rings of tetrahedra around a cluster whose free nodes a restart moves (one and two
        more for the untangled patch, :meth:`run`).
    minimise : callable
        ``minimise(x, free)``: the relaxer's Newton method on the tetrahedra around
        ``free`` (in place).
    stats : dict of str to int
        The relaxer's counters: ``restarts`` and ``feasible`` (the max-min fallback's) are
        counted here.
    """

    def __init__(
        self,
        mesh: RelaxMesh,
        rings: int,
        minimise: Callable[[NDArray[np.float64], NDArray[np.int64]], None],
        stats: dict[str, int],
    ) -> None:
        self.mesh = mesh
        self.rings = rings
        self.minimise = minimise
        self.stats = stats

    def run(self, x: NDArray[np.float64], moved: NDArray[np.bool_], q: NDArray[np.float64]) -> None:
        """Restart the neighbourhood of every tetrahedron left inverted (in place).

        Each cluster of inverted tetrahedra (joined by a node) restarts the free nodes of
        the tetrahedra around it from a bone's rigid motion, where their rest shape is
        fair: the bone of the cluster's fixed nodes, or else the one with most fixed nodes
        within two rings of it, then the next; one ring of tetrahedra around the cluster,
        then none, then two. The free nodes within ``rings + 1`` rings of the cluster (then
        ``rings + 2``) are untangled from there (:func:`untangle`), then relaxed; a restart
        is kept when fewer tetrahedra of that patch are inverted, undone otherwise
        (Newton's path from a restart is sensitive to its start: the variants are tried in
        turn). A cluster none of them mends falls back on maximising the least ``J`` of a
        smaller patch (:meth:`_feasible`). Up to :data:`RELAX_RESTARTS` rounds. ``moved``
        marks the free nodes moved; ``q``: the qualities at ``x``, kept up to date.
        """
        mesh = self.mesh
        for _ in range(RELAX_RESTARTS):
            inv = np.flatnonzero(q <= 0.0)
            if len(inv) == 0:
                return
            # clusters: inverted tetrahedra joined by a node
            a = mesh.n2t[:, inv]
            _, label = connected_components(a.T @ a, directed=False)
            mended = False
            for c in range(label.max() + 1):
                cluster = inv[label == c]
                mended |= self._cluster(x, moved, cluster)
                # every patch a restart moves lies within rings + 2 rings of the cluster
                mesh.requality(q, x, mesh.ring(np.unique(mesh.tets[cluster]), self.rings + 2))
            if not mended:
                return

    def _cluster(
        self, x: NDArray[np.float64], moved: NDArray[np.bool_], cluster: NDArray[np.int64]
    ) -> bool:
        """Restart one cluster of inverted tetrahedra (see :meth:`run`): mended or not."""
        mesh = self.mesh
        core = np.unique(mesh.tets[cluster])
        # candidate bones: the cluster's own, then the others within two rings of it
        own = mesh.bone_id[core]
        near = mesh.bone_id[mesh.ring(core, 2)]
        own, near = own[own >= 0], near[near >= 0]
        if len(near) == 0:
            return False
        count = np.bincount(near) + len(near) * np.bincount(own, minlength=near.max() + 1)
        candidates = np.argsort(-count, kind="stable")[: min(2, int((count > 0).sum()))]
        for patch in (self.rings + 1, self.rings + 2):
            free = mesh.ring(core, patch)
            free = free[~mesh.fixed[free]]
            if self._variants(x, moved, core, free, candidates, (1, 0, 2), untangle):
                return True
        return self._feasible(x, moved, core, candidates)

    def _variants(
        self,
        x: NDArray[np.float64],
        moved: NDArray[np.bool_],
        core: NDArray[np.int64],
        free: NDArray[np.int64],
        candidates: NDArray[np.int64],
        reaches: tuple[int, ...],
        untangler: Callable[[RelaxMesh, NDArray[np.float64], NDArray[np.int64]], object],
    ) -> bool:
        """Restart a fold from the candidate bones' rigid motions; keep the first that helps.

        The nodes within each of ``reaches`` rings of ``core`` are carried by each
        candidate bone, the ``free`` patch untangled (``untangler``) and relaxed; the
        first that leaves fewer of the patch's tetrahedra inverted is kept (True),
        otherwise the patch is put back.
        """
        mesh = self.mesh
        cells = mesh.cells(free)
        n_before = int((tet_volumes(x, mesh.tets[cells]) <= 0.0).sum())
        before = x[free].copy()
        for reach in reaches:
            inner = mesh.ring(core, reach)
            inner = inner[~mesh.fixed[inner]]
            for b in candidates.tolist():
                rot, shift = rigid_motion(mesh, x, b)
                x[inner] = mesh.rest[inner] @ rot.T + shift
                self.stats["restarts"] += 1
                untangler(mesh, x, free)
                self.minimise(x, free)
                if int((tet_volumes(x, mesh.tets[cells]) <= 0.0).sum()) < n_before:
                    moved[free] = True
                    return True
                x[free] = before
        return False

    def _feasible(
        self,
        x: NDArray[np.float64],
        moved: NDArray[np.bool_],
        core: NDArray[np.int64],
        candidates: NDArray[np.int64],
    ) -> bool:
        """The fallback of a restart: untangle by maximising the patch's least ``J``.

        The penalty of :func:`untangle` sums the shortfalls of every tetrahedron: where the
        free nodes of a fold cannot mend one tetrahedron without denting its neighbours,
        its minimum keeps that one just inverted. The least ``J`` itself, maximised with the
        others as constraints (:func:`maxmin`), leaves that trade: from the cluster's own
        free nodes carried rigidly by a candidate bone, it reaches ``J`` =
        :data:`RELAX_UNTANGLE` on every tetrahedron of the patch (``rings`` rings around
        the cluster ``core``'s nodes). The cluster's own nodes are restarted, then one ring
        and two rings around it; the patch is then relaxed as any other, and kept when
        fewer of its tetrahedra are inverted.
        """
        mesh = self.mesh
        free = mesh.ring(core, self.rings)
        free = free[~mesh.fixed[free]]
        if len(free) == 0 or 3 * len(free) > _MAXMIN_VARIABLES:
            return False

        def counted(mesh: RelaxMesh, x: NDArray[np.float64], free: NDArray[np.int64]) -> None:
            self.stats["feasible"] += 1
            maxmin(mesh, x, free)

        return self._variants(x, moved, core, free, candidates, (0, 1, 2), counted)
