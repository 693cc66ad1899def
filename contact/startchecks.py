"""A scene's start: an object inside a bone is refused, one inside the skin or a plane warned of."""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np

from .errors import InputError
from .geometry.plane import Plane
from .geometry.surfacequery import TriangleSurface
from .hand.posing import Pose
from .hand.shipped import Hand
from .scene.model import PlaneScene
from .solver.body import ElasticBody
from .solver.pairs import ContactPair, measure

__all__ = ["check_bones", "warn_overlaps"]

log = logging.getLogger(__name__)


def check_bones(hand: Hand, pose: Pose, objects: Sequence[ElasticBody], t: float) -> None:
    """Refuse an object that starts inside a bone of the posed hand: no contact resolves it.

    Its contact nodes inside a bone's closed surface (winding number), for the ball and
    any ``[[object]]`` alike; a bone's surface is built only where some object's nodes lie
    in its bounding box.

    Raises
    ------
    InputError
        Naming the frame, the object and the bone.
    """
    xs = [o.mesh.points[o.contact_nodes] for o in objects]
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


def warn_overlaps(
    t: float, bodies: Sequence[ElasticBody], planes: Sequence[PlaneScene], tolerance: float
) -> None:
    """Warn where an object starts inside the skin, a plane or another object, too deep.

    Called at the scene's start (the first frame solved), before any contact solve: the
    hand as posed there, the planes at their scene positions (their motion is how a scene
    presses, not a misplaced ball). A node deeper than ``tolerance`` times its element
    size (``solver.gap_tolerance``) gives one log line for its pair, naming the deepest
    node and its depth.
    """
    at_rest = [Plane(p.point, p.normal, name=p.name) for p in planes]
    objects = [b for b in bodies if b.name != "hand"]
    pairs = [ContactPair(o, pl) for o in objects for pl in at_rest]
    hand = [b for b in bodies if b.name == "hand"]
    for i, o in enumerate(objects):
        for other in objects[i + 1 :] + hand:
            pairs += [ContactPair(o, other), ContactPair(other, o)]
    u = {b.name: np.zeros((b.mesh.n_points, 3)) for b in bodies}
    for pair in pairs:
        p, _ = measure(pair, u, 0.0)
        if not p.nodes.size:
            continue
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
