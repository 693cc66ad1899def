"""The contact set of a frame: which rows to add, renew and release.

A node in contact stays in contact (contact memory) until its force pulls. An update
measures the deformed bodies (:mod:`contact.solver.pairs`) and adds a row (step 4's
:class:`contact.solver.rows.ContactRows`) for each node found inside its master; a row
whose node has slid off its facet, or whose soft master has turned, is linearised again
(renewed); rows whose node has left its master are dropped. The first set of a frame
takes the nodes that touch, or the overlap's inner half (:func:`first_set`).
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from . import zone
from .driven import DrivenPlanes
from .pairs import ContactPair, Penetrations
from .rows import ContactRows, MortarCandidates

__all__ = [
    "CORNER_COS",
    "CORNER_ROWS",
    "NEAR",
    "RELINEARISE",
    "ContactSet",
    "FrameGeometry",
    "among",
    "first_set",
    "set_key",
]

#: A node in contact found inside another facet of its master, whose normal differs from
#: its rows' by more than arccos of this (about 0.8 degree), is in a concave corner or
#: crease: it keeps its row and gets one for that facet too, up to ``CORNER_ROWS`` rows in
#: all. Nearly flat creases count: on one row at a time, a node there would move from
#: facet to facet; two rows that nearly repeat one another are safe for the unilateral
#: solve (it opens the one not needed).
CORNER_COS = 0.9999
CORNER_ROWS = 3
#: Times a contact row may be linearised again on the same facet in one frame (a soft
#: master's facets turn under the load; a bound in case the turning does not settle).
RELINEARISE = 8
#: Where a side of a pair is placed by the contacts (a free body, a force-driven plane)
#: or the pair has friction (:attr:`ContactPair.wide_start`), the first contact set of
#: contact space holds every node inside its master or outside within this many of its
#: element sizes (or the pair's deepest overlap, see :meth:`ContactSet.near_band`), as
#: candidates: a free body's first solve would otherwise slide it through what it nearly
#: touches (a bowl's walls that touch the ball between nodes, a palm half a millimetre
#: above a ball the fingers squeeze). Otherwise it holds the nodes deeper than half the
#: deepest overlap (:func:`first_set`), about Hertz's patch, and a ring of
#: :data:`contact.solver.zone.HELD_RING` elements: about half the overlap's area.
NEAR = 0.5
#: Stride of a row's (pair, node) key: more nodes than any body has.
_KEY_STRIDE = 1 << 40


class FrameGeometry(Protocol):
    """What the contact set needs of its frame: the pairs and their measurement."""

    pairs: list[ContactPair]
    mortar: dict[int, MortarCandidates]
    driven: DrivenPlanes
    local: dict[str, NDArray[np.float64]]
    margin: float
    timings: dict[str, float]

    def measure_pair(self, i: int, u: Mapping[str, NDArray], margin: float) -> Penetrations:
        """Pair ``i``'s candidates within ``margin`` at displacements ``u``."""
        ...

    def tol(self, pair: ContactPair, nodes: NDArray[np.int64]) -> NDArray[np.float64]:
        """Penetration tolerance of slave nodes (m)."""
        ...


class ContactSet:
    """The row bookkeeping of one frame: add, renew and release contact rows.

    Parameters
    ----------
    frame : FrameGeometry
        The frame whose pairs the rows belong to (:class:`contact.solver.frame.FrameState`).

    Attributes
    ----------
    reverse : list of int
        For each pair, the pair in the other direction between the same two bodies
        (-1 if none).
    broken : int
        Contacts the last :meth:`new_rows` found off their masters.
    broken_keys : ndarray of int
        Their (pair, node) keys.
    renewed, relinearised : dict of int to dict of int to int
        Times each node of each pair had its row renewed on another facet, or linearised
        again on the same one, in this frame.
    """

    def __init__(self, frame: FrameGeometry) -> None:
        self.frame = frame
        pairs = frame.pairs
        self.reverse = [
            next(
                (
                    j
                    for j, q in enumerate(pairs)
                    if not p.rigid and q.slave is p.master and q.master is p.slave
                ),
                -1,
            )
            for p in pairs
        ]
        self.broken = 0
        self.broken_keys = np.zeros(0, dtype=np.int64)
        self.renewed: dict[int, dict[int, int]] = {}
        self.relinearised: dict[int, dict[int, int]] = {}

    def near_band(
        self, pair: ContactPair, nodes: NDArray[np.int64], gap: NDArray[np.float64], near: float
    ) -> NDArray[np.float64]:
        """How far outside a node joins the first set, open (m, per node).

        ``near`` of its element size, or the pair's deepest overlap where that is more
        (up to one element). Two bodies pressed together by an overlap ``d`` close the
        nodes whose gap is less than about ``d`` (a Hertz patch); taking them all keeps
        the first solve's patch, and the updates it takes, the same on every mesh.
        Against a rigid master (a plane) only the slave gives way, away from it: the
        nodes a press closes are inside it already, and the band is ``near`` alone.
        """
        local = self.frame.local[pair.slave.name][nodes]
        if pair.rigid:
            return near * local
        deepest = float(np.max(-gap, initial=0.0))
        return np.minimum(np.maximum(near * local, deepest), local)

    def new_rows(
        self,
        rows: ContactRows,
        u: Mapping[str, NDArray],
        touching: bool,
        released: NDArray[np.bool_] | None = None,
        idle: NDArray[np.bool_] | None = None,
        near: float = 0.0,
        before: tuple[Mapping[str, NDArray], float] | None = None,
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
        fr = self.frame
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
        for i, pair in enumerate(fr.pairs):
            if i in fr.mortar:
                rows, n, d = self._mortar_rows(i, rows, dropped, u, touching, near)
                changed += n
                depth = max(depth, d)
                continue
            p = fr.measure_pair(i, u, fr.margin)
            if not p.nodes.size:
                continue
            tol = fr.tol(pair, p.nodes)
            mine = rows.pair == i
            in_rows = rows.node[mine]
            n_slave = pair.slave.mesh.n_points
            active = among(p.nodes, in_rows, n_slave)
            # a contact whose node has moved away from its master by half an element (or
            # out of reach) no longer has a valid linearised row: the body slid off it
            far = active & (p.gap > 0.5 * fr.local[pair.slave.name][p.nodes])
            lost = np.unique(in_rows[~among(in_rows, p.nodes, n_slave)])
            gone = np.concatenate([p.nodes[far], lost])
            self.broken += gone.size
            broken.append(gone + i * _KEY_STRIDE)
            fresh = ~active & ~among(p.nodes, dropped.node[dropped.pair == i], n_slave)
            depth = max(depth, float(np.max(-p.gap, initial=0.0)))
            hit = fresh & (first_set(p.gap, tol) if touching else (p.gap < -tol))
            if touching and near > 0.0 and pair.wide_start:
                # every node inside or near: the unilateral solve closes what must push
                hit |= fresh & (p.gap < self.near_band(pair, p.nodes, p.gap, near))
            elif touching and near > 0.0:
                # Hertz's patch and a ring, as the zone marks them: the patch ends about
                # there, and the ring takes in what the discrete one has beyond it
                local = fr.local[pair.slave.name][p.nodes]
                x = pair.slave.mesh.points
                hit = fresh & zone.slave_zone(x, p.nodes, p.gap, hit, local, zone.HELD_RING)
            j = self.reverse[i]
            if j >= 0 and hit.any():
                # node on node: a slave node whose closest point is a master vertex that
                # is itself in contact the other way round would repeat that contact's row
                vertex = p.weights.max(axis=1) >= 1.0 - 1e-9
                tip = p.facet[np.arange(p.nodes.size), p.weights.argmax(axis=1)]
                hit &= ~(vertex & among(tip, rows.node[rows.pair == j], pair.master.mesh.n_points))
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
                # Nodes left inside make the frame not converged (FrameState.result).
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
                rows = rows.extended(fr.pairs, i, q)
                changed += q.nodes.size
        self.broken_keys = np.concatenate(broken) if broken else np.zeros(0, dtype=np.int64)
        fr.timings["geometry"] += time.perf_counter() - t
        return rows, changed, depth

    def without_broken(self, rows: ContactRows) -> ContactRows:
        """``rows`` less those whose node the last :meth:`new_rows` found off its master.

        Their linearisation no longer holds: the node left its facet (a free body slid
        along the contacts that held it). A node that penetrates something at its new
        place has its new row already; one that comes back gets a row when measured.
        """
        if not self.broken_keys.size or not len(rows):
            return rows
        return rows.select(~np.isin(rows.pair * _KEY_STRIDE + rows.node, self.broken_keys))

    def _outside_before(
        self, i: int, p: Penetrations, before: tuple[Mapping[str, NDArray], float]
    ) -> Penetrations:
        """``p`` with each node measured at ``before`` instead, where it was outside."""
        u, jump = before
        prior = self.frame.measure_pair(i, u, jump + self.frame.margin)
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

    def _left(
        self, rows: ContactRows, idle: NDArray[np.bool_], u: Mapping[str, NDArray]
    ) -> NDArray[np.bool_]:
        """Idle rows whose node has moved half an element off its master, or out of reach."""
        fr = self.frame
        out = np.zeros(len(rows), dtype=bool)
        for i, pair in enumerate(fr.pairs):
            mine = idle & (rows.pair == i)
            if i in fr.mortar or not mine.any():
                continue
            p = fr.measure_pair(i, u, fr.margin)
            n_slave = pair.slave.mesh.n_points
            near = p.nodes[p.gap <= 0.5 * fr.local[pair.slave.name][p.nodes]]
            # a node with a closed row too keeps its idle rows (a corner's other facet)
            held = rows.node[(rows.pair == i) & ~idle]
            node = rows.node[mine]
            keep = among(node, near, n_slave) | among(node, held, n_slave)
            out[np.flatnonzero(mine)[~keep]] = True
        return out

    def _mortar_rows(
        self,
        i: int,
        rows: ContactRows,
        dropped: ContactRows,
        u: Mapping[str, NDArray],
        touching: bool,
        near: float = 0.0,
    ) -> tuple[ContactRows, int, float]:
        """New mortar rows of pair ``i``: weighted gaps closed or below the tolerance.

        With ``touching`` and ``near`` on a pair placed by its contacts, the first set
        also holds the rows open by less than :meth:`near_band`: a weighted gap closes
        only once the press passes the mean gap over the node's faces, so a ball that
        rests on a table at one node has every row open, and the unilateral solve must
        see them to let it settle onto them.
        """
        pair, cand = self.frame.pairs[i], self.frame.mortar[i]
        g = self._weighted_gaps(i, u)
        nodes = cand.rows.node
        tol = self.frame.tol(pair, nodes)
        fresh = ~np.isin(nodes, rows.node[rows.pair == i]) & ~np.isin(
            nodes, dropped.node[dropped.pair == i]
        )
        hit = fresh & (first_set(g, tol) if touching else (g < -tol))
        if touching and near > 0.0 and pair.wide_start:
            hit |= fresh & (g < self.near_band(pair, nodes, g, near))
        depth = float(np.max(-g, initial=0.0))
        if hit.any():
            rows = rows.joined(cand.rows.select(hit))
        return rows, int(hit.sum()), depth

    def _weighted_gaps(self, i: int, u: Mapping[str, NDArray]) -> NDArray[np.float64]:
        """Every candidate row's weighted gap of mortar pair ``i`` at displacements ``u``."""
        pair, cand = self.frame.pairs[i], self.frame.mortar[i]
        u_m = np.zeros(0) if pair.rigid else u[pair.master.name]  # type: ignore[union-attr]
        g = cand.gaps(u[pair.slave.name], u_m)
        if pair.rigid and pair.master.force is not None:  # a force-driven plane, where it is
            g = g - float(self.frame.driven.shift[pair.master.name][0] @ pair.master.normal)
        return g

    def mortar_zone(self, i: int, u: Mapping[str, NDArray]) -> list[tuple[str, NDArray, NDArray]]:
        """The contact zone of mortar pair ``i``: (body, nodes, nearness) of each side.

        As node rows mark theirs (:meth:`contact.solver.frame.FrameState.mark_zones`): the
        rows the first set takes (inside, or within the near band where the pair starts
        wide) and a ring of slave nodes around them (:func:`zone.slave_zone`), each row
        marking the nodes its weights touch on both sides, as near as its weighted gap.
        """
        pair, cand = self.frame.pairs[i], self.frame.mortar[i]
        nodes = cand.rows.node
        if not nodes.size:
            return []
        g = self._weighted_gaps(i, u)
        first = first_set(g, self.frame.tol(pair, nodes))
        local = self.frame.local[pair.slave.name][nodes]
        ring = None if pair.wide_start else zone.HELD_RING
        sel = zone.slave_zone(pair.slave.mesh.points, nodes, g, first, local, ring)
        if pair.wide_start:
            sel |= g < self.near_band(pair, nodes, g, NEAR)
        sides = ((pair.slave.name, cand.rows.s_nodes), (pair.master.name, cand.rows.m_nodes))
        out = []
        for name, support in sides[: 1 if pair.rigid else 2]:  # a plane has no zone
            touched = support[sel]
            ok = touched >= 0
            out.append((name, touched[ok], np.broadcast_to(g[sel][:, None], touched.shape)[ok]))
        return out


def first_set(gap: NDArray[np.float64], tol: NDArray[np.float64]) -> NDArray[np.bool_]:
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


def among(x: NDArray[np.int64], y: NDArray[np.int64], n: int) -> NDArray[np.bool_]:
    """``np.isin(x, y)`` for node numbers below ``n``, through a mask.

    No sorting: a frame asks this many times of a few hundred nodes, where a mask over the
    body's nodes is far cheaper than ``np.isin``.
    """
    mask = np.zeros(n, dtype=bool)
    mask[y] = True
    return mask[x]


def set_key(rows: ContactRows) -> bytes:
    """The contact set's identity: its rows, in any order (a renewed row is another row)."""
    if not len(rows):
        return b""
    normals = np.ascontiguousarray(rows.normal, dtype=np.float64).view(np.int64)
    k = np.column_stack([rows.keys, rows.m_nodes, normals])
    return k[np.lexsort(k.T[::-1])].tobytes()
