"""Who presses how hard: contact forces per region (finger) and per plane, and ``forces.png``.

A body with named regions (the hand: palm, thumb, index, middle, ring, little) has its
contact forces summed per region: the *normal force* of a region is the sum of the normal
contact forces on its nodes (N, always >= 0), its *resultant* the force its nodes exert on
the other bodies, applied at the centroid of those nodes weighted by their normal force. A
node belongs to the region of most of its cells (:func:`contact.hand.fingers.node_parts`,
as in ``summary.json``'s forces per part). A plane's force on the bodies is minus its
``obstacle_forces`` entry, applied at the centroid of the contact nodes that lie on it.

The *grip force* of a frame is ``summary.json``'s ``grip_force`` where the caller gives
it, else the sum of the regions' normal forces, or, without named regions, of the planes'
force magnitudes: the pictures scale their arrows by it (:mod:`contact.output.pictures`),
and ``forces.png`` (:mod:`contact.output.plots`) plots it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

import fem

from ..hand.fingers import node_parts
from ..solver.results import FrameResult

__all__ = ["FrameForces", "Push", "frame_forces"]

#: A contact node lies on a plane when it is within this fraction of the scene's size of
#: it (contacts close to round-off; the fraction only has to exceed the penetrations).
_ON_PLANE = 0.01


@dataclass(frozen=True)
class Push:
    """A force that one part of the scene exerts on the others.

    Attributes
    ----------
    label : str
        ``"index"``, ``"hand region 2"`` or ``"plane table"``.
    normal : float
        Sum of the normal contact forces (N); for a plane the magnitude of its force.
    point : ndarray (3,)
        Where it acts (deformed positions).
    force : ndarray (3,)
        The resultant it exerts (N).
    """

    label: str
    normal: float
    point: NDArray[np.float64]
    force: NDArray[np.float64]


@dataclass
class FrameForces:
    """The forces of one frame, for its picture and for ``forces.png``.

    Attributes
    ----------
    time : float
    regions : list of Push
        One per named region with contact (in region order), then one per plane with
        contact.
    fingers : dict of str to float
        Normal force of every named region of the scene, touching or not (N).
    bones : dict of str to float
        Magnitude of every support group's force (N).
    grip : float
        The grip force (N).
    """

    time: float
    regions: list[Push] = field(default_factory=list)
    fingers: dict[str, float] = field(default_factory=dict)
    bones: dict[str, float] = field(default_factory=dict)
    grip: float = 0.0


def frame_forces(
    time: float,
    result: FrameResult,
    points: Mapping[str, NDArray[np.float64]],
    meshes: Mapping[str, tuple[fem.Mesh, Sequence[str]]],
    planes: Sequence[tuple[str, NDArray[np.float64], NDArray[np.float64]]],
    size: float,
    grip: float | None = None,
) -> FrameForces:
    """The forces of a frame per named region and per plane.

    Parameters
    ----------
    time : float
        Frame time.
    result : FrameResult
        The solve.
    points : mapping of str to ndarray (N, 3)
        Deformed nodal positions of every body.
    meshes : mapping of str to (fem.Mesh, sequence of str)
        Body with named regions -> its mesh and the region names.
    planes : sequence of (str, ndarray (3,), ndarray (3,))
        Name, point and unit normal of each plane.
    size : float
        The scene's size (m), for telling which contact nodes lie on a plane.
    grip : float, optional
        The grip force (N) as ``summary.json`` has it; default as the module says.

    Returns
    -------
    FrameForces
    """
    out = FrameForces(float(time))
    normal = {
        b: np.asarray(f.get("normal_force", np.zeros(len(points[b]))), dtype=np.float64)
        for b, f in result.contact_fields.items()
        if b in points
    }
    for body, (mesh, names) in meshes.items():
        node_region = node_parts(mesh, len(names))
        fn = normal.get(body, np.zeros(len(points[body])))
        fc = np.asarray(result.contact_force.get(body, np.zeros((len(fn), 3))), np.float64)
        for rid, name in enumerate(names):
            on = (node_region == rid) & (fn > 0)
            total = float(fn[on].sum())
            out.fingers[name] = total
            if total > 0:
                point = (fn[on, None] * points[body][on]).sum(axis=0) / total
                out.regions.append(Push(name, total, point, -fc[on].sum(axis=0)))
    out.grip = float(sum(out.fingers.values()))
    for name, point, unit in planes:
        force = result.obstacle_forces.get(name)
        if force is None or not np.linalg.norm(force) > 0:
            continue
        near = [
            x[(fn > 0) & (np.abs((x - point) @ unit) < _ON_PLANE * size)]
            for b, x in points.items()
            if (fn := normal.get(b)) is not None
        ]
        at = np.concatenate([np.zeros((0, 3)), *near])
        where = at.mean(axis=0) if len(at) else np.asarray(point, dtype=np.float64)
        f = -np.asarray(force, dtype=np.float64)
        out.regions.append(Push(f"plane {name}", float(np.linalg.norm(f)), where, f))
    if grip is not None:
        out.grip = float(grip)
    elif not meshes:
        out.grip = float(sum(p.normal for p in out.regions))
    out.bones = {
        g: float(np.linalg.norm(v))
        for groups in result.support_forces.values()
        for g, v in sorted(groups.items())
    }
    return out
