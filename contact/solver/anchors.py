"""Stick anchors: where each frictional contact stuck, the only history friction carries.

Quasi-static Coulomb friction acts on a frame's slip increment: the slave node's motion
relative to the master's material point it stuck to at the end of the previous frame (a
facet and barycentric weights, or a point of a plane, which moves with the plane).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

__all__ = ["Anchors"]


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
