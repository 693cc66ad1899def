"""A scene's start: an object inside a bone or deep in a body refused, a small overlap warned of."""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from ..errors import InputError
from ..geometry.plane import Plane
from ..geometry.surfacequery import TriangleSurface
from ..hand.posing import Pose
from ..hand.shipped import Hand
from ..scene.model import PlaneScene
from ..solver.body import ElasticBody
from ..solver.pairs import ContactPair, measure

__all__ = ["OVERLAP_REFUSED", "check_bones", "check_overlaps", "smallest_extent"]

log = logging.getLogger(__name__)

#: The deepest start-up overlap allowed, as a fraction of the smallest extent of the
#: object (the smaller of two objects): past it the object is misplaced, not pressed.
OVERLAP_REFUSED = 0.1


def check_bones(
    hand: Hand,
    pose: Pose,
    objects: Sequence[ElasticBody],
    t: float,
    displacement: Mapping[str, NDArray[np.float64]] | None = None,
) -> None:
    """Refuse an object that starts inside a bone of the posed hand: no contact resolves it.

    Its contact nodes inside a bone's closed surface (winding number), for the ball and
    any ``[[object]]`` alike; a bone's surface is built only where some object's nodes lie
    in its bounding box. ``displacement``: where a finite object starts the frame, from
    its reference (flat or ``(N, 3)``).

    Raises
    ------
    InputError
        Naming the frame, the object and the bone.
    """
    moved = displacement or {}
    xs = [
        (o.mesh.points + np.reshape(moved.get(o.name, np.zeros(3)), (-1, 3)))[o.contact_nodes]
        for o in objects
    ]
    for name, surf in hand.bones.items():
        tf = pose.transforms[name]
        pts = np.asarray(surf.points) @ tf[:3, :3].T + tf[:3, 3]
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        s = None
        for o, x in zip(objects, xs, strict=True):
            near = np.all((x >= lo) & (x <= hi), axis=1)
            if not near.any():
                continue
            if s is None:
                tri = np.asarray(surf.faces).reshape(-1, 4)[:, 1:]
                s = TriangleSurface(pts, tri, name=f"bone {name}")
            if (s.winding_number(x[near]) > 0.5).any():
                what = "the ball" if o.name == "ball" else f"object {o.name!r}"
                raise InputError(
                    f"frame t = {t:g}: {what} starts inside bone {name}: place {what} "
                    "or close the hand less"
                )


def smallest_extent(points: NDArray[np.float64]) -> float:
    """A body's extent across its thinnest direction (m): along its least principal axis."""
    x = np.asarray(points, dtype=np.float64)
    x = x - x.mean(axis=0)
    _, axes = np.linalg.eigh(x.T @ x)
    return float(np.ptp(x @ axes[:, 0]))


def check_overlaps(
    t: float, bodies: Sequence[ElasticBody], planes: Sequence[PlaneScene], tolerance: float
) -> None:
    """Refuse an object that starts deep in a plane or an object; warn where it starts inside.

    Called at the scene's start (the first frame solved), before any contact solve: the
    hand as posed there, the planes at their scene positions (their motion is how a scene
    presses, not a misplaced ball). An object deeper in a plane or another object than
    :data:`OVERLAP_REFUSED` times the smaller object's smallest extent
    (:func:`smallest_extent`; a ball's diameter) is misplaced, not pressed: refused,
    naming the pair, the depth and the limit. The hand is posed into an object by its
    keyframes and automatic flexions to press it, however deep (:func:`check_bones` is its
    limit). Otherwise a node deeper than ``tolerance`` times its element size
    (``solver.gap_tolerance``) gives one log line for its pair, naming the deepest node
    and its depth.

    Raises
    ------
    InputError
        The pair overlapping deepest for its object's size, past the limit.
    """
    at_rest = [Plane(p.point, p.normal, name=p.name) for p in planes]
    objects = [b for b in bodies if b.name != "hand"]
    pairs = [ContactPair(o, pl) for o in objects for pl in at_rest]
    hand = [b for b in bodies if b.name == "hand"]
    for i, o in enumerate(objects):
        for other in objects[i + 1 :] + hand:
            pairs += [ContactPair(o, other), ContactPair(other, o)]
    size = {o.name: smallest_extent(o.mesh.points) for o in objects}
    u = {b.name: np.zeros((b.mesh.n_points, 3)) for b in bodies}
    found = []
    for pair in pairs:
        p, _ = measure(pair, u, 0.0)
        if p.nodes.size:
            found.append((pair, p))
    worst = None
    for pair, p in found:
        if "hand" in (pair.slave.name, pair.master.name):
            continue  # posed into an object is how a hand presses: its bones are the limit
        k = int(np.argmin(p.gap))
        obj = min((n for n in (pair.slave.name, pair.master.name) if n in size), key=size.get)
        limit = OVERLAP_REFUSED * size[obj]
        if -p.gap[k] > limit and (worst is None or -p.gap[k] / limit > worst[0]):
            worst = (-float(p.gap[k]) / limit, pair, int(p.nodes[k]), -float(p.gap[k]), obj)
    if worst is not None:
        _, pair, node, depth, obj = worst
        what = "the ball" if obj == "ball" else f"object {obj!r}"
        raise InputError(
            f"frame t = {t:g}: {pair.name} overlap at the start: node {node} of "
            f"{pair.slave.name} is {depth * 1e3:.3g} mm inside {pair.master.name}, deeper "
            f"than {100 * OVERLAP_REFUSED:g} % of the smallest extent of {what} "
            f"({OVERLAP_REFUSED * size[obj] * 1e3:.3g} mm): place them apart"
        )
    for pair, p in found:
        local = np.sqrt(np.maximum(pair.slave.node_areas[p.nodes], 1e-300))
        k = int(np.argmax(-p.gap / local))
        if -p.gap[k] <= tolerance * local[k]:
            continue
        log.warning(
            "t = %g: %s overlap at the start: node %d of %s is %.3g mm inside %s "
            "(gap tolerance %.3g mm)",
            t,
            pair.name,
            int(p.nodes[k]),
            pair.slave.name,
            -float(p.gap[k]) * 1e3,
            pair.master.name,
            tolerance * local[k] * 1e3,
        )
