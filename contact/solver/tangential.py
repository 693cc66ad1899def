"""Coulomb friction in a frame: tangential rows against stick anchors, solved with the normal rows.

Each frictional contact gets two tangential rows beside its normal row, along a tangent
basis ``t1, t2`` of its normal (:func:`tangent_basis`). A tangential row is built like a
normal row (the slave node ``+t``, the master's points ``-w_k t``), with the anchor's
facet and weights in place of the closest point's and the node-to-anchor offset in place
of the gap, so that its value is the slip increment since the anchor along ``t``
(:mod:`contact.solver.anchors`). A contact found for the first time in a frame is
anchored where it is found. At the end of the frame a contact that stuck keeps its
anchor and one that slipped is anchored where it ended.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .anchors import Anchors, end_anchors, master_points, own_of
from .delassus import BodyState, ContactSpace
from .friction import STICK, FrictionResult, solve_friction
from .rows import ContactRows, pad_columns

__all__ = ["Friction", "couples", "friction_zone", "tangent_basis"]

_Key = tuple[int, int]


def couples(frame) -> list[tuple[int, int]]:
    """Pairs of pairs that meet one interface both ways: ``(i, j)``, ``i`` the finer side.

    The finer side is the one whose contact nodes have the smaller median element size.
    """
    pairs = frame.pairs
    out = []
    for i, a in enumerate(pairs):
        for j in range(i + 1, len(pairs)):
            b = pairs[j]
            if a.rigid or b.rigid or a.slave is not b.master or b.slave is not a.master:
                continue
            size = [
                float(np.median(frame.local[p.slave.name][p.candidates]))
                if p.candidates.size
                else np.inf
                for p in (a, b)
            ]
            out.append((i, j) if size[0] <= size[1] else (j, i))
    return out


def friction_zone(frame, anchors: Anchors | None) -> tuple[dict, dict]:
    """Where a frictional frame's contact zone is measured, and the nodes it must hold.

    The bodies as the last frame left them (the first search looks there), and the nodes
    of the anchors carried in (their slave nodes and their masters' facets), so that
    the tangential rows get their compliance from partial solves too. Nothing without
    friction or anchors: the zone is measured at rest, as it always is.
    """
    if anchors is None or not any(p.friction > 0 for p in frame.pairs):
        return {}, {}
    start = anchors.displaced(frame.bodies)
    extra: dict[str, list[NDArray[np.int64]]] = {}
    index = {p.name: p for p in frame.pairs}
    for name in np.unique(anchors.pair) if len(anchors) else ():
        pair = index.get(str(name))
        if pair is None or pair.friction <= 0:
            continue
        sel = anchors.pair == name
        extra.setdefault(pair.slave.name, []).append(anchors.node[sel])
        if not pair.rigid:
            facets = anchors.facet[sel]
            extra.setdefault(pair.master.name, []).append(facets[facets >= 0])
    return start, {k: np.concatenate(v) for k, v in extra.items()}


def tangent_basis(normal: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    """Unit tangents ``t1 = n x e / |n x e|`` and ``t2 = n x t1`` of unit normals ``(m, 3)``.

    ``e`` is the coordinate axis least aligned with ``n``: the same basis for the same
    normal everywhere, never degenerate.
    """
    n = np.asarray(normal, dtype=np.float64).reshape(-1, 3)
    e = np.eye(3)[np.argmin(np.abs(n), axis=1)]
    t1 = np.cross(n, e)
    t1 /= np.linalg.norm(t1, axis=1)[:, None]
    return t1, np.cross(n, t1)


class Friction:
    """The frictional contacts of a frame: their anchors, tangential rows and solve.

    Parameters
    ----------
    frame : FrameState
        The frame (its pairs give each contact's coefficient).
    anchors : Anchors, optional
        Where contacts stuck at the end of the previous frame.
    """

    def __init__(self, frame, anchors: Anchors | None = None) -> None:
        self.frame = frame
        self.given = Anchors() if anchors is None else anchors
        self.previous = {} if anchors is None else anchors.displaced(frame.bodies)
        self.motion = {} if anchors is None else anchors.motion
        self.base = np.array([float(p.friction) for p in frame.pairs])
        self.mu = self.base.copy()  # as solved: one side of each couple (see one_way)
        self.couples = couples(frame)
        self.active = bool((self.base > 0).any())
        index = {p.name: i for i, p in enumerate(frame.pairs)}
        self.anchor: dict[_Key, tuple[NDArray, NDArray, NDArray]] = {}
        if anchors is not None:
            for k in range(len(anchors)):
                i = index.get(str(anchors.pair[k]))
                if i is not None and self.base[i] > 0:
                    key = (i, int(anchors.node[k]))
                    self.anchor[key] = (anchors.facet[k], anchors.weights[k], anchors.point[k])
        self.offsets: dict[_Key, NDArray[np.float64]] = {}
        self.iterations = 0
        self.system: tuple | None = None

    # ------------------------------------------------------------------ anchors
    def start(self) -> dict[str, NDArray]:
        """Where the frame's first search looks: each body as the last frame left it.

        Bodies whose mesh changed (another number of nodes) start at rest. Without
        friction the search starts at rest, as it always has.
        """
        out = {}
        for b in self.frame.bodies:
            prev = self.previous.get(b.name) if self.active else None
            shape = (b.mesh.n_points, 3)
            same = prev is not None and prev.shape == shape
            out[b.name] = prev.copy() if same else np.zeros(shape)
        return out

    def register(self, rows: ContactRows, u: dict[str, NDArray]) -> None:
        """Anchor every frictional contact of ``rows`` met for the first time where it is now."""
        pairs = self.frame.pairs
        new = [i for i in np.flatnonzero(self.base[rows.pair] > 0)
               if (int(rows.pair[i]), int(rows.node[i])) not in self.anchor]  # fmt: skip
        xs = rows.select(np.asarray(new, np.int64)).slave_points(pairs, u)
        # a weighted row's master point under it: one query of each master's surface
        under: dict[int, tuple[NDArray, NDArray]] = {}
        for p in {int(rows.pair[i]) for i in new}:
            if pairs[p].mortar and not pairs[p].rigid:
                at = [j for j, i in enumerate(new) if rows.pair[i] == p]
                facet, w = master_points(pairs[p], xs[at], u)
                under.update({new[j]: (facet[n], w[n]) for n, j in enumerate(at)})
        for i, x in zip(new, xs, strict=True):
            key = (int(rows.pair[i]), int(rows.node[i]))
            if key in self.anchor:
                continue  # a node's second row (a concave corner): its first row's anchor
            pair = pairs[key[0]]
            if pair.rigid:
                # the plane's material point under the row's slave point, the plane where
                # the step started (where the last frame left it), the point where it is now
                plane = pair.master
                motion = self.motion.get(plane.name, plane.motion)
                point = plane.moved(motion).project(x[None])[0] - motion
                self.anchor[key] = (np.full(3, -1, np.int64), np.zeros(3), point)
            elif pair.mortar:
                self.anchor[key] = (*under[i], np.full(3, np.nan))
            else:
                self.anchor[key] = (
                    rows.m_nodes[i, :3].copy(), rows.m_coef[i, :3].copy(), np.full(3, np.nan)
                )

    def measured_from(self) -> Anchors:
        """Every anchor the frame measures slip from (carried in or met), placed as given."""
        keys = list(self.anchor)
        pairs = self.frame.pairs
        facet, weights, point = (
            np.array([self.anchor[k][j] for k in keys]).reshape(len(keys), 3) for j in range(3)
        )
        return self.given.keeping(
            Anchors(
                pair=np.array([pairs[i].name for i, _ in keys], dtype=object),
                node=np.array([n for _, n in keys], dtype=np.int64),
                facet=facet.astype(np.int64),
                weights=weights,
                point=point,
            )
        )

    def _anchor_points(self, keys: list[_Key]) -> NDArray[np.float64]:
        """Anchors' positions at the frame's reference (the master's reference points)."""
        pairs = self.frame.pairs
        out = np.empty((len(keys), 3))
        for j, key in enumerate(keys):
            facet, w, point = self.anchor[key]
            master = pairs[key[0]].master
            if pairs[key[0]].rigid:
                out[j] = point + master.motion
            else:
                out[j] = w @ master.mesh.points[facet]
        return out

    def _weighted(self, key: _Key) -> bool:
        """Whether contact ``key`` is a weighted (mortar) row against a body."""
        pair = self.frame.pairs[key[0]]
        return bool(pair.mortar and not pair.rigid)

    def _offsets(self, keys: list[_Key], rows: ContactRows) -> NDArray[np.float64]:
        """Where weighted rows' anchors sat from the masters' weighted points at the start.

        Friction acts on the weighted slip (Popp and Wall): the slave's weighted point
        against the master's, ``sum_k b_k x_k``, so that a uniform traction is spread on
        the master as the mortar spreads the pressure. A stick anchor is kept as the
        master's material point it sat on; the frame measures the slip from that point's
        offset to the master's weighted point where the frame started (``rows`` the
        contacts' rows, in the order of ``keys``).
        """
        missing = [j for j, key in enumerate(keys) if key not in self.offsets]
        if missing:
            start = self.start()
            sub = rows.select(np.asarray(missing, np.int64))
            means = sub.master_points(self.frame.pairs, start)
            for n, j in enumerate(missing):
                facet, w, _ = self.anchor[keys[j]]
                master = self.frame.pairs[keys[j][0]].master
                x = master.mesh.points[facet] + start[master.name][facet]
                self.offsets[keys[j]] = w @ x - means[n]
        return np.array([self.offsets[key] for key in keys]).reshape(-1, 3)

    # ------------------------------------------------------------------ rows
    def one_way(self, rows: ContactRows, start: NDArray[np.float64] | None) -> None:
        """Friction on one side of each interface met both ways, for the next solve.

        Both sides keep their normal rows, but tangential rows on both sides of one
        interface hold the same slip twice: the stick constraints repeat one another and
        the tangential forces are not unique. They are taken on the side with more
        contacts (rows pushing in the last solve, or rows at all before the first; the
        finer side where even), and reach the other side through the rows' facet
        weights, action and reaction.
        """
        self.mu = self.base.copy()
        if not self.couples:
            return
        carry = rows.pair[start > 0] if start is not None else rows.pair
        count = np.bincount(carry, minlength=len(self.base))
        for finer, other in self.couples:
            self.mu[finer if count[other] > count[finer] else other] = 0.0

    def rows(self, rows: ContactRows) -> tuple[ContactRows, NDArray[np.int64], NDArray]:
        """The normal rows followed by the frictional contacts' tangential rows.

        Returns
        -------
        full : ContactRows
            ``rows``, then two tangential rows per frictional contact (a node with
            several rows in a pair gets them at its first).
        tangent : ndarray of int, shape (k, 2)
            Each contact's tangential rows in ``full``, -1 where it has none.
        mu : ndarray, shape (k,)
            Each contact's coefficient (0 where it has no tangential rows).
        """
        k = len(rows)
        mu = self.mu[rows.pair] if k else np.zeros(0)
        seen: set[_Key] = set()
        fr = []
        for i in np.flatnonzero(mu > 0):
            key = (int(rows.pair[i]), int(rows.node[i]))
            if key not in seen:
                seen.add(key)
                fr.append(i)
        fr_idx = np.asarray(fr, dtype=np.int64)
        mu = np.where(np.isin(np.arange(k), fr_idx), mu, 0.0)
        tangent = np.full((k, 2), -1, np.int64)
        if not fr_idx.size:
            return rows, tangent, mu
        keys = [(int(rows.pair[i]), int(rows.node[i])) for i in fr_idx]
        kf = fr_idx.size
        tangent[fr_idx] = k + np.arange(2 * kf).reshape(kf, 2)
        t1, t2 = tangent_basis(rows.normal[fr_idx])
        dirs = np.stack([t1, t2], axis=1).reshape(-1, 3)
        picked = rows.select(fr_idx)
        offset = picked.slave_points(self.frame.pairs) - self._anchor_points(keys)
        facets = np.array([self.anchor[key][0] for key in keys], dtype=np.int64).reshape(-1, 3)
        weights = np.array([self.anchor[key][1] for key in keys]).reshape(-1, 3)
        weighted = np.array([self._weighted(key) for key in keys], dtype=bool)
        if weighted.any():
            # weighted rows between bodies: the master's weighted point, offset by where
            # the anchor sat from it when the frame started
            w = np.flatnonzero(weighted)
            sub = picked.select(weighted)
            offset[w] = sub.slave_points(self.frame.pairs) - sub.master_points(self.frame.pairs)
            offset[w] -= self._offsets([keys[j] for j in w], sub)
            width = max(3, sub.m_nodes.shape[1])
            facets, weights = pad_columns(facets, width, -1), pad_columns(weights, width, 0.0)
            facets[w] = pad_columns(sub.m_nodes, width, -1)
            weights[w] = pad_columns(sub.m_coef, width, 0.0)
        g0 = np.einsum("mj,mkj->mk", offset, np.stack([t1, t2], axis=1)).ravel()
        tangential = ContactRows(
            np.repeat(rows.pair[fr_idx], 2),
            np.repeat(rows.node[fr_idx], 2),
            dirs,
            g0,
            np.repeat(rows.s_nodes[fr_idx], 2, axis=0),
            np.repeat(rows.s_coef[fr_idx], 2, axis=0),
            np.repeat(facets, 2, axis=0),
            np.repeat(weights, 2, axis=0),
        )
        return rows.joined(tangential), tangent, mu

    # ------------------------------------------------------------------ solve
    def solve(
        self,
        space: ContactSpace,
        rows: ContactRows,
        start: NDArray[np.float64] | None,
        carried: dict[_Key, NDArray[np.float64]] | None = None,
    ) -> tuple[FrictionResult, dict[str, BodyState], dict, ContactRows, NDArray[np.int64]]:
        """Forces of the normal and tangential rows of ``rows`` and every body's state.

        ``start`` holds the normal rows' starting forces, ``carried`` each contact's
        tangential force vector from the last solve. Where the side of an interface met
        both ways that took the tangential rows ends with fewer contacts than the other,
        the solve is made again with them on the other side.
        """
        self.one_way(rows, start)
        for attempt in range(2):
            full, tangent, mu = self.rows(rows)
            e = self.frame.matrices(full)
            sys_ = space.system(e, full.g0)
            lam0 = self._start(rows, start, carried, tangent, len(full))
            res = solve_friction(
                sys_.w, sys_.g, sys_.rhs, sys_.c, mu=mu, tangent=tangent, start=lam0,
                load_scale=sys_.load_scale, h=sys_.h, aux=sys_.aux, prox=sys_.prox,
            )
            self.iterations += res.iterations
            chosen = self.mu.copy()
            self.one_way(rows, res.lam[: len(rows)])  # the side its contacts now favour
            if attempt or np.array_equal(self.mu, chosen):
                self.mu = chosen
                break
        self.system = (sys_, mu, tangent)
        # the rows that bind: every normal row, a closed contact's tangential rows (only a
        # stuck one's where the solve found no balance: a slide that nothing settled is
        # no place, and the body is left where its stuck and pushing rows hold it)
        bound = np.zeros(len(full), dtype=bool)
        bound[: len(rows)] = True
        grip = ((res.status > 0) if res.solved else (res.status == STICK)) & (tangent[:, 0] >= 0)
        bound[tangent[grip].ravel()] = True
        states = space.states(e, res.lam, res.a, bound, sys_.g, sys_.mode_rows)
        return res, states, e, full, tangent

    def _start(
        self,
        rows: ContactRows,
        start: NDArray[np.float64] | None,
        carried: dict[_Key, NDArray[np.float64]] | None,
        tangent: NDArray[np.int64],
        size: int,
    ) -> NDArray[np.float64] | None:
        """The forces a solve starts from.

        The normal rows' ``start``, and the tangential forces ``carried`` by contact,
        projected on the new tangent basis.
        """
        if start is None:
            return None
        lam0 = np.zeros(size)
        lam0[: len(rows)] = start
        if carried:
            has = np.flatnonzero(tangent[:, 0] >= 0)
            t1, t2 = tangent_basis(rows.normal[has])
            for j, i in enumerate(has):
                f = carried.get((int(rows.pair[i]), int(rows.node[i])))
                if f is not None:
                    lam0[tangent[i]] = (f @ t1[j], f @ t2[j])
        return lam0

    def tangential_forces(
        self, rows: ContactRows, lam: NDArray[np.float64], tangent: NDArray[np.int64]
    ) -> NDArray[np.float64]:
        """Each contact's tangential force vector on its slave node ``(k, 3)`` (N)."""
        out = np.zeros((len(rows), 3))
        has = np.flatnonzero(tangent[:, 0] >= 0)
        if has.size:
            t1, t2 = tangent_basis(rows.normal[has])
            out[has] = lam[tangent[has, 0], None] * t1 + lam[tangent[has, 1], None] * t2
        return out

    def carry(
        self, rows: ContactRows, lam: NDArray[np.float64], tangent: NDArray[np.int64]
    ) -> dict[_Key, NDArray[np.float64]]:
        """Each contact's tangential force vector, by its key, to start the next solve."""
        forces = self.tangential_forces(rows, lam, tangent)
        has = np.flatnonzero(tangent[:, 0] >= 0)
        return {(int(rows.pair[i]), int(rows.node[i])): forces[i] for i in has}

    def anchors_after(
        self,
        rows: ContactRows,
        status: NDArray[np.int64],
        tangent: NDArray[np.int64],
        u: dict[str, NDArray],
    ) -> Anchors:
        """The anchors to carry: a stuck contact keeps its own, any other moves to where it is.

        Only closed contacts are kept (``status`` 1 or 2); frictionless ones are anchored
        too, for a later frame whose friction is switched on.
        """
        closed = np.flatnonzero(status > 0)
        own = {}
        for i in closed:
            key = (int(rows.pair[i]), int(rows.node[i]))
            if status[i] == 1 and tangent[i, 0] >= 0 and key in self.anchor:
                own[int(i)] = self.anchor[key]
        return end_anchors(self.frame, rows.select(status > 0), u, own_of(closed, own))
