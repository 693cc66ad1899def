"""The contact iteration of a frame: seed 000's five steps, and the same in contact space.

Both algorithms share the geometry (:mod:`contact.solver.pairs`): step 2 finds the slave nodes
behind a plane or inside another body's surface and takes, for each, a gap row along the
master's normal at its closest point; a node in contact stays in contact (contact memory)
until its force pulls, and is then released.

``"seed"`` is Fig. 9 of seed 000 read literally, a Dirichlet-Neumann iteration between
one *Dirichlet* body (the ball) and the others (the hand):

3. solve the ball with its contact rows prescribed against the others' current
   positions; its reactions are the contact forces (equations 7 and 8; a free ball through
   its rigid modes, whose amplitudes place it);
4. dispatch each reaction, reversed, onto the master facet's nodes with the barycentric
   weights (action equals reaction by construction);
5. solve the others under these forces (bones prescribed); the ball keeps step 3's
   state; relax the others' answer (none, a fixed factor, or Aitken's).

It converges only where the ball is the softer side (the others then act as a mould stiffer
than it). ``"contact-space"`` (the default) solves the fixed point of steps 2 to 5 directly
with the Delassus operator of both bodies (:class:`contact.solver.delassus.ContactSpace`). Its
rows are candidates: for the rows linearised so far, the unilateral solve
(:mod:`contact.solver.lcp`) closes those that must push and leaves the others open at zero force,
so a row that pulls is opened there, at no cost in back-solves, and is taken again there
if the linearised gaps need it. The outer loop only brings geometry: it measures the
deformed bodies, adds a row for each node found inside its master and linearises stale
rows again, and stops when the measure finds nothing new. The set of rows only grows
within a frame (rows left far behind by a body that moved off are dropped), so the outer
loop cannot cycle by releasing and taking the same contacts in turn, as it did where
rows both ways meet (two-pass node-to-surface contact over-constrains there).

Each body is factored once (when it is built); nothing is refactored here.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

import fem

from ..errors import ContactError
from ..geometry.plane import Plane
from .body import ElasticBody
from .delassus import BodyState, ContactSpace
from .pairs import ContactPair, ContactRows, Penetrations, Survey, measure, mortar_candidates
from .results import FrameResult, IterationRecord
from .zone import master_zone, slave_zone

__all__ = [
    "ALGORITHMS",
    "LCP_TOLERANCE",
    "RELAXATIONS",
    "ContactSettings",
    "solve_frame",
]

log = logging.getLogger(__name__)

#: Contact algorithms by name.
ALGORITHMS = ("contact-space", "seed")
#: Relaxations of the seed loop.
RELAXATIONS = ("none", "fixed", "aitken")
#: A node in contact found inside another facet of its master, whose normal differs from
#: its rows' by more than arccos of this (about 0.8 degree), is in a concave corner or
#: crease: it keeps its row and gets one for that facet too, up to ``CORNER_ROWS`` rows in
#: all. Nearly flat creases count: on one row at a time, a node there would move from
#: facet to facet; two rows that nearly repeat one another are safe for the unilateral
#: solve (it opens the one not needed).
CORNER_COS = 0.9999
CORNER_ROWS = 3
#: Times a contact row may be linearised again on the same facet in one frame.
RELINEARISE = 8
#: The unilateral solve leaves a row open when its linearised gap is at least minus this
#: fraction of the penetration tolerance (``gap_tolerance`` times the element size): the
#: rest of the tolerance is for the linearisation's error, so that the nonlinear measure
#: does not find the node inside and take it again.
LCP_TOLERANCE = 0.5
#: The first contact set of contact space holds every node inside its master or outside
#: within this many of its element sizes (or the pair's deepest overlap, see
#: ``_Frame.near_band``), as candidates: a free body's first solve would otherwise slide
#: it through what it nearly touches (a bowl's walls that touch the ball between nodes, a
#: palm half a millimetre above a ball the fingers squeeze).
NEAR = 0.5
#: A solve that moves a free body rigidly by more than this many element sizes (the
#: frame's largest) jumped: new rows are linearised where it was before (a safety net
#: behind ``NEAR``: an obstacle further than that from the ball at the frame's start).
JUMP = 0.5
#: Updates in a frame whose solve slides a free body so far that contacts leave their
#: facets, each caught by new contacts where it slid, before the frame stops as not held.
SLIDES = 3
#: A body that slid is held when the unit slide direction keeps at least this length
#: in the span of the normals of the rows that push it.
HELD_COS = 0.5
#: A free body that moved rigidly by more than this many of its element sizes and that
#: no contact pushes at the end was pushed out of contact (not held).
PUSHED_OUT = 0.5
#: Stride of a row's (pair, node) key: more nodes than any body has.
_KEY_STRIDE = 1 << 40


@dataclass(frozen=True)
class ContactSettings:
    """Settings of the contact iteration.

    Parameters
    ----------
    algorithm : {"contact-space", "seed"}
        See the module docstring.
    max_iterations : int
        Limit on the iterations (>= 1).
    tolerance : float
        Seed loop: converged when the largest change of a nodal displacement between two
        iterations is at most this fraction of the largest displacement (> 0).
    gap_tolerance : float
        A node is penetrating when it is inside its master by more than this fraction of
        its local element size (square root of its tributary area); at the start, nodes
        that touch within it are taken in contact (> 0).
    force_tolerance : float
        Seed loop: a contact is released when it pulls by more than this fraction of
        the largest contact force (>= 0). Contact space opens every row that would pull
        (its unilateral solve: forces below 1e-10 of the scale of its gaps are round-off).
    relaxation : {"none", "fixed", "aitken"}
        Relaxation of the seed loop's step 5.
    relaxation_factor : float
        The fixed factor, and Aitken's first one, in (0, 1].
    support_limits : mapping of str to float, optional
        Largest force (N) each support group (bone) may carry; a frame whose force passes
        it stops (seed) or is reported over the limit (contact space). Groups not named
        have no limit.
    """

    algorithm: str = "contact-space"
    max_iterations: int = 50
    tolerance: float = 1e-4
    gap_tolerance: float = 1e-3
    force_tolerance: float = 1e-9
    relaxation: str = "none"
    relaxation_factor: float = 0.5
    support_limits: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.algorithm not in ALGORITHMS:
            raise ContactError(
                f"solver.algorithm must be one of {', '.join(ALGORITHMS)}, got {self.algorithm!r}"
            )
        if self.relaxation not in RELAXATIONS:
            raise ContactError(
                f"solver.relaxation must be one of {', '.join(RELAXATIONS)}, "
                f"got {self.relaxation!r}"
            )
        if not isinstance(self.max_iterations, int) or self.max_iterations < 1:
            raise ContactError(
                f"solver.max_iterations must be an integer >= 1, got {self.max_iterations!r}"
            )
        for key in ("tolerance", "gap_tolerance"):
            v = getattr(self, key)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ContactError(f"solver.{key} must be a positive number, got {v!r}")
        if not (math.isfinite(self.force_tolerance) and self.force_tolerance >= 0):
            raise ContactError(f"solver.force_tolerance must be >= 0, got {self.force_tolerance!r}")
        if not (0 < self.relaxation_factor <= 1):
            raise ContactError(
                f"solver.relaxation_factor must lie in (0, 1], got {self.relaxation_factor!r}"
            )
        for k, v in self.support_limits.items():
            if not (isinstance(v, (int, float)) and v > 0):
                raise ContactError(f"bone force limit of {k!r} must be positive, got {v!r}")


class _Frame:
    """The state shared by both algorithms: bodies, pairs, geometry, records."""

    def __init__(
        self,
        bodies: Sequence[ElasticBody],
        planes: Sequence[Plane],
        pairs: Sequence[ContactPair],
        settings: ContactSettings,
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
        # the pair in the other direction between the same two bodies, -1 if none
        self.reverse = [
            next(
                (
                    j
                    for j, q in enumerate(self.pairs)
                    if not p.rigid and q.slave is p.master and q.master is p.slave
                ),
                -1,
            )
            for p in self.pairs
        ]
        self.local = {b.name: np.sqrt(np.maximum(b.node_areas, 1e-300)) for b in self.bodies}
        self.margin = max(
            float(self.local[b.name].max()) for b in self.bodies
        )  # broad-phase margin: one element
        self.callback: Callable[[IterationRecord], None] | None = None
        self._measured: dict[int, tuple[dict[str, NDArray], float, Penetrations]] = {}
        # what each pair's last measurement tells of its nodes far from the master
        self._surveys: dict[int, Survey] = {}
        self._force = 0.0
        self.broken = 0
        self.broken_keys = np.zeros(0, dtype=np.int64)
        self.renewed: dict[int, dict[int, int]] = {}
        self.relinearised: dict[int, dict[int, int]] = {}
        self._loads = max(float(np.linalg.norm(b.loads)) for b in self.bodies)
        boxes = np.array([fem.bounding_box(b.mesh.points) for b in self.bodies])  # (b, 2, 3)
        self.extent = float((boxes[:, 1].max(axis=0) - boxes[:, 0].min(axis=0)).max())
        self.timings = {"geometry": 0.0, "contact solve": 0.0, "bodies": 0.0, "mortar": 0.0}
        t = time.perf_counter()
        # mortar rows come from the reference geometry, once per frame
        self.mortar = {
            i: mortar_candidates(p, i, self.margin) for i, p in enumerate(self.pairs) if p.mortar
        }
        self.timings["mortar"] = time.perf_counter() - t

    def mark_zones(self) -> None:
        """Mark each body's contact zone for partial solves, before it is factored.

        The zone of each pair (:mod:`contact.solver.zone`): the expected patch and a ring around
        it on the slave, and the master nodes those can reach, measured at rest. Rows
        there get their compliance from partial solves (:meth:`fem.StaticSolver.mark`);
        a row outside (the patch grew further) costs a full back-solve, nothing else.
        """
        t = time.perf_counter()
        u = {b.name: np.zeros((b.mesh.n_points, 3)) for b in self.bodies}
        # candidate nodes of each body's zone, with how near they are (smaller first)
        zone: dict[str, list[tuple[NDArray[np.int64], NDArray[np.float64]]]] = {
            b.name: [] for b in self.bodies
        }
        for i, pair in enumerate(self.pairs):
            if i in self.mortar:
                cand = self.mortar[i]
                sides = ((pair.slave, cand.rows.s_nodes), (pair.master, cand.rows.m_nodes))
                for body, nodes in sides:
                    n = np.unique(nodes[nodes >= 0])  # type: ignore[union-attr]
                    zone[body.name].append((n, np.full(n.size, -np.inf)))
                continue
            wide = 3.0 * self.margin
            p = self.measure_pair(i, u, wide)
            depth = float(np.max(-p.gap, initial=0.0))
            if depth + self.margin > wide:  # deep overlap: its ring too
                p = self.measure_pair(i, u, depth + self.margin)
            slave = pair.slave
            first = _first(p.gap, self.tol(pair, p.nodes))  # as new_rows takes it
            local = self.local[slave.name][p.nodes]
            sel = slave_zone(slave.mesh.points, p.nodes, p.gap, first, local)
            # and every node the first set holds (inside, or within the near band)
            sel |= p.gap < self.near_band(pair, p, NEAR)
            near, gap = p.nodes[sel], p.gap[sel]
            if not near.size:
                continue
            zone[slave.name].append((near, gap))
            if not pair.rigid:
                master: ElasticBody = pair.master  # type: ignore[assignment]
                used = master.contact_nodes
                ok, dist = master_zone(
                    slave.mesh.points[near],
                    gap,
                    self.local[slave.name][near],
                    master.mesh.points[used],
                )
                zone[master.name].append((used[ok], dist[ok]))
        for b in self.bodies:
            if zone[b.name]:
                nodes, near = (np.concatenate(x) for x in zip(*zone[b.name], strict=True))
                marked = b.mark_zone(nodes, near)
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

    def near_band(self, pair: ContactPair, p: Penetrations, near: float) -> NDArray[np.float64]:
        """How far outside a node joins the first set, open (m, per node).

        ``near`` of its element size, or the pair's deepest overlap where that is more
        (up to one element). Two bodies pressed together by an overlap ``d`` close the
        nodes whose gap is less than about ``d`` (a Hertz patch); taking them all keeps
        the first solve's patch, and the updates it takes, the same on every mesh.
        Against a rigid master (a plane) only the slave gives way, away from it: the
        nodes a press closes are inside it already, and the band is ``near`` alone (the
        hand cup's first set 287 -> 235 rows; the same forces and updates on the cup at
        four stiffness ratios and two depths, and on every row of the iteration study).
        """
        local = self.local[pair.slave.name][p.nodes]
        if pair.rigid:
            return near * local
        deepest = float(np.max(-p.gap, initial=0.0))
        return np.minimum(np.maximum(near * local, deepest), local)

    def slides(self, states: dict[str, BodyState]) -> dict[str, NDArray[np.float64]]:
        """Each free body's rigid translation in ``states`` (m)."""
        out = {}
        for b in self.bodies:
            rigid = states[b.name].rigid
            if b.solver.free_body and rigid.size:
                out[b.name] = (b.solver.modes[:, :3] @ rigid[:3]).reshape(-1, 3)[0]
        return out

    def slipping(self, moves: dict[str, NDArray[np.float64]], broken: int) -> str:
        """The stop reason when contacts in the set have lost their masters.

        Frictionless contacts hold a free body only where their normals enclose it; where
        they do not (a ball pushed towards the open side of a hand), the linear solve
        slides it rigidly along the open direction until its linearised contacts
        balance, so far that the contact nodes have left their facets. Unless something
        it slid into holds it (see :func:`_contact_space`), the frame stops: the body
        slips out. ``moves``: the bodies' rigid translations (:meth:`slides`).
        """
        sizes = [(float(np.linalg.norm(m)), n, m) for n, m in moves.items()]
        how = ""
        if sizes:
            dist, name, move = max(sizes, key=lambda m: m[0])
            d = move / max(dist, 1e-300)
            how = f"{name} slid {dist * 1e3:.3g} mm along [{d[0]:.2f}, {d[1]:.2f}, {d[2]:.2f}]; "
        return (
            f"not held: {how}{broken} contact(s) left their facets (frictionless contacts "
            "that do not enclose a body cannot hold it)"
        )

    def pushed_out(
        self,
        e: dict[str, sp.csr_matrix],
        lam: NDArray[np.float64],
        moves: dict[str, NDArray[np.float64]],
    ) -> str:
        """The stop reason of a free body the contacts pushed off, or "" if none was.

        A free body that moved rigidly by more than ``PUSHED_OUT`` of its element size
        and that no contact pushes at the end was pushed out of contact: frictionless
        contacts that do not enclose it (fingers closing on a ball with nothing behind
        it) push it away until they open. Any place further along balances too, so the
        frame does not say where it is. ``e`` are the rows' matrices (:meth:`matrices`),
        ``moves`` the bodies' rigid translations (:meth:`slides`).
        """
        for name, move in moves.items():
            dist = float(np.linalg.norm(move))
            if dist <= PUSHED_OUT * float(self.local[name].max()):
                continue  # a nudge (a ball settling in a frictionless bowl)
            eb = e.get(name)
            if eb is not None and (lam > 0).any() and eb[lam > 0].nnz:
                continue
            d = move / dist
            return (
                f"not held: {name} pushed out of contact, {dist * 1e3:.3g} mm along "
                f"[{d[0]:.2f}, {d[1]:.2f}, {d[2]:.2f}], and no contact holds it "
                "(frictionless contacts hold a free body only where they enclose it)"
            )
        return ""

    def holds(
        self,
        e: dict[str, sp.csr_matrix],
        lam: NDArray[np.float64],
        moves: dict[str, NDArray[np.float64]],
    ) -> bool:
        """Whether the pushing rows hold every free body against its slide ``moves``.

        A body that slid so far that contacts left their facets is held once the normals
        of the rows that push it span the slide's direction: a wall or another finger
        caught it. Otherwise it slid out of reach and the forces that remain (none, or
        only those in other directions) do not say where it is. ``e`` as for
        :meth:`pushed_out`.
        """
        modes = {b.name: b.solver.modes for b in self.bodies}
        for name, move in moves.items():
            dist = float(np.linalg.norm(move))
            if dist == 0.0:
                continue
            eb = e.get(name)
            if eb is None or not (lam > 0).any():
                return False
            t = eb[lam > 0] @ modes[name][:, :3]  # the pushing rows' directions
            _, sv, vt = np.linalg.svd(t, full_matrices=False)
            span = vt[sv > 1e-6 * sv.max()] if sv.size and sv.max() > 0 else np.zeros((0, 3))
            if np.linalg.norm(span @ (move / dist)) < HELD_COS:
                return False
        return True

    def force_scale(self, lam: NDArray[np.float64]) -> float:
        """The frame's force scale: the largest contact force met so far, or the loads.

        Contacts pull when their force is below ``-force_tolerance`` times it: a contact
        whose force is zero to round-off is not released (a free ball that nothing
        presses would otherwise cycle between touching and not).
        """
        self._force = max(self._force, float(np.abs(lam).max(initial=0.0)))
        return max(self._force, self._loads, 1e-300)

    def record(self, history: list[IterationRecord], rec: IterationRecord) -> None:
        """Append an iteration's record and tell the callback."""
        history.append(rec)
        if self.callback is not None:
            self.callback(rec)

    def measure(self, u: dict[str, NDArray]) -> list[Penetrations]:
        """Gaps of every pair's candidates at displacements ``u``."""
        t = time.perf_counter()
        out = [self.measure_pair(i, u, self.margin) for i in range(len(self.pairs))]
        self.timings["geometry"] += time.perf_counter() - t
        return out

    def measure_pair(self, i: int, u: dict[str, NDArray], margin: float) -> Penetrations:
        """Pair ``i``'s candidates within ``margin`` at displacements ``u``.

        The last measurement of each pair is kept: asked again at the same displacements
        (the converged state, the rest state the contact zone was marked at) with a
        margin no wider, it is filtered instead of measured again.
        """
        pair = self.pairs[i]
        names = [pair.slave.name] + ([] if pair.rigid else [pair.master.name])
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

    def new_rows(
        self,
        rows: ContactRows,
        u: dict[str, NDArray],
        touching: bool,
        released: NDArray[np.bool_] | None = None,
        idle: NDArray[np.bool_] | None = None,
        near: float = 0.0,
        before: tuple[dict[str, NDArray], float] | None = None,
    ) -> tuple[ContactRows, int, float]:
        """The next contact set: rows released, penetrating nodes added, stale rows renewed.

        Parameters
        ----------
        rows : ContactRows
            The current set.
        u : dict of str to ndarray
            Current displacements ``(N, 3)`` of every body.
        touching : bool
            Also take nodes within the tolerance outside (the first contact set).
        released : ndarray of bool, optional
            Rows to drop (pulling); their nodes are not taken again in this update.
        idle : ndarray of bool, optional
            Rows kept open at zero force (candidates of the unilateral solve): those whose
            node has moved half an element off its master, or out of reach, are dropped
            instead of counting as contacts that left their facets.
        near : float
            With ``touching``, take every node inside its master or outside it within
            :meth:`near_band` (``near`` of its element size, or the pair's deepest
            overlap): candidates the unilateral solve closes or leaves open, so that a
            free body's first solve cannot slide it through what it nearly touches, and
            the patch of two pressed bodies is taken whole.
        before : (dict of str to ndarray, float), optional
            The displacements before a solve that moved a free body rigidly by more
            than half an element, and how far (m). New rows of deformable masters are
            linearised there, where their nodes were still outside, on the facets they
            were coming to: at the new place a node found deep inside would get the
            closest facet of wherever it landed (the far side of a finger).

        Returns
        -------
        rows : ContactRows
        changed : int
            Rows added or renewed: a node in contact that has slid off its facet so far that
            it is inside the master again gets the row of its new closest point.
        depth : float
            Deepest penetration measured (m).
        """
        self.broken = 0
        broken: list[NDArray[np.int64]] = []
        dropped = rows.select(released) if released is not None else ContactRows()
        if released is not None:
            rows = rows.select(~released)
            idle = idle[~released] if idle is not None else None
        changed = 0
        depth = 0.0
        t = time.perf_counter()
        if idle is not None and idle.any():
            rows = rows.select(~self._left(rows, idle, u))
        for i, pair in enumerate(self.pairs):
            if i in self.mortar:
                rows, n, d = self._mortar_rows(i, rows, dropped, u, touching)
                changed += n
                depth = max(depth, d)
                continue
            p = self.measure_pair(i, u, self.margin)
            if not p.nodes.size:
                continue
            tol = self.tol(pair, p.nodes)
            mine = rows.pair == i
            in_rows = rows.node[mine]
            n_slave = pair.slave.mesh.n_points
            active = _among(p.nodes, in_rows, n_slave)
            # a contact whose node has moved away from its master by half an element (or
            # out of reach) no longer has a valid linearised row: the body slid off it
            far = active & (p.gap > 0.5 * self.local[pair.slave.name][p.nodes])
            lost = np.unique(in_rows[~_among(in_rows, p.nodes, n_slave)])
            gone = np.concatenate([p.nodes[far], lost])
            self.broken += gone.size
            broken.append(gone + i * _KEY_STRIDE)
            fresh = ~active & ~_among(p.nodes, dropped.node[dropped.pair == i], n_slave)
            depth = max(depth, float(np.max(-p.gap, initial=0.0)))
            hit = fresh & (_first(p.gap, tol) if touching else (p.gap < -tol))
            if touching and near > 0.0:
                # every node inside or near: the unilateral solve closes what must push
                hit |= fresh & (p.gap < self.near_band(pair, p, near))
            j = self.reverse[i]
            if j >= 0 and hit.any():
                # node on node: a slave node whose closest point is a master vertex that
                # is itself in contact the other way round would repeat that contact's row
                vertex = p.weights.max(axis=1) >= 1.0 - 1e-9
                tip = p.facet[np.arange(p.nodes.size), p.weights.argmax(axis=1)]
                hit &= ~(vertex & _among(tip, rows.node[rows.pair == j], pair.master.mesh.n_points))
            stale = active & (p.gap < -tol) & (not pair.rigid)
            drop = np.zeros(len(rows), dtype=bool)
            for w in np.flatnonzero(stale):
                n = int(p.nodes[w])
                own = np.flatnonzero(mine & (rows.node == n))
                facet = set(p.facet[w].tolist())
                same = any(set(f[f >= 0].tolist()) == facet for f in rows.m_nodes[own])
                cos = float((rows.normal[own] @ p.normal[w]).max())
                if not same and cos < CORNER_COS and own.size < CORNER_ROWS:
                    # a concave edge or corner: held on one facet, the node is inside the
                    # next one, and the other way round. Outside a concave corner is the
                    # intersection of its facets' half-spaces: it keeps both rows (one
                    # that pulls is released as any other)
                    continue
                # the row is renewed: linearised again at the facet's current place and
                # normal (a soft master's facets turn under the load), or on the facet
                # the node has slid onto. A node that changed facets twice already keeps
                # its row (on a flat edge, renewals would alternate for ever); one renewed
                # on the same facet RELINEARISE times too (the turning has not settled).
                # Nodes left inside make the frame not converged (:meth:`result`).
                limit, book = (RELINEARISE, self.relinearised) if same else (2, self.renewed)
                seen = book.setdefault(i, {})
                seen[n] = seen.get(n, 0) + 1
                if seen[n] > limit:
                    stale[w] = False
                else:
                    drop[own[np.argmax(rows.normal[own] @ p.normal[w])]] = True
            if drop.any():
                rows = rows.select(~drop)
            if before is not None and not pair.rigid and hit.any():
                q = self._outside_before(i, p.select(hit), before).joined(p.select(stale))
            else:
                q = p.select(hit | stale)
            if q.nodes.size:
                rows = rows.extended(self.pairs, i, q)
                changed += q.nodes.size
        self.broken_keys = np.concatenate(broken) if broken else np.zeros(0, dtype=np.int64)
        self.timings["geometry"] += time.perf_counter() - t
        return rows, changed, depth

    def _outside_before(
        self, i: int, p: Penetrations, before: tuple[dict[str, NDArray], float]
    ) -> Penetrations:
        """``p`` with each node measured at ``before`` instead, where it was outside."""
        u, jump = before
        prior = self.measure_pair(i, u, jump + self.margin)
        pos = {int(n): k for k, n in enumerate(prior.nodes)}
        take = np.array([pos.get(int(n), -1) for n in p.nodes], dtype=np.int64)
        ok = take >= 0
        ok[ok] = prior.gap[take[ok]] >= 0.0
        if not ok.any():
            return p
        out = p.select(np.ones(p.nodes.size, dtype=bool))
        for name in ("gap", "facet", "weights", "normal"):
            getattr(out, name)[ok] = getattr(prior, name)[take[ok]]
        return out

    def without_broken(self, rows: ContactRows) -> ContactRows:
        """``rows`` less those whose node the last :meth:`new_rows` found off its master.

        Their linearisation no longer holds: the node left its facet (a free body slid
        along the contacts that held it). A node that penetrates something at its new
        place has its new row already; one that comes back gets a row when measured.
        """
        if not self.broken_keys.size or not len(rows):
            return rows
        return rows.select(~np.isin(rows.pair * _KEY_STRIDE + rows.node, self.broken_keys))

    def _left(
        self, rows: ContactRows, idle: NDArray[np.bool_], u: dict[str, NDArray]
    ) -> NDArray[np.bool_]:
        """Idle rows whose node has moved half an element off its master, or out of reach."""
        out = np.zeros(len(rows), dtype=bool)
        for i, pair in enumerate(self.pairs):
            mine = idle & (rows.pair == i)
            if i in self.mortar or not mine.any():
                continue
            p = self.measure_pair(i, u, self.margin)
            n_slave = pair.slave.mesh.n_points
            near = p.nodes[p.gap <= 0.5 * self.local[pair.slave.name][p.nodes]]
            # a node with a closed row too keeps its idle rows (a corner's other facet)
            held = rows.node[(rows.pair == i) & ~idle]
            node = rows.node[mine]
            keep = _among(node, near, n_slave) | _among(node, held, n_slave)
            out[np.flatnonzero(mine)[~keep]] = True
        return out

    def _mortar_rows(
        self,
        i: int,
        rows: ContactRows,
        dropped: ContactRows,
        u: dict[str, NDArray],
        touching: bool,
    ) -> tuple[ContactRows, int, float]:
        """New mortar rows of pair ``i``: weighted gaps closed or below the tolerance."""
        pair, cand = self.pairs[i], self.mortar[i]
        g = cand.gaps(u[pair.slave.name], u[pair.master.name])  # type: ignore[union-attr]
        nodes = cand.rows.node
        tol = self.tol(pair, nodes)
        fresh = ~np.isin(nodes, rows.node[rows.pair == i]) & ~np.isin(
            nodes, dropped.node[dropped.pair == i]
        )
        hit = fresh & (_first(g, tol) if touching else (g < -tol))
        depth = float(np.max(-g, initial=0.0))
        if hit.any():
            rows = rows.joined(cand.rows.select(hit))
        return rows, int(hit.sum()), depth

    def matrices(self, rows: ContactRows) -> dict:
        """Each body's part of the rows."""
        return rows.matrices(self.pairs, self.bodies)

    def supports(self, states: dict[str, BodyState]) -> dict[str, dict[str, NDArray]]:
        """Force on every support group (bone) of every body, from the bodies' reactions."""
        return {b.name: b.support_forces(states[b.name].reactions) for b in self.bodies}

    def over_limit(self, supports: dict[str, dict[str, NDArray]]) -> dict[str, tuple[float, float]]:
        """Support groups whose force magnitude passes its limit."""
        out = {}
        for forces in supports.values():
            for name, f in forces.items():
                limit = self.settings.support_limits.get(name)
                mag = float(np.linalg.norm(f))
                if limit is not None and mag > limit:
                    out[name] = (mag, float(limit))
        return out

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

    def result(
        self,
        *,
        converged: bool,
        stop: str,
        history: list[IterationRecord],
        rows: ContactRows,
        lam: NDArray[np.float64],
        states: dict[str, BodyState],
    ) -> FrameResult:
        """Assemble the frame's result from the last state."""
        e = self.matrices(rows) if len(rows) else {}
        contact_force = {}
        for b in self.bodies:
            eb = e.get(b.name)
            f = eb.T @ lam if eb is not None else np.zeros(b.mesh.n_dofs)
            contact_force[b.name] = f.reshape(-1, 3)
        plane_forces = {}
        for pl in self.planes:
            idx = [i for i, p in enumerate(self.pairs) if p.master is pl]
            sel = np.isin(rows.pair, idx)
            plane_forces[pl.name] = -(lam[sel][:, None] * rows.normal[sel]).sum(axis=0)
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
        over = self.over_limit(supports)
        if over and converged:
            converged = False
            stop = _limit_reason(over)
        self.timings["total"] = time.perf_counter() - self.t0
        names = np.array([p.name for p in self.pairs], dtype=object)
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
            contacts={
                "pair": names[rows.pair] if len(rows) else np.zeros(0, dtype=object),
                "node": rows.node.copy(),
                "force": np.asarray(lam, dtype=np.float64).copy(),
                "normal": rows.normal.copy(),
            },
            max_penetration=depth,
            penetration_ratio=ratio,
            separation_ratio=apart,
            timings=dict(self.timings),
        )


def _first(gap: NDArray[np.float64], tol: NDArray[np.float64]) -> NDArray[np.bool_]:
    """The first contact set of a pair: nodes deeper than half its deepest overlap.

    Where the bodies overlap (a posed hand in a ball, a plate moved into it), taking every
    overlapping node holds about twice the final patch (for two spheres the overlap radius
    is sqrt(2) times Hertz's contact radius, at which the overlap is half the deepest): the
    outer ones are released ring by ring, and each costs back-solves. Half the deepest
    overlap is where Hertz's patch ends; the updates add what is missing. Where nothing
    overlaps by more than the tolerance, the touching nodes are taken.
    """
    deepest = float(np.max(-gap, initial=0.0))
    if deepest <= float(np.max(tol, initial=0.0)):
        return gap < tol
    return gap < -0.5 * deepest


def _among(x: NDArray[np.int64], y: NDArray[np.int64], n: int) -> NDArray[np.bool_]:
    """``np.isin(x, y)`` for node numbers below ``n``, through a mask (no sorting).

    A frame asks this some 90 times of a few hundred nodes: ``np.isin`` sorts both
    arrays (40 us a call), a mask over the body's nodes costs 1 us.
    """
    mask = np.zeros(n, dtype=bool)
    mask[y] = True
    return mask[x]


def _limit_reason(over: dict[str, tuple[float, float]]) -> str:
    name, (force, limit) = max(over.items(), key=lambda kv: kv[1][0] / kv[1][1])
    return f"bone force limit: {name} carries {force:.4g} N > {limit:.4g} N"


def _first_body_force(e: dict, lam: NDArray[np.float64], body: ElasticBody) -> NDArray[np.float64]:
    eb = e.get(body.name)
    if eb is None or not lam.size:
        return np.zeros(3)
    return (eb.T @ lam).reshape(-1, 3).sum(axis=0)


def _record(
    it: int,
    rows: ContactRows,
    added: int,
    released: int,
    change: float,
    depth: float,
    e: dict,
    lam: NDArray[np.float64],
    frame: _Frame,
    omega: float,
    support: float = 0.0,
    closed: int | None = None,
) -> IterationRecord:
    return IterationRecord(
        iteration=it,
        n_contacts=len(rows) if closed is None else closed,
        added=added,
        released=released,
        max_change=change,
        max_penetration=depth,
        total_force=_first_body_force(e, lam, frame.bodies[0]),
        normal_force=float(np.nansum(lam)),
        relaxation=omega,
        max_support_force=support,
    )


def _with_support(rec: IterationRecord, supports: dict[str, dict[str, NDArray]]) -> IterationRecord:
    """The record with the largest support force magnitude of ``supports``."""
    largest = max((np.linalg.norm(f) for s in supports.values() for f in s.values()), default=0.0)
    return replace(rec, max_support_force=float(largest))


def _key(rows: ContactRows) -> bytes:
    """The contact set's identity: its rows, in any order (a renewed row is another row)."""
    if not len(rows):
        return b""
    normals = np.ascontiguousarray(rows.normal, dtype=np.float64).view(np.int64)
    k = np.column_stack([rows.keys, rows.m_nodes, normals])
    return k[np.lexsort(k.T[::-1])].tobytes()


def solve_frame(
    bodies: Sequence[ElasticBody],
    pairs: Sequence[ContactPair],
    planes: Sequence[Plane] = (),
    settings: ContactSettings | None = None,
    *,
    dirichlet: str | None = None,
    callback: Callable[[IterationRecord], None] | None = None,
) -> FrameResult:
    """Resolve the contacts of one frame.

    Parameters
    ----------
    bodies : sequence of ElasticBody
        The deformable bodies (the first is the one whose total contact force the
        history records: the ball), each at its frame's reference position.
    pairs : sequence of ContactPair
        Which slave nodes touch which master (both directions between two bodies: two
        pairs).
    planes : sequence of Plane
        The rigid planes the pairs refer to, moved to the frame's position.
    settings : ContactSettings, optional
        Algorithm and tolerances.
    dirichlet : str, optional
        Seed loop: the body solved with its contacts prescribed (default the first).
    callback : callable, optional
        Called with each iteration's record as it is made (progress display).

    Returns
    -------
    FrameResult
        Never raises on non-convergence: ``converged`` is False and ``stop_reason`` says
        why, with the last state kept.

    Raises
    ------
    ContactError
        Bad settings, or a free body that nothing holds.
    """
    settings = settings or ContactSettings()
    with fem.sparse_threads():  # the cores are PARDISO's: no spinning OpenBLAS workers
        frame = _Frame(bodies, planes, pairs, settings)
        frame.callback = callback
        frame.mark_zones()
        if settings.algorithm == "seed":
            return _seed(frame, dirichlet or frame.bodies[0].name)
        return _contact_space(frame)


def _contact_space(frame: _Frame) -> FrameResult:
    st = frame.settings
    space = ContactSpace(frame.bodies)
    u = {b.name: np.zeros((b.mesh.n_points, 3)) for b in frame.bodies}
    rows, _, _ = frame.new_rows(ContactRows(), u, touching=True, near=NEAR)
    history: list[IterationRecord] = []
    seen: set[bytes] = set()
    stop, converged = "iteration limit", False
    prev = np.zeros(sum(b.mesh.n_dofs for b in frame.bodies))
    solved, lam, states = rows, np.zeros(0), {}
    start: NDArray[np.float64] | None = None
    slides = 0
    slid: tuple[str, dict[str, NDArray[np.float64]]] | None = None
    last_u = u
    last_moves: dict[str, NDArray[np.float64]] = {}
    for it in range(1, st.max_iterations + 1):
        key = _key(rows)
        if key in seen:
            stop = "cycling"
            break
        seen.add(key)
        t = time.perf_counter()
        e = frame.matrices(rows)
        tol = LCP_TOLERANCE * frame.row_tol(rows)
        res, states = space.solve_unilateral(e, rows.g0, tol, start)
        lam = res.lam
        frame.timings["contact solve"] += time.perf_counter() - t
        solved = rows
        closed = lam > 0
        n_closed = int(closed.sum())
        was = start > 0 if start is not None else np.zeros(len(rows), dtype=bool)
        opened = int((was & ~closed).sum())
        u = {name: s.u.reshape(-1, 3) for name, s in states.items()}
        flat = np.concatenate([states[b.name].u for b in frame.bodies])
        change = float(np.abs(flat - prev).max())
        prev = flat
        moves = frame.slides(states)
        jump = max(
            (float(np.linalg.norm(m - last_moves.get(n, 0.0))) for n, m in moves.items()),
            default=0.0,
        )
        before = (last_u, jump) if jump > JUMP * frame.margin else None
        last_u, last_moves = u, moves
        grown, added, depth = frame.new_rows(rows, u, False, idle=~closed, before=before)
        if frame.broken:
            slides += 1
            slid = slid or (frame.slipping(moves, frame.broken), moves)
            if not added or slides > SLIDES:
                # nothing the body slid into holds it (or it keeps sliding): it slips out
                rec = _record(it, rows, 0, 0, change, depth, e, lam, frame, 1.0, 0.0, n_closed)
                frame.record(history, rec)
                stop = slid[0]
                break
            # it slid into something (a wall, another finger) that may hold it: the rows
            # it left are dropped, those it now penetrates are solved with the others
            log.debug("contact space: %d contacts left their facets", frame.broken)
            grown = frame.without_broken(grown)
        supports = frame.supports(states)
        rec = _record(it, rows, added, opened, change, depth, e, lam, frame, 1.0, 0.0, n_closed)
        frame.record(history, _with_support(rec, supports))
        log.debug(
            "contact space: iteration %d, %d rows (%d closed, %d opened), +%d, %d LCP steps",
            it,
            len(rows),
            n_closed,
            opened,
            added,
            res.steps,
        )
        if not res.solved:
            stop = f"the contact forces did not settle in {res.steps} steps"
            break
        if not added:
            converged, stop = True, "converged"
            if slid is not None and not frame.holds(e, lam, slid[1]):
                converged, stop = False, slid[0]
            elif out := frame.pushed_out(e, lam, moves):
                converged, stop = False, out
            break
        start = _carried(rows, lam, grown)
        rows = grown
    keep = lam > 0
    return frame.result(
        converged=converged,
        stop=stop,
        history=history,
        rows=solved.select(keep),
        lam=lam[keep],
        states=states,
    )


def _carried(
    rows: ContactRows, lam: NDArray[np.float64], grown: ContactRows
) -> NDArray[np.float64]:
    """The forces of ``rows`` carried over to ``grown``, by contact.

    A renewed row keeps its node's (largest) force; a new one starts at zero.
    """
    out = np.zeros(len(grown))
    if not len(rows) or not len(grown):
        return out
    n = int(max(rows.node.max(), grown.node.max())) + 1
    code = rows.pair * n + rows.node
    order = np.lexsort((-lam, code))  # the largest force of a node's rows first
    uniq, first = np.unique(code[order], return_index=True)
    best = lam[order][first]
    new = grown.pair * n + grown.node
    pos = np.searchsorted(uniq, new)
    pos = np.minimum(pos, uniq.size - 1)
    hit = uniq[pos] == new
    out[hit] = best[pos[hit]]
    return out


def _seed(frame: _Frame, dirichlet: str) -> FrameResult:
    st = frame.settings
    names = [b.name for b in frame.bodies]
    if dirichlet not in names:
        raise ContactError(f"the seed loop's Dirichlet body {dirichlet!r} is not in {names}")
    ball = frame.bodies[names.index(dirichlet)]
    others = [b for b in frame.bodies if b is not ball]
    for p in frame.pairs:
        if p.slave is not ball and p.master is not ball:
            raise ContactError(
                f"the seed loop resolves contacts with {dirichlet!r} only; pair {p.name} "
                "does not involve it (use the contact-space algorithm)"
            )
    space = ContactSpace(frame.bodies)
    states = {
        b.name: BodyState(np.zeros(b.mesh.n_dofs), np.zeros(b.mesh.n_dofs), np.zeros(0))
        for b in frame.bodies
    }
    u = {b.name: np.zeros((b.mesh.n_points, 3)) for b in frame.bodies}
    # step 2 (first time): nodes penetrating or touching in the posed position
    rows, _, _ = frame.new_rows(ContactRows(), u, touching=True)
    history: list[IterationRecord] = []
    stop, converged = "iteration limit", False
    omega = 1.0 if st.relaxation == "none" else st.relaxation_factor
    residual_prev: NDArray | None = None
    lam = np.zeros(0)
    solved = rows
    for it in range(1, st.max_iterations + 1):
        t = time.perf_counter()
        e = frame.matrices(rows)
        # step 3: the ball with its contact rows prescribed against the others' positions
        g = rows.g0.copy()
        for b in others:
            if b.name in e:
                g += e[b.name] @ states[b.name].u
        eb = e.get(ball.name)
        try:
            if eb is None or not len(rows):
                sol = ball.solver.solve(ball.loads)
                lam = np.zeros(0)
            else:
                sol = ball.solver.solve(ball.loads, extra=eb, extra_values=-g)
                lam = sol.extra_reactions
        except fem.LoadError as exc:
            raise ContactError(f"nothing holds {ball.name}: {exc}") from None
        except fem.SolverError as exc:
            # rows from both directions prescribe the ball twice where the surfaces meet
            # node to node: its own compliance on them is singular (the sum of both
            # bodies', which the contact-space solve uses, is not)
            stop = f"singular contact rows on {ball.name}: {exc}"
            if lam.size != len(solved):  # nothing solved yet: report no contact
                solved, lam = ContactRows(), np.zeros(0)
            break
        frame.timings["contact solve"] += time.perf_counter() - t
        t = time.perf_counter()
        new_states = {ball.name: BodyState(sol.u, sol.reactions, sol.rigid)}
        # steps 4 and 5: the reactions, reversed, dispatched onto the others; solve them
        residuals = []
        for b in others:
            eo = e.get(b.name)
            forces = eo.T @ lam if eo is not None and lam.size else np.zeros(b.mesh.n_dofs)
            answer = space.state(b, forces, np.zeros(6) if b.solver.free_body else np.zeros(0))
            residuals.append(answer.u - states[b.name].u)
            new_states[b.name] = answer
        if others:
            r = np.concatenate(residuals)
            if st.relaxation == "aitken" and residual_prev is not None:
                dr = r - residual_prev
                denom = float(dr @ dr)
                if denom > 0:
                    omega = float(np.clip(-omega * (residual_prev @ dr) / denom, 0.01, 1.0))
            residual_prev = r
            for b, res in zip(others, residuals, strict=True):
                old = states[b.name]
                full = new_states[b.name]
                uu = old.u + omega * res
                reac = old.reactions + omega * (full.reactions - old.reactions)
                new_states[b.name] = BodyState(uu, reac, full.rigid)
        frame.timings["bodies"] += time.perf_counter() - t
        flat_new = np.concatenate([new_states[b.name].u for b in frame.bodies])
        flat_old = np.concatenate([states[b.name].u for b in frame.bodies])
        change = float(np.abs(flat_new - flat_old).max())
        size = max(float(np.abs(flat_new).max()), 1e-300)
        states = new_states
        solved = rows
        if not np.isfinite(size) or size > frame.extent:
            # a linear solution moving a node further than the scene is wide: the
            # Dirichlet-Neumann iteration diverges (the ball is the stiffer side)
            stop = "diverged"
            frame.record(
                history, _record(it, rows, 0, 0, change, np.nan, e, lam, frame, omega, 0.0)
            )
            break
        u = {name: s.u.reshape(-1, 3) for name, s in states.items()}
        scale = frame.force_scale(lam)
        pulling = lam < -st.force_tolerance * scale
        grown, added, depth = frame.new_rows(rows, u, False, pulling)
        supports = frame.supports(states)
        over = frame.over_limit(supports)
        rec = _record(it, rows, added, int(pulling.sum()), change, depth, e, lam, frame, omega)
        frame.record(history, _with_support(rec, supports))
        log.debug("seed: iteration %d, %d contacts, change %.3g", it, len(rows), change)
        if over:
            stop = _limit_reason(over)
            break
        if it > 1 and change <= st.tolerance * size and not added and not pulling.any():
            converged, stop = True, "converged"
            break
        rows = grown
    return frame.result(
        converged=converged,
        stop=stop,
        history=history,
        rows=solved,
        lam=lam,
        states=states,
    )
