"""Stick anchors: where each frictional contact stuck, the only history friction carries.

Quasi-static Coulomb friction acts on a frame's slip increment: the slave node's motion
(a weighted row's weighted point's) relative to the master's material point it stuck to
at the end of the previous frame (a facet and barycentric weights, or a point of a
plane, which moves with the plane).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from .pairs import displaced_surface
from .rows import ContactRows

__all__ = ["Anchors", "end_anchors", "master_points", "own_of"]


@dataclass(frozen=True)
class Anchors:
    """The anchors of the contacts closed at the end of a frame.

    Attributes
    ----------
    pair : ndarray of str, shape (k,)
        Each anchor's pair name (``"slave/master"``): pairs are rebuilt each frame.
    node : ndarray of int, shape (k,)
        Its slave node.
    facet : ndarray of int, shape (k, 3)
        The master facet's nodes (-1 against a plane).
    weights : ndarray, shape (k, 3)
        Barycentric weights on the facet (0 against a plane).
    point : ndarray, shape (k, 3)
        Against a plane: the anchor point less the plane's motion (m), so that it moves
        with the plane; NaN against a body.
    displacement : dict of str to ndarray
        Each body's displacements ``(N, 3)`` at the end of the frame: where the next
        frame's first contact search looks, so that a contact met in it is anchored
        where its node was at the step's start, not at rest.
    motion : dict of str to ndarray
        Each plane's motion ``(3,)`` at the end of the frame: a contact the next frame
        meets against a plane is anchored at the plane's material point under the node
        at the step's start.
    reference : dict of str to ndarray
        Each body's reference points ``(N, 3)`` that ``displacement`` is measured from.
    """

    pair: NDArray = field(default_factory=lambda: np.zeros(0, dtype=object))
    node: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))
    facet: NDArray[np.int64] = field(default_factory=lambda: np.zeros((0, 3), np.int64))
    weights: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))
    point: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))
    displacement: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    motion: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    reference: dict[str, NDArray[np.float64]] = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.node.size)

    def displaced(self, bodies: Sequence) -> dict[str, NDArray[np.float64]]:
        """Each body's displacement at the end, from the reference it has now.

        Where its nodes were: ``x_then + u - x_now`` for a body placed anew since (a free
        ball whose roll was taken into its placement, a ball that follows a joint); a body
        whose mesh changed (another number of nodes) is left out.
        """
        out = {}
        for b in bodies:
            u = self.displacement.get(b.name)
            if u is None or u.shape != (b.mesh.n_points, 3):
                continue
            then = self.reference.get(b.name)
            out[b.name] = u if then is None else then + u - b.mesh.points
        return out

    def starting(
        self,
        displacement: Mapping[str, NDArray[np.float64]],
        reference: Mapping[str, NDArray[np.float64]],
    ) -> Anchors:
        """These anchors, with the bodies they do not place yet placed where they start.

        ``displacement`` ``(N, 3)`` from ``reference`` ``(N, 3)`` per body: where a
        contact first met in the frame is measured from (a finite body's placement at the
        frame's start, in every Newton step alike). Bodies placed here keep their own.
        """
        new = [n for n in displacement if n not in self.displacement]
        u = {n: np.asarray(displacement[n], float).reshape(-1, 3) for n in new}
        x = {n: np.asarray(reference[n], float).reshape(-1, 3) for n in new}
        return replace(
            self, displacement={**self.displacement, **u}, reference={**self.reference, **x}
        )

    def keeping(self, met: Anchors) -> Anchors:
        """The anchors of ``met`` (every contact a frame measured its slip from), placed as these.

        A Newton step's frame anchors a contact it meets first where it meets it; the next
        step starts from the same anchors and the same starting placements, so that every
        step solves the frame's friction, not a new increment from where the last ended.
        """
        return replace(
            self, pair=met.pair, node=met.node, facet=met.facet, weights=met.weights,
            point=met.point,
        )  # fmt: skip


def master_points(
    pair, x: NDArray[np.float64], u: Mapping[str, NDArray]
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """The master's material points under points ``x`` ``(k, 3)`` at displacements ``u``.

    The closest points of the master's displaced contact surface, as facets ``(k, 3)``
    and barycentric weights ``(k, 3)``: a weighted row's stick anchor, the master's point
    under the row's weighted slave point.
    """
    master = pair.master
    surface, tri = displaced_surface(master, master.mesh.points + np.asarray(u[master.name]))
    c = surface.closest(x)
    return tri[c.face].astype(np.int64), c.bary


def own_of(closed: NDArray[np.int64], own: dict[int, tuple]) -> dict[int, tuple]:
    """``own`` renumbered from row indices to positions among ``closed``."""
    where = {int(i): j for j, i in enumerate(closed)}
    return {where[i]: a for i, a in own.items()}


def end_anchors(
    frame, rows: ContactRows, u: dict[str, NDArray], own: dict[int, tuple] | None = None
) -> Anchors:
    """Anchors of contacts ``rows`` where their slave nodes are at displacements ``u``.

    A plane's is the node's projection on it; a body's the closest point of its deformed
    surface (the facet and weights the measure finds). ``own`` maps a row to an anchor it
    keeps instead (a contact that stuck).
    """
    own = own or {}
    pairs = frame.pairs
    k = len(rows)
    facets = np.full((k, 3), -1, np.int64)
    weights = np.zeros((k, 3))
    points = np.full((k, 3), np.nan)
    placed = rows.slave_points(pairs, u)
    for i in np.unique(rows.pair):
        pair = pairs[int(i)]
        sel = np.flatnonzero(rows.pair == i)
        nodes = rows.node[sel]
        if pair.rigid:
            points[sel] = pair.master.project(placed[sel]) - pair.master.motion
        elif pair.mortar:
            facets[sel], weights[sel] = master_points(pair, placed[sel], u)
        else:
            found = frame.measure_pair(int(i), u, frame.margin)
            at = {int(n): j for j, n in enumerate(found.nodes)}
            for r, n in zip(sel, nodes):
                hit = at.get(int(n))
                if hit is not None:
                    facets[r] = found.facet[hit]
                    weights[r] = found.weights[hit]
                elif rows.m_nodes.shape[1] >= 3:
                    facets[r] = rows.m_nodes[r, :3]  # out of reach: where its row was taken
                    weights[r] = rows.m_coef[r, :3]
    for r, (facet, w, point) in own.items():
        facets[r], weights[r], points[r] = facet, w, point
    return Anchors(
        pair=np.array([pairs[int(i)].name for i in rows.pair], dtype=object),
        node=rows.node.copy(),
        facet=facets,
        weights=weights,
        point=points,
        displacement={name: np.array(v, dtype=np.float64) for name, v in u.items()},
        motion=frame.driven.positions(),
        reference={b.name: b.mesh.points.copy() for b in frame.bodies},
    )
