"""The flesh relaxer: the bounded correction after the JLD mapping of a pose (step 1).

The JLD mapping alone folds the flesh at deep flexions (the palmar flesh of a joint is
squeezed between the two bones, the skin of a joint's crease turns over). The
:class:`FleshRelaxer` takes the free nodes around every tetrahedron the mapping degraded
(quality below :data:`RELAX_QUALITY` and below half its rest quality, the rings of
tetrahedra around them) and moves them, the bones and every other node held, to the minimum
of an untangling distortion energy measured from the rest shape. Where the mapping keeps
every tetrahedron fair, nothing moves (the rest pose is exact).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import relaxkernels
from .quality import tet_quality
from .relaxmesh import RelaxMesh
from .relaxnewton import newton
from .restarts import Restarts

__all__ = ["RELAX_QUALITY", "RELAX_STOP", "FleshRelaxer"]

#: A tetrahedron whose quality falls below this (and below half its rest quality) is
#: relaxed by :class:`FleshRelaxer`.
RELAX_QUALITY = 0.05
#: The relaxation stops once every tetrahedron it moves is above this fraction of that
#: threshold (a fifth: quality 0.01 at least).
RELAX_STOP = 0.2
#: A warm start (:meth:`FleshRelaxer.relax_quality`) whose Newton run leaves a tetrahedron
#: of its part below this fraction of the stop floor is followed by the next start, the
#: better result kept: without it the warm frames' worst quality drifts from frame to
#: frame; at the floor itself, the retries cost more steps for no better quality.
_WARM_RETRY = 0.5
#: A warm start's local mend (:meth:`FleshRelaxer._mend_locally`) that leaves a tetrahedron
#: inverted stops after this many Newton steps without a better iterate (fewer inverted,
#: then a better worst quality), and its fresh start follows: a creeping mend of a wide
#: patch is slower than the fresh start over a small one.
_MEND_PATIENCE = 8


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
    method (:func:`contact.hand.relaxnewton.newton`): each tetrahedron's Hessian made
    positive semi-definite (on a fair tetrahedron, ``J > 1/4``, the convex part of the
    energy; on a degenerate or inverted one, the exact Hessian in ``F`` projected on its
    positive eigenvalues), the step solved by block-preconditioned conjugate gradients,
    then a backtracking line search. Escobar's ``delta`` follows the most inverted
    tetrahedron of the patch, ``sqrt(eps (eps - J_min))`` with ``eps`` the ``delta``
    given: a gentle barrier on a tangled patch, a steep one (``eps / 10``) once every
    ``J`` exceeds ``eps``. A patch still inverted at the minimum is widened by a ring
    around its inverted tetrahedra (``rounds``), as long as the wider patch mends more
    (the fair ones left below the floor are the final relaxation's); a pass that leaves
    more inverted than before is undone. Each connected part of a patch is minimised on
    its own; in the first pass, from the lower-energy of two starts, the mapping and the
    harmonic fill of its folds (:meth:`_first_pass`). With ``bone_id``, a tetrahedron
    still inverted after the passes (a fold Newton's method cannot leave) restarts its
    neighbourhood from a nearby bone's rigid motion (:mod:`contact.hand.restarts`); last,
    the positive tetrahedra left below the stop floor are relaxed once more on their own.

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
        The same in the first pass (one ring more a pass). One ring is enough from the
        first pass's two starts (as few inverted poses, as good a worst quality as two)
        and much cheaper; see ``benchmarks/results/posing.md``.
    rounds : int
        At most this many passes (each on the tetrahedra still inverted, one ring more).
    maxiter : int
        Newton iterations per pass.
    bone_id : array_like of int, shape (N,), optional
        The bone each fixed node belongs to (-1 free). With it, a tetrahedron still
        inverted after the passes restarts its neighbourhood from a bone's rigid motion
        (see :meth:`relax_quality`).

    Attributes
    ----------
    mesh : RelaxMesh
        The rest shape and its patches.
    stats : dict of str to int
        Counters of the last :meth:`relax_quality`.
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
        self.mesh = RelaxMesh(points, tets, fixed, bone_id)
        # the stop floor of every tetrahedron (RELAX_STOP of its degraded threshold)
        self._floor = RELAX_STOP * np.minimum(RELAX_QUALITY, 0.5 * self.mesh.rest_quality)
        self.kappa, self.delta = float(kappa), float(delta)
        self.rings, self.rounds, self.maxiter = int(rings), int(rounds), int(maxiter)
        self.pass_rings = int(pass_rings)
        self.stats: dict[str, int] = {}

    @property
    def rest(self) -> NDArray[np.float64]:
        """Rest positions, shape (N, 3)."""
        return self.mesh.rest

    @property
    def tets(self) -> NDArray[np.int64]:
        """The tetrahedra, shape (M, 4)."""
        return self.mesh.tets

    @property
    def fixed(self) -> NDArray[np.bool_]:
        """Nodes that never move, shape (N,)."""
        return self.mesh.fixed

    @property
    def bone_id(self) -> NDArray[np.int64] | None:
        """The bone of each fixed node (-1 free), or None."""
        return self.mesh.bone_id

    @property
    def rest_quality(self) -> NDArray[np.float64]:
        """Shape quality of every tetrahedron at rest."""
        return self.mesh.rest_quality

    def degraded(
        self, x: NDArray[np.float64], quality: NDArray[np.float64] | None = None
    ) -> NDArray[np.int64]:
        """Tetrahedra below :data:`RELAX_QUALITY` and below half their rest quality.

        ``quality``: every tetrahedron's quality at ``x``, if known (else computed).
        """
        q = tet_quality(x, self.mesh.tets) if quality is None else quality
        return np.flatnonzero((q < RELAX_QUALITY) & (q < 0.5 * self.rest_quality))

    def _energy(self, x: NDArray[np.float64], patch: dict[str, NDArray], delta: float) -> float:
        """The energy of a patch's tetrahedra alone; ``patch`` from :meth:`RelaxMesh.gather`."""
        return relaxkernels.patch_energy(
            x, patch["tets"], patch["dmat"], patch["vol"], delta * delta, self.kappa
        )

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
        ``rounds``; a later pass over every tetrahedron still degraded costs far more on
        the worst frames and mends nothing the restarts do not). Then, with ``bone_id``,
        restarts of the clusters left inverted from a bone's rigid motion
        (:class:`contact.hand.restarts.Restarts`); then one relaxation around the positive
        tetrahedra left below the stop floor (:meth:`_polish`). ``stats`` counts the
        Newton iterations, passes, stalls, restarts (of which ``feasible``: the max-min
        fallback's), the tetrahedra polished and the warm starts mended locally
        (:meth:`_mend_locally`).

        ``warm``, shape (N, 3), optional: a third start for the first pass (next to the
        mapping and its harmonic fill), typically the mapping plus the previous frame's
        correction (a warm start, :meth:`contact.hand.posing.HandPoser.pose`). Only its
        free nodes in the patch around the tetrahedra ``x`` degrades are used, and only
        where its energy is the lowest: a warm start never moves a node the mapping alone
        leaves in place.

        Returns
        -------
        points : ndarray, shape (N, 3)
            ``x`` itself (not copied) when no tetrahedron is degraded.
        moved : int
            Free nodes moved.
        quality : ndarray, shape (M,)
            :func:`~contact.hand.quality.tet_quality` of every tetrahedron at ``points`` (its
            sign is the volume's: a caller needs no other pass over the mesh to find inverted
            ones).
        """
        x = np.asarray(x, dtype=np.float64)
        q = tet_quality(x, self.mesh.tets)
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
            nodes = self.mesh.ring(np.unique(self.mesh.tets[bad]), self.pass_rings + k)
            free = nodes[~self.mesh.fixed[nodes]]
            if len(free) == 0:
                break
            moved[free] = True
            self.stats["passes"] += 1
            before = x[free].copy()
            if k == 0:
                left = self._first_pass(x, free, bad, q, warm)
            else:
                self._minimise(x, free)
                self.mesh.requality(q, x, free)
                left = int((q <= 0.0).sum())
            # a wider pass is for what is left inverted (the tetrahedra left fair but below
            # the floor are the polish's)
            bad = np.flatnonzero(q <= 0.0)
            if left > inverted:  # worse than before the pass: undo it
                x[free] = before
                self.mesh.requality(q, x, free)
                break
            # done, or a wider patch did not help: what is left is reported by the caller
            if left == 0 or (k > 0 and left == inverted):
                break
            inverted = left
        if self.bone_id is not None:
            Restarts(self.mesh, self.rings, self._minimise, self.stats).run(x, moved, q)
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

        The mapping's positions, or the harmonic fill (:meth:`RelaxMesh.fill`) of the free
        nodes of the degraded tetrahedra ``bad`` and one ring around them, where the
        mapping folds the flesh (from the fill, a deep fold takes far fewer Newton steps).
        Each connected part of the patch ``free`` (see :meth:`_minimise`) starts from the
        one of lower energy; should Newton's method leave a tetrahedron of the part
        inverted, it is run again from the other start and the better result kept (fewer
        inverted, then the better worst quality). ``warm``: a third start (see
        :meth:`relax_quality`), competing on energy with the two others: where it is
        the lowest, it is mended around its degraded tetrahedra alone
        (:meth:`_mend_locally`). Where those reach across the whole part, Newton's
        method runs on the part from the starts in order of energy, and a run from the
        warm start that leaves a tetrahedron below :data:`_WARM_RETRY` of the floor is
        followed by the next start. (The fill is made even where the warm start wins:
        mending the warm start wherever it is below the mapping's energy carries stale
        corrections from frame to frame.) ``q``: the qualities at ``x``, kept up to date.
        Returns the tetrahedra left inverted.
        """
        start = x[free].copy()
        core = self.mesh.ring(np.unique(self.mesh.tets[bad]), 1)
        self.mesh.fill(x, core[~self.mesh.fixed[core]])
        filled = x[free].copy()
        warm = None if warm is None else np.asarray(warm, dtype=np.float64)
        for part in self.mesh.parts(free):
            at = np.searchsorted(free, part)
            cells = self.mesh.cells(part)
            floor = self._floor[cells]
            patch = self.mesh.gather(cells)
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
        self.mesh.requality(q, x, free)
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
        than that, at a higher cost). Against Newton runs over the whole part, a frame
        takes a fraction of the time for the same worst quality.

        ``patch`` and ``floor``: the part's tetrahedra (:meth:`RelaxMesh.gather`) and their
        stop floors.

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
        self.mesh.fill(x, near)
        self._newton(x, near)
        q = tet_quality(x, tets)
        fresh = (int((q <= 0.0).sum()), -float(q.min()))
        if key <= fresh:
            x[part] = kept
            return key
        return fresh

    def _around(self, cells: NDArray[np.int64], part: NDArray[np.int64]) -> NDArray[np.int64]:
        """The nodes of ``part`` within ``rings`` rings of the tetrahedra ``cells``, sorted."""
        near = self.mesh.ring(np.unique(self.mesh.tets[cells]), self.rings)
        return np.intersect1d(near, part, assume_unique=True)

    def _polish(
        self, x: NDArray[np.float64], moved: NDArray[np.bool_], q: NDArray[np.float64]
    ) -> None:
        """Relax once more around the positive tetrahedra left below the stop floor.

        A pass over a wide patch ends when its energy no longer falls by a thousandth:
        one nearly flat tetrahedron among thousands passes that test (such as a split
        tetrahedron by a bone node). Around those alone (``rings`` rings),
        the same energy is dominated by them. Kept only if the patch's worst quality
        improves and nothing more is inverted. ``q``: the qualities at ``x``.
        """
        floor = self._floor
        low = np.flatnonzero((q > 0.0) & (q < floor))
        if len(low) == 0:
            return
        free = self.mesh.ring(np.unique(self.mesh.tets[low]), self.rings)
        free = free[~self.mesh.fixed[free]]
        if len(free) == 0:
            return
        cells = self.mesh.cells(free)
        q0 = q[cells]
        before = x[free].copy()
        self.stats["polished"] = len(low)
        self._minimise(x, free)
        q1 = tet_quality(x, self.mesh.tets[cells])
        if (q1 <= 0.0).sum() > (q0 <= 0.0).sum() or q1[q1 > 0.0].min() < q0[q0 > 0.0].min():
            x[free] = before
            return
        q[cells] = q1
        moved[free] = True

    def _minimise(self, x: NDArray[np.float64], free: NDArray[np.int64]) -> None:
        """Newton's method on the energy of the tetrahedra around ``free`` (in place).

        Each connected part of the free nodes (joined by a tetrahedron) is minimised on
        its own: the parts share no tetrahedron, so the energy is their sum, and a part
        that converges early (a finger's joint) does not ride along while a deeper one
        (the wrist) takes its Newton steps and line searches.
        """
        for part in self.mesh.parts(free):
            self._newton(x, part)

    def _newton(self, x: NDArray[np.float64], free: NDArray[np.int64], patience: int = 0) -> None:
        """Newton's method on the tetrahedra around one connected part ``free`` (in place).

        See :func:`contact.hand.relaxnewton.newton`; counted in :attr:`stats`.
        """
        newton(
            self.mesh, x, free, self._floor, self.kappa, self.delta, self.maxiter, self.stats,
            patience,
        )  # fmt: skip
