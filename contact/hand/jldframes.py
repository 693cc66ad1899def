"""The skeleton as the JLD mapping sees it: segments, joint planes and frames, small helpers.

:class:`SkeletonTopology` chains the bones; :class:`JointFrames` holds each joint's centre,
axes, plane and animator's values and each bone's proximal and distal planes, and assigns
points to segments (the proximal assignment of Magnenat-Thalmann, Laperrière and Thalmann
1988, section 4). The row-wise vector helpers avoid numpy's set-up on short axes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .rigspec import ROOT
from .skeleton import PIVOT_SUFFIX, Skeleton

__all__ = [
    "EPS",
    "JointFrames",
    "SkeletonTopology",
    "apply",
    "close",
    "cross",
    "muscle_profile",
    "rotate",
    "smoothstep",
    "unit",
]

#: Floor of the denominators of ratios and normalisations.
EPS = 1e-12


def smoothstep(t: ArrayLike) -> NDArray[np.float64]:
    """``3 t^2 - 2 t^3`` of ``t`` clipped to [0, 1]: 0 below, 1 above, C1 in between."""
    t = np.clip(np.asarray(t, dtype=np.float64), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def muscle_profile(ratio: ArrayLike, peak: ArrayLike, power: ArrayLike) -> NDArray[np.float64]:
    """Two exponential functions joined at ``peak`` (Magnenat-Thalmann et al. 1988, Fig. 11).

    ``f = (a exp(1 - a)) ** power`` with ``a = ratio / peak`` before the join point and
    ``a = (1 - ratio) / (1 - peak)`` after it: 0 at both ends, 1 at ``peak`` where the two
    join with zero slope.
    """
    r = np.clip(np.asarray(ratio, dtype=np.float64), 0.0, 1.0)
    peak = np.asarray(peak, dtype=np.float64)
    a = np.where(r <= peak, r / peak, (1.0 - r) / (1.0 - peak))
    return (a * np.exp(1.0 - a)) ** power


def rotate(v: NDArray, axis: NDArray, angle: NDArray) -> NDArray:
    """Rotate vectors ``v`` about unit ``axis`` by ``angle`` (radians), row by row.

    Rodrigues' formula written on the columns (numpy's reductions along the short
    axis of an (n, 3) array are several times slower).
    """
    c, s = np.cos(angle), np.sin(angle)
    kv = axis[:, 0] * v[:, 0] + axis[:, 1] * v[:, 1] + axis[:, 2] * v[:, 2]
    kv *= 1.0 - c
    out = v * c[:, None]
    out += cross(axis, v) * s[:, None]
    out += axis * kv[:, None]
    return out


def apply(t: NDArray, x: NDArray) -> NDArray:
    """``t[:, :3, :3] x + t[:, :3, 3]`` row by row for transforms ``t`` (n, 4, 4)."""
    out = t[:, :3, 0] * x[:, :1]
    out += t[:, :3, 1] * x[:, 1:2]
    out += t[:, :3, 2] * x[:, 2:]
    out += t[:, :3, 3]
    return out


def cross(a: NDArray, b: NDArray) -> NDArray:
    """Row-wise cross product of (n, 3) arrays (``np.cross`` without its axis set-up)."""
    a0, a1, a2 = a[:, 0], a[:, 1], a[:, 2]
    b0, b1, b2 = b[:, 0], b[:, 1], b[:, 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=1)


def close(a: NDArray, b: NDArray) -> bool:
    """``np.allclose(a, b, atol=1e-9)`` of two small arrays, without its set-up."""
    return bool((np.abs(a - b) <= 1e-9 + 1e-5 * np.abs(b)).all())


def unit(v: NDArray) -> NDArray:
    """Rows of ``v`` scaled to unit length."""
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


@dataclass(frozen=True)
class SkeletonTopology:
    """Bone segments and how they chain, derived once from a :class:`Skeleton`.

    Attributes
    ----------
    names : list of str
        Bone names; index ``i`` is bone id ``i``.
    start, end, direction : ndarray, shape (B, 3)
        Rest axis of each bone (from its joint) and its unit direction.
    joint : list of str
        The joint carrying each bone (``"root"`` for fixed bones).
    parent : ndarray of int, shape (B,)
        The bone carried by the parent joint, -1 for none.
    chained : ndarray of bool, shape (B,)
        Bone ``i`` is the only bone carried by a joint hanging on its parent bone, and
        that joint is the parent's axis end: the two share a joint plane (two-sided JLD).
    child : ndarray of int, shape (B,)
        The chained child bone, -1 for none.
    """

    names: list[str]
    start: NDArray[np.float64]
    end: NDArray[np.float64]
    direction: NDArray[np.float64]
    joint: list[str]
    parent: NDArray[np.int64]
    chained: NDArray[np.bool_]
    child: NDArray[np.int64]

    @classmethod
    def from_skeleton(cls, skeleton: Skeleton) -> SkeletonTopology:
        """Build the topology of a skeleton's bones."""
        bones = skeleton.bones
        names = list(bones)
        joint = [b.joint for b in bones.values()]
        start = np.stack([b.start for b in bones.values()])
        end = np.stack([b.end for b in bones.values()])
        carried = {j: i for i, j in enumerate(joint)}
        parent = np.full(len(names), -1, dtype=np.int64)
        for i, j in enumerate(joint):
            if j != ROOT:
                parent[i] = carried.get(skeleton.joints[j].parent, -1)
        child = np.full(len(names), -1, dtype=np.int64)
        for a in range(len(names)):
            kids = np.flatnonzero(parent == a)
            if len(kids) == 1 and close(start[kids[0]], end[a]):
                child[a] = kids[0]
        chained = np.zeros(len(names), dtype=bool)
        chained[child[child >= 0]] = True
        return cls(names, start, end, unit(end - start), joint, parent, chained, child)


class JointFrames:
    """The skeleton's joints and segments as the JLD mapping sees them, derived once.

    Per joint (index in ``joint_names``): centre ``jpos``, flexion and pivot axes
    ``jflex``, ``jpiv``, maximal flexion ``jmax``, the bones it joins (``jparent``,
    ``jchild``; ``jtwo``: both sides chained), its plane's normal ``jm`` and frame
    (``ja`` along the flexion axis, ``jn`` dorsal), and the animator's values ``j_proximal``,
    ``j_distal``, ``j_rounding``, ``j_muscle``, ``j_muscle_peak``, ``j_muscle_power``. Per
    bone: its joint ``bjoint``, proximal and distal planes (``p_pt``, ``p_n``; ``d_pt``,
    ``d_n``, ``d_joint``), mean shaft half-width ``shaft``, dorsal normal ``b_normal`` and
    whether it is a finger's (``b_finger``). ``hubs``: bones carrying several joints (the
    carpus), ``hub_children`` the bones they carry. ``flex_col``, ``piv_col`` and
    ``bone_joint`` index the skeleton's angle vector and transform stack.

    Parameters
    ----------
    skeleton : Skeleton
    """

    def __init__(self, skeleton: Skeleton) -> None:
        sk = skeleton
        self.topology = topo = SkeletonTopology.from_skeleton(skeleton)
        self.joint_names = skeleton.joint_names
        self.jidx = {j: i for i, j in enumerate(self.joint_names)}
        nj = len(self.joint_names)
        spec = sk.spec
        self.jpos = np.stack([sk.joints[j].position for j in self.joint_names])
        self.jflex = np.stack([sk.joints[j].flexion_axis for j in self.joint_names])
        self.jpiv = np.stack(
            [
                sk.joints[j].pivot_axis if sk.joints[j].pivot_axis is not None else [0, 0, 1.0]
                for j in self.joint_names
            ]
        )
        self.jmax = np.array([max(sk.joints[j].flexion_limits[1], EPS) for j in self.joint_names])
        child_bone = np.array([topo.joint.index(j) for j in self.joint_names])
        self.jchild = child_bone
        # columns of each joint's flexion and pivot in the skeleton's angle vector, and
        # each bone's joint in its transform stack (the root last: the identity)
        col = {n: i for i, n in enumerate(sk.angle_names)}
        self.flex_col = np.array([col[j] for j in self.joint_names])
        self.piv_col = np.array([col.get(j + PIVOT_SUFFIX, -1) for j in self.joint_names])
        self.bone_joint = np.array([self.jidx.get(j, nj) for j in topo.joint])
        self.jparent = topo.parent[child_bone]
        self.jtwo = topo.chained[child_bone]
        params = [spec.jld_params(j) for j in self.joint_names]
        for key in ("proximal", "distal", "rounding", "muscle", "muscle_peak", "muscle_power"):
            setattr(self, f"j_{key}", np.array([getattr(p, key) for p in params]))
        # joint plane (bisector of the two bones, or normal to the child) and its frame
        d_child = topo.direction[child_bone]
        d_par = np.where(self.jtwo[:, None], topo.direction[np.maximum(self.jparent, 0)], d_child)
        m = unit(d_child + d_par)
        a = self.jflex - np.einsum("ij,ij->i", self.jflex, m)[:, None] * m
        a = unit(a)
        self.jm, self.ja = m, a
        self.jn = np.cross(m, a)  # dorsal normal of the joint plane (y x flexion axis)
        # each bone's planes: proximal (its joint's, or normal to it) and distal
        nb = len(topo.names)
        self.bjoint = np.array([self.jidx.get(j, -1) for j in topo.joint])
        self.p_pt = topo.start.copy()
        self.p_n = np.where(
            (self.bjoint >= 0)[:, None], self.jm[np.maximum(self.bjoint, 0)], topo.direction
        )
        self.p_n[~topo.chained] = topo.direction[~topo.chained]
        self.d_pt = topo.end.copy()
        self.d_n = topo.direction.copy()
        self.d_joint = np.full(nb, -1, np.int64)
        for b in range(nb):
            c = topo.child[b]
            if c >= 0:
                self.d_n[b] = self.p_n[c]
                self.d_joint[b] = self.bjoint[c]
        bones = list(sk.bones.values())
        self.shaft = np.array([b.shaft.mean() for b in bones])
        hubs = [b for b in range(nb) if topo.child[b] < 0 and (topo.parent == b).sum() > 1]
        self.hubs = np.array(hubs, dtype=np.int64)
        self.hub_children = [int(c) for c in np.flatnonzero(np.isin(topo.parent, hubs))]
        self.b_normal = np.stack([b.frame[:, 2] for b in bones])  # dorsal
        self.b_finger = np.array([b.part != spec.base_group for b in bones]) & (self.bjoint >= 0)

    def clamped_distance(self, x: NDArray, bones: NDArray | None = None) -> NDArray:
        """Distance of every point to every bone's axis segment (or to ``bones``)."""
        topo = self.topology
        idx = np.arange(len(topo.names)) if bones is None else bones
        a, ab = topo.start[idx], topo.end[idx] - topo.start[idx]
        t = np.clip(((x[:, None] - a) * ab).sum(-1) / (ab * ab).sum(-1), 0.0, 1.0)
        return np.linalg.norm(x[:, None] - (a + t[..., None] * ab), axis=-1)

    def ratio(self, x: NDArray, seg: NDArray) -> NDArray:
        """Ratio between the bone's proximal and distal planes (0 and 1 on them)."""
        sp = ((x - self.p_pt[seg]) * self.p_n[seg]).sum(-1)
        sd = ((x - self.d_pt[seg]) * self.d_n[seg]).sum(-1)
        # far from the segment the two planes may converge: bound the denominator from
        # below (continuously) by a fifth of the planes' distance along the axis
        span = ((self.d_pt[seg] - self.p_pt[seg]) * self.p_n[seg]).sum(-1)
        return sp / np.maximum(sp - sd, 0.2 * span)

    def assign(self, x: NDArray, bid: NDArray) -> NDArray:
        """Proximal assignment: nearest axis, then across joint planes to the neighbour."""
        topo = self.topology
        seg = np.argmin(self.clamped_distance(x), axis=1)
        free = bid < 0
        seg[~free] = bid[~free]
        for _ in range(3):
            r = self.ratio(x, seg)
            back = free & (r < 0.0) & topo.chained[seg]
            seg[back] = topo.parent[seg[back]]
            fwd = free & ~back & (r >= 1.0) & (topo.child[seg] >= 0)
            seg[fwd] = topo.child[seg[fwd]]
            # a one-sided child (a metacarpal on the carpus): behind its plane, the parent
            r = self.ratio(x, seg)
            off = free & (r < 0.0) & ~topo.chained[seg] & (topo.parent[seg] >= 0)
            seg[off] = topo.parent[seg[off]]
        return seg

    def assign_in(self, x: NDArray, allowed: NDArray) -> NDArray:
        """Proximal assignment of points to one of the ``allowed`` bones (one ray)."""
        topo = self.topology
        seg = allowed[np.argmin(self.clamped_distance(x, allowed), axis=1)]
        r = self.ratio(x, seg)
        back = (r < 0.0) & topo.chained[seg] & np.isin(topo.parent[seg], allowed)
        seg[back] = topo.parent[seg[back]]
        fwd = ~back & (r >= 1.0) & np.isin(topo.child[seg], allowed)
        seg[fwd] = topo.child[seg[fwd]]
        return seg
