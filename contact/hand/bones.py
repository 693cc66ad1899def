"""Bone surfaces: one closed, swept surface per bone, with a shaft and wider ends.

Each bone is swept along its axis (local y of the bone frame, from its start) with an
elliptic cross-section whose half-widths ``(wx, wz)`` follow a profile:

- a rounded proximal end, the quarter ellipse of radii ``base`` (across x, along, across z);
- a smooth (cubic, zero-slope) waist from the base to the ``shaft`` half-widths at mid-bone
  and back out to the ``head`` half-widths at the distal end point;
- a rounded distal end, the half ellipsoid of radii ``head`` centred on that end point (a
  joint centre sits inside its bone's head, as the centre of a condyle does).

The proximal end starts ``gap`` beyond the parent bone, measured along the bone's axis from
its joint: the parent lies in the half-space below, the bone in the one above, so the two
never touch across the joint at rest.

Surfaces are built as rings of ``n_around`` nodes plus a pole at each end, so they are
closed, manifold and outward oriented by construction; the edge length sets the density.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ..errors import RigError
from ..geometry.surfaces import enclosed_volume, poly_from_arrays
from .rigspec import ROOT, BoneSpec
from .skeleton import Skeleton

if TYPE_CHECKING:
    import pyvista

__all__ = ["bone_profile", "bone_surfaces", "joint_clearance", "sweep_bone"]

log = logging.getLogger(__name__)


def _smooth(t: NDArray) -> NDArray:
    return t * t * (3.0 - 2.0 * t)


def bone_profile(bone: BoneSpec, y_start: float, edge: float) -> tuple[NDArray, NDArray]:
    """Stations along the bone axis and the half-widths there.

    Parameters
    ----------
    bone : BoneSpec
    y_start : float
        Where the proximal end begins, along the axis from ``bone.start`` (m).
    edge : float
        Target spacing of the stations (m).

    Returns
    -------
    y : ndarray, shape (K,)
        Stations, increasing, poles excluded (they are at ``y_start`` and the far end).
    half_widths : ndarray, shape (K, 2)
        ``(wx, wz)`` at each station.
    """
    length = bone.length
    (bx, by, bz), (hx, hy, hz) = bone.base, bone.head
    yb = y_start + by
    if yb >= length:
        raise RigError(
            f"bone {bone.name}: its base (from {y_start * 1e3:.1f} mm, radius along "
            f"{by * 1e3:.1f} mm) reaches past its end at {length * 1e3:.1f} mm"
        )
    ym = 0.5 * (yb + length)

    def cap(radius: float, across: float) -> NDArray:
        n = max(3, int(np.ceil(0.5 * np.pi * max(radius, across) / edge)))
        return np.linspace(0.0, 0.5 * np.pi, n + 1)[1:]  # angle from the pole

    phi0 = cap(by, max(bx, bz))
    y0 = yb - by * np.cos(phi0)
    w0 = np.outer(np.sin(phi0), [bx, bz])
    n_mid = max(2, int(np.ceil((length - yb) / edge)))
    y1 = np.linspace(yb, length, n_mid + 1)[1:-1]
    t = np.clip((y1 - yb) / (ym - yb), 0.0, 1.0)
    s = np.clip((y1 - ym) / (length - ym), 0.0, 1.0)
    base, shaft, head = np.array([bx, bz]), bone.shaft, np.array([hx, hz])
    w1 = np.where(
        (y1 < ym)[:, None],
        base + (shaft - base) * _smooth(t)[:, None],
        shaft + (head - shaft) * _smooth(s)[:, None],
    )
    phi2 = cap(hy, max(hx, hz))[::-1]
    y2 = length + hy * np.cos(phi2)
    w2 = np.outer(np.sin(phi2), [hx, hz])
    return np.concatenate([y0, y1, y2]), np.concatenate([w0, w1, w2])


def sweep_bone(
    bone: BoneSpec, y_start: float, edge: float
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Points (rest frame, m) and outward triangles of one bone's closed surface.

    Parameters
    ----------
    bone : BoneSpec
    y_start : float
        Start of the proximal end along the axis (m), see :func:`bone_profile`.
    edge : float
        Target edge length (m).
    """
    y, w = bone_profile(bone, y_start, edge)
    n = max(8, int(np.ceil(2.0 * np.pi * w.max() / edge)))
    theta = 2.0 * np.pi * np.arange(n) / n
    local = np.stack(
        [
            w[:, :1] * np.cos(theta),
            np.broadcast_to(y[:, None], (len(y), n)),
            w[:, 1:] * np.sin(theta),
        ],
        axis=-1,
    ).reshape(-1, 3)
    poles = np.array([[0.0, y_start, 0.0], [0.0, bone.length + bone.head[1], 0.0]])
    local = np.vstack([local, poles])
    k = len(y)
    ring = np.arange(k * n).reshape(k, n)
    a, b = ring[:-1], np.roll(ring[:-1], -1, axis=1)
    c, d = ring[1:], np.roll(ring[1:], -1, axis=1)
    quads = np.concatenate(
        [np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)]
    )
    p0, p1 = k * n, k * n + 1
    fan0 = np.stack([np.full(n, p0), np.roll(ring[0], -1), ring[0]], -1)
    fan1 = np.stack([np.full(n, p1), ring[-1], np.roll(ring[-1], -1)], -1)
    tri = np.concatenate([fan0, quads, fan1]).astype(np.int64)
    pts = bone.start + local @ bone.frame.T
    if enclosed_volume(pts, tri) < 0:
        tri = tri[:, ::-1]
    return pts, tri


def _start_offsets(
    skeleton: Skeleton, edge: float, starts: dict[str, float] | None = None
) -> dict[str, tuple[NDArray, NDArray]]:
    """Sweep every bone at rest, parents first, each starting ``gap`` beyond its parents.

    ``starts``, when given, receives each bone's ``y_start`` (see :func:`bone_profile`).
    """
    spec = skeleton.spec
    by_joint: dict[str, list[str]] = {}
    for name, b in spec.bones.items():
        by_joint.setdefault(b.joint, []).append(name)
    out: dict[str, tuple[NDArray, NDArray]] = {}
    for joint in [ROOT, *skeleton.joint_names]:
        parent = spec.joints[joint].parent if joint != ROOT else None
        for name in by_joint.get(joint, []):
            b = spec.bones[name]
            axis = b.frame[:, 1]
            reach = (
                [
                    float(((out[p][0] - b.start) @ axis).max())
                    for p in by_joint.get(parent, [])
                    if p in out
                ]
                if parent
                else []
            )
            y_start = max(reach) + spec.gap if reach else 0.0
            out[name] = sweep_bone(b, y_start, edge)
            if starts is not None:
                starts[name] = y_start
    return out


def bone_surfaces(
    skeleton: Skeleton,
    edge: float = 0.001,
    angles: Mapping[str, float] | None = None,
) -> dict[str, pyvista.PolyData]:
    """The closed surface of every bone, posed by forward kinematics.

    Parameters
    ----------
    skeleton : Skeleton
    edge : float
        Target edge length of the triangles (m).
    angles : mapping of str to float, optional
        Joint angles in degrees; the rest pose by default.

    Returns
    -------
    dict of str to pyvista.PolyData
        By bone name, in the rig's bone order; triangles face outward.
    """
    if not edge > 0:
        raise ValueError(f"edge length must be positive, got {edge!r}")
    rest = _start_offsets(skeleton, edge)
    transforms = skeleton.forward_kinematics(angles)
    out = {}
    for name in skeleton.bone_names:
        pts, tri = rest[name]
        t = transforms[name]
        out[name] = poly_from_arrays(pts @ t[:3, :3].T + t[:3, 3], tri)
    log.info("bones: %d surfaces, %d triangles", len(out), sum(p.n_cells for p in out.values()))
    return out


def _inside(bone: BoneSpec, y_start: float, edge: float, x: NDArray) -> NDArray[np.bool_]:
    """Which rest-frame points lie inside a bone's swept surface (its profile, exactly)."""
    y, w = bone_profile(bone, y_start, edge)
    y = np.concatenate([[y_start], y, [bone.length + bone.head[1]]])
    w = np.vstack([[0.0, 0.0], w, [0.0, 0.0]])
    u = (x - bone.start) @ bone.frame
    wx, wz = np.interp(u[:, 1], y, w[:, 0]), np.interp(u[:, 1], y, w[:, 1])
    r = (u[:, 0] / np.maximum(wx, 1e-12)) ** 2 + (u[:, 2] / np.maximum(wz, 1e-12)) ** 2
    return (u[:, 1] > y_start) & (u[:, 1] < y[-1]) & (r < 1.0)


def joint_clearance(
    skeleton: Skeleton,
    joint: str,
    steps: int = 7,
    edge: float = 0.0005,
) -> tuple[float, dict[str, float]]:
    """Smallest distance between the bones a joint separates, over its range of motion.

    The bone the joint carries is turned over a grid of its flexion (and pivot) angles,
    ``steps`` values from limit to limit each, the limits themselves included; at each
    the distance of its surface points to the surfaces of the bones carried by the
    joint's parent (the parent bone, and its siblings) is measured, negative (minus the
    depth, roughly) where a point lies inside.

    Returns
    -------
    clearance : float
        The smallest distance (m) over the grid; the rig asks for ``flesh.gap``.
    angles : dict of str to float
        The angles (degrees) where it occurs.
    """
    from scipy.spatial import cKDTree

    spec = skeleton.spec
    starts: dict[str, float] = {}
    rest = _start_offsets(skeleton, edge, starts)
    child = [n for n, b in spec.bones.items() if b.joint == joint]
    parent = spec.joints[joint].parent
    others = [n for n, b in spec.bones.items() if b.joint == parent and n not in child]
    j = spec.joints[joint]
    names = [joint] + ([joint + "_pivot"] if j.pivot_axis is not None else [])
    lims = skeleton.limits
    grids = np.meshgrid(*[np.linspace(*lims[n], steps) for n in names], indexing="ij")
    trees = {o: cKDTree(rest[o][0]) for o in others}
    best, where = np.inf, {}
    for values in zip(*(g.ravel() for g in grids)):
        angles = dict(zip(names, (float(v) for v in values)))
        tf = skeleton.forward_kinematics(angles)
        for c in child:
            x = rest[c][0] @ tf[c][:3, :3].T + tf[c][:3, 3]
            for o in others:
                d = trees[o].query(x)[0]
                inside = _inside(spec.bones[o], starts[o], edge, x)
                d = np.where(inside, -d, d).min()
                if d < best:
                    best, where = float(d), angles
    return best, where
