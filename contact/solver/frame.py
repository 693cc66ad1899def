"""The state of one frame that both algorithms share: zones, tolerances, measure, result.

A :class:`FrameState` holds the bodies, the pairs and what the frame learns of them: each
pair's last measurement (:func:`contact.solver.pairs.measure`), the mortar candidates,
the timings, and the :class:`contact.solver.contactset.ContactSet` that keeps its rows.
It marks the contact zones before the bodies are factored, records each iteration and
assembles the :class:`contact.solver.results.FrameResult` from the last state. The
algorithms (:mod:`contact.solver.contact_space`, :mod:`contact.solver.seed`) drive it.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Mapping, Sequence

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

import fem

from ..errors import ContactError
from ..geometry.plane import Plane
from . import contactset, held
from . import zone as zones
from .anchors import Anchors
from .body import ElasticBody
from .contactset import ContactSet, first_set
from .delassus import BodyState
from .driven import DrivenPlanes
from .fields import FrictionState, contact_fields, held_verdict
from .pairs import ContactPair, Penetrations, Survey, measure
from .results import FrameResult, IterationRecord
from .rows import ContactRows, MortarCandidates, mortar_candidates
from .settings import ContactSettings
from .verdicts import over_limit
from .zone import master_zone, slave_zone

__all__ = ["FrameState"]

log = logging.getLogger(__name__)


class FrameState:
    """The state of one frame: bodies, pairs, geometry, contact set, timings.

    Parameters
    ----------
    bodies : sequence of ElasticBody
        The deformable bodies (the first is the one whose total contact force the
        history records).
    planes : sequence of Plane
        The rigid planes the pairs refer to.
    pairs : sequence of ContactPair
        Which slave nodes touch which master.
    settings : ContactSettings
        Algorithm and tolerances.
    callback : callable, optional
        Called with each iteration's record as it is made.

    Raises
    ------
    ContactError
        On names that repeat, or a pair whose bodies or plane are not in the scene.
    """

    def __init__(
        self,
        bodies: Sequence[ElasticBody],
        planes: Sequence[Plane],
        pairs: Sequence[ContactPair],
        settings: ContactSettings,
        callback: Callable[[IterationRecord], None] | None = None,
    ) -> None:
        names = [b.name for b in bodies] + [p.name for p in planes]
        if len(set(names)) != len(names):
            raise ContactError(f"body and plane names must be unique, got {names}")
        self.t0 = time.perf_counter()
        self.bodies = list(bodies)
        self.planes = list(planes)
        self.pairs = list(pairs)
        for p in self.pairs:
            if p.slave not in self.bodies or (not p.rigid and p.master not in self.bodies):
                raise ContactError(f"contact pair {p.name}: its bodies are not in the scene")
            if p.rigid and p.master not in self.planes:
                raise ContactError(f"contact pair {p.name}: its plane is not in the scene")
        self.settings = settings
        self.driven = DrivenPlanes(self.planes, self.pairs)
        self.local = {b.name: np.sqrt(np.maximum(b.node_areas, 1e-300)) for b in self.bodies}
        # broad-phase margin: one element
        self.margin = max(float(self.local[b.name].max()) for b in self.bodies)
        self.callback = callback
        self._measured: dict[int, tuple[dict[str, NDArray], float, Penetrations]] = {}
        # what each pair's last measurement tells of its nodes far from the master
        self._surveys: dict[int, Survey] = {}
        self._force = 0.0
        self._loads = max(float(np.linalg.norm(b.loads)) for b in self.bodies)
        boxes = np.array([fem.bounding_box(b.mesh.points) for b in self.bodies])  # (b, 2, 3)
        self.extent = float((boxes[:, 1].max(axis=0) - boxes[:, 0].min(axis=0)).max())
        self.timings = {"geometry": 0.0, "contact solve": 0.0, "bodies": 0.0, "mortar": 0.0}
        t = time.perf_counter()
        # mortar rows come from the reference geometry, once per frame
        self.mortar: dict[int, MortarCandidates] = {
            i: mortar_candidates(p, i, self.margin) for i, p in enumerate(self.pairs) if p.mortar
        }
        self.timings["mortar"] = time.perf_counter() - t
        self.contacts = ContactSet(self)

    def mark_zones(
        self,
        start: Mapping[str, NDArray] | None = None,
        extra: Mapping[str, NDArray[np.int64]] | None = None,
    ) -> None:
        """Mark each body's contact zone for partial solves, then factor the bodies.

        The zone of each pair (:mod:`contact.solver.zone`): the expected patch and a ring
        around it on the slave, and the master nodes those can reach, measured at rest
        (or at ``start``, where the frame's first search looks). Rows there get their
        compliance from partial solves (:meth:`fem.StaticSolver.mark`); a row outside
        (the patch grew further) costs a full back-solve, nothing else. Where both sides
        of a frictionless pair are held, the expected patch is the first set: the nodes
        deeper than half the deepest overlap and a ring (``HELD_RING`` of :mod:`.zone`),
        about half the overlap's area and so half its marked DOFs (their count makes the
        factorisation dearer). ``extra`` nodes are marked first (friction's anchors).
        """
        t = time.perf_counter()
        u = {b.name: np.zeros((b.mesh.n_points, 3)) for b in self.bodies}
        if start is not None:
            u.update({k: np.asarray(v) for k, v in start.items() if k in u})
        self.driven.touch(u)
        # candidate nodes of each body's zone, with how near they are (smaller first)
        # and the components their rows can touch
        zone: dict[str, list[tuple[NDArray, NDArray, NDArray]]] = {b.name: [] for b in self.bodies}
        every = np.ones(3, dtype=bool)
        for name, nodes in (extra or {}).items():
            if name in zone and len(nodes):
                n = np.unique(np.asarray(nodes, dtype=np.int64))
                zone[name].append((n, np.full(n.size, -np.inf), every))
        for i, pair in enumerate(self.pairs):
            if i in self.mortar:
                for name, nodes, near in self.contacts.mortar_zone(i, u):
                    zone[name].append((nodes, near, pair.touched))  # a plane's: its normal
                continue
            wide = 3.0 * self.margin
            p = self.measure_pair(i, u, wide)
            depth = float(np.max(-p.gap, initial=0.0))
            if depth + self.margin > wide:  # deep overlap: its ring too
                p = self.measure_pair(i, u, depth + self.margin)
            slave = pair.slave
            first = first_set(p.gap, self.tol(pair, p.nodes))  # as new_rows takes it
            local = self.local[slave.name][p.nodes]
            ring = None if pair.wide_start else zones.HELD_RING
            sel = slave_zone(slave.mesh.points, p.nodes, p.gap, first, local, ring)
            # and every node the first set holds (inside, or within the near band)
            if pair.wide_start:
                sel |= p.gap < self.contacts.near_band(pair, p.nodes, p.gap, contactset.NEAR)
            near, gap = p.nodes[sel], p.gap[sel]
            if not near.size:
                continue
            zone[slave.name].append((near, gap, pair.touched))
            if not pair.rigid:
                master: ElasticBody = pair.master  # type: ignore[assignment]
                used = master.contact_nodes
                ok, dist = master_zone(
                    slave.mesh.points[near],
                    gap,
                    self.local[slave.name][near],
                    master.mesh.points[used],
                )
                zone[master.name].append((used[ok], dist[ok], every))
        for b in self.bodies:
            if parts := zone[b.name]:
                nodes, near = (np.concatenate(x) for x in list(zip(*parts, strict=True))[:2])
                touched = np.concatenate([np.broadcast_to(t, (n.size, 3)) for n, _, t in parts])
                marked = b.mark_zone(nodes, near, touched)
                log.debug("%s: %d contact-zone nodes marked", b.name, marked)
        self.timings["geometry"] += time.perf_counter() - t
        before = {b.name: b.solver.factor_time for b in self.bodies}
        for b in self.bodies:
            # the body's own loads (gravity) are solved in the factorisation's sweeps
            b.solver.anticipate(b.loads[b.solver.free])
            b.solver.factorize()
        self.timings["factorisation"] = sum(
            b.solver.factor_time - before[b.name] for b in self.bodies
        )

    def force_scale(self, lam: NDArray[np.float64]) -> float:
        """The frame's force scale: the largest contact force met so far, or the loads.

        Contacts pull when their force is below ``-force_tolerance`` times it: a contact
        whose force is zero to round-off is not released (a free ball that nothing
        presses would otherwise cycle between touching and not).
        """
        self._force = max(self._force, float(np.abs(lam).max(initial=0.0)))
        return max(self._force, self._loads, 1e-300)

    def record(
        self,
        history: list[IterationRecord],
        *,
        iteration: int,
        contacts: int,
        added: int,
        released: int,
        change: float,
        depth: float,
        e: Mapping[str, sp.csr_matrix],
        lam: NDArray[np.float64],
        relaxation: float = 1.0,
        supports: Mapping[str, Mapping[str, NDArray]] | None = None,
        normal_rows: int | None = None,
    ) -> None:
        """Append an iteration's record to ``history`` and tell the callback.

        Parameters
        ----------
        history : list of IterationRecord
            The frame's records so far.
        iteration : int
            The iteration's number, from 1.
        contacts : int
            Contacts in its set (closed rows, for contact space).
        added, released : int
            Rows the update added (or renewed) and released (or opened).
        change : float
            Largest change of a nodal displacement (m).
        depth : float
            Deepest penetration measured (m).
        e : mapping of str to sparse matrix
            Each body's part ``E_b`` of the rows.
        lam : ndarray, shape (m,)
            The rows' forces (N).
        relaxation : float
            The seed loop's relaxation factor (1 otherwise).
        supports : mapping, optional
            The support groups' forces (:meth:`supports`); none: a largest of 0.
        normal_rows : int, optional
            With friction: the first ``normal_rows`` rows are the normal ones (the
            rest tangential), for the record's normal force.
        """
        largest = 0.0
        if supports is not None:
            norms = (np.linalg.norm(f) for s in supports.values() for f in s.values())
            largest = float(max(norms, default=0.0))
        rec = IterationRecord(
            iteration=iteration,
            n_contacts=contacts,
            added=added,
            released=released,
            max_change=change,
            max_penetration=depth,
            total_force=_body_force(e, lam, self.bodies[0]),
            normal_force=float(np.nansum(lam[:normal_rows])),
            relaxation=relaxation,
            max_support_force=largest,
        )
        history.append(rec)
        if self.callback is not None:
            self.callback(rec)

    def measure(self, u: Mapping[str, NDArray]) -> list[Penetrations]:
        """Gaps of every pair's candidates at displacements ``u``."""
        t = time.perf_counter()
        out = [self.measure_pair(i, u, self.margin) for i in range(len(self.pairs))]
        self.timings["geometry"] += time.perf_counter() - t
        return out

    def measure_pair(self, i: int, u: Mapping[str, NDArray], margin: float) -> Penetrations:
        """Pair ``i``'s candidates within ``margin`` at displacements ``u``.

        The last measurement of each pair is kept: asked again at the same displacements
        (the converged state, the rest state the contact zone was marked at) with a
        margin no wider, it is filtered instead of measured again.
        """
        pair = self.pairs[i]
        names = [pair.slave.name] + ([] if pair.rigid else [pair.master.name])
        if pair.master.name in self.driven.shift:  # a force-driven plane, where it is now
            u = self.driven.where(i, u)
            names.append(pair.master.name)
        kept = self._measured.get(i)
        if kept is not None:
            ku, kmargin, kp = kept
            if margin <= kmargin and all(np.array_equal(ku[n], u[n]) for n in names):
                return kp.select(kp.gap < margin)
        p, survey = measure(pair, u, margin, self._surveys.get(i))
        if survey is not None:
            self._surveys[i] = survey
        self._measured[i] = ({n: np.array(u[n]) for n in names}, margin, p)
        return p

    def tol(self, pair: ContactPair, nodes: NDArray[np.int64]) -> NDArray[np.float64]:
        """Penetration tolerance of slave nodes (m)."""
        return self.settings.gap_tolerance * self.local[pair.slave.name][nodes]

    def row_tol(self, rows: ContactRows) -> NDArray[np.float64]:
        """Penetration tolerance of every row's slave node (m)."""
        out = np.zeros(len(rows))
        for i, pair in enumerate(self.pairs):
            mine = rows.pair == i
            if mine.any():
                out[mine] = self.tol(pair, rows.node[mine])
        return out

    def matrices(self, rows: ContactRows) -> dict[str, sp.csr_matrix]:
        """Each body's part ``E_b`` of the rows, and each force-driven plane's.

        A force-driven plane is a rigid master with one node: its part ``(m, 3)`` is
        minus the row's direction on the rows against it (a plane that moves by ``d``
        closes them by ``n . d``).
        """
        out = rows.matrices(self.pairs, self.bodies)
        out.update(self.driven.matrices(rows))
        return out

    def supports(self, states: Mapping[str, BodyState]) -> dict[str, dict[str, NDArray]]:
        """Force on every support group (bone) of every body, from the bodies' reactions."""
        return {b.name: b.support_forces(states[b.name].reactions) for b in self.bodies}

    def over_limit(
        self, supports: Mapping[str, Mapping[str, NDArray]]
    ) -> dict[str, tuple[float, float]]:
        """Support groups whose force magnitude passes its limit (:mod:`.verdicts`)."""
        return over_limit(self.settings.support_limits, supports)

    def separation(
        self, rows: ContactRows, lam: NDArray[np.float64], pens: list[Penetrations]
    ) -> float:
        """Largest gap of a pushing row's node at the end, over its element size.

        A row is linear in the displacements: taken where the bodies were, it still
        pushes once they have slid along each other, with its node found apart from the
        master by the nonlinear measure (the row's plane and the master's surface part
        by about the slide times the turn of the normal). Out of the measure's reach
        counts as one element.
        """
        out = 0.0
        pushing = lam > 1e-9 * float(np.max(lam, initial=0.0))  # not round-off forces
        for i, (pair, p) in enumerate(zip(self.pairs, pens)):
            if pair.rigid or i in self.mortar:
                continue  # a plane's row is exact; a mortar row closes weighted gaps
            nodes = rows.node[(rows.pair == i) & pushing & (lam > 0)]
            if not nodes.size:
                continue
            gap = np.full(nodes.size, self.margin)  # out of reach: a whole element
            if p.nodes.size:
                order = np.argsort(p.nodes)
                k = order[np.minimum(np.searchsorted(p.nodes, nodes, sorter=order), order.size - 1)]
                hit = p.nodes[k] == nodes
                gap[hit] = p.gap[k[hit]]
            r = gap / self.local[pair.slave.name][nodes]
            out = max(out, float(np.max(np.minimum(r, 1.0), initial=0.0)))
        return out

    def untouched(
        self,
        rows: ContactRows,
        e: Mapping[str, sp.csr_matrix],
        lam: NDArray[np.float64],
        states: Mapping[str, BodyState],
    ) -> str:
        """The stop reason of a free body that no contact holds at the end, or "".

        :func:`contact.solver.held.touches_nothing` for the last solve of the normal rows
        ``rows`` (forces ``lam``): a body moved when its rigid motion passes the gap
        tolerance times its largest element size. A row pushes when its force passes
        round-off: 1e-10 of the force its own stiffness (the diagonal of ``K`` along it,
        an upper bound of its inverse compliance) takes to close the deepest gap.
        """
        moves = held.slides(self.bodies, states)
        gap = held.end_gaps(rows.g0, e, states)
        tol = self.row_tol(rows)
        still = {n: self.settings.gap_tolerance * float(self.local[n].max()) for n in moves}
        m = lam.size
        stiff = np.zeros(m)
        for b in self.bodies:
            if (eb := e.get(b.name)) is not None:
                stiff += eb[:m].multiply(eb[:m]) @ b.stiffness_diagonal
        small = 1e-10 * float(np.abs(rows.g0).max(initial=0.0)) * stiff
        rest = {b.name: rows.g0 < -tol for b in self.bodies if not b.loads.any()}
        return held.touches_nothing(e, lam, gap, tol, moves, still, small, rest)

    def result(
        self,
        *,
        converged: bool,
        stop: str,
        history: list[IterationRecord],
        rows: ContactRows,
        lam: NDArray[np.float64],
        states: Mapping[str, BodyState],
        friction: FrictionState | None = None,
        anchors: Anchors | None = None,
        slip: dict | None = None,
    ) -> FrameResult:
        """Assemble the frame's result from the last state.

        A frame converged only where no node-to-surface contact is left inside by more
        than the tolerance; otherwise ``stop_reason`` says which. A support group over its
        limit leaves it converged: ``over_limit`` names it (:mod:`.verdicts`). ``rows``
        and ``lam`` are the closed contacts' normal rows and forces; ``friction`` their
        tangential rows and forces, where any; ``slip`` the record of a free body friction
        does not hold (:meth:`contact.solver.coulomb.Slip.record`).
        """
        e = self.matrices(rows) if len(rows) else {}
        force_rows, force_lam = rows, lam
        if friction is not None:
            force_rows, force_lam = friction.rows, friction.lam
        e_all = self.matrices(force_rows) if len(force_rows) else {}
        contact_force = {}
        for b in self.bodies:
            eb = e_all.get(b.name)
            f = eb.T @ force_lam if eb is not None else np.zeros(b.mesh.n_dofs)
            contact_force[b.name] = f.reshape(-1, 3)
        plane_forces = {}
        for pl in self.planes:
            idx = [i for i, p in enumerate(self.pairs) if p.master is pl]
            sel = np.isin(force_rows.pair, idx)
            plane_forces[pl.name] = -(force_lam[sel][:, None] * force_rows.normal[sel]).sum(
                axis=0
            )
        supports = {
            b.name: b.support_forces(states[b.name].reactions) for b in self.bodies if b.supports
        }
        u = {b.name: states[b.name].u.reshape(-1, 3) for b in self.bodies}
        pens = self.measure(u)
        depth = max((float(np.max(-p.gap, initial=0.0)) for p in pens), default=0.0)
        ratios = [
            -p.gap / self.local[pair.slave.name][p.nodes] for pair, p in zip(self.pairs, pens)
        ]
        ratio = max((float(np.max(r, initial=0.0)) for r in ratios), default=0.0)
        apart = self.separation(rows, lam, pens)
        if converged:
            # contacts whose rows could not be renewed any more may still penetrate: a
            # frame is converged only where every node-to-surface pair is within the
            # tolerance (mortar pairs close weighted gaps, not nodal ones)
            worst = [
                (float(r.max()), pair.name, int(p.nodes[np.argmax(r)]))
                for i, (pair, p, r) in enumerate(zip(self.pairs, pens, ratios))
                if i not in self.mortar and r.size
            ]
            deepest = max(worst, default=(0.0, "", -1))
            if deepest[0] > self.settings.gap_tolerance:
                converged = False
                stop = (
                    f"penetration left: node {deepest[2]} of pair {deepest[1]} is inside by "
                    f"{deepest[0]:.3g} of its element size (tolerance "
                    f"{self.settings.gap_tolerance:g})"
                )
        spun = held.turned(self.bodies, states)
        if spun and converged:
            converged, stop = False, spun
        over = self.over_limit(supports)
        self.timings["total"] = time.perf_counter() - self.t0
        names = np.array([p.name for p in self.pairs], dtype=object)
        contacts = {
            "pair": names[rows.pair] if len(rows) else np.zeros(0, dtype=object),
            "node": rows.node.copy(),
            "force": np.asarray(lam, dtype=np.float64).copy(),
            "normal": rows.normal.copy(),
        }
        if friction is not None:
            contacts.update(friction.per_contact())
        fields = contact_fields(self.bodies, self.pairs, rows, lam, e, contact_force, friction)
        return FrameResult(
            converged=converged,
            stop_reason=stop,
            algorithm=self.settings.algorithm,
            iterations=len(history),
            history=tuple(history),
            displacement=u,
            contact_force=contact_force,
            obstacle_forces=plane_forces,
            support_forces=supports,
            over_limit=over,
            contacts=contacts,
            max_penetration=depth,
            penetration_ratio=ratio,
            separation_ratio=apart,
            timings=dict(self.timings),
            friction=None if friction is None else friction.report,
            held=held_verdict(self.bodies, converged, stop),
            anchors=anchors,
            contact_fields=fields,
            plane_positions=self.driven.positions(),
            slip=slip,
        )


def _body_force(
    e: Mapping[str, sp.csr_matrix], lam: NDArray[np.float64], body: ElasticBody
) -> NDArray[np.float64]:
    """The total contact force ``E_b^T lambda`` on ``body``."""
    eb = e.get(body.name)
    if eb is None or not lam.size:
        return np.zeros(3)
    return (eb.T @ lam).reshape(-1, 3).sum(axis=0)
