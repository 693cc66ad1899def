"""Joint-dependent local deformations (JLD): the skin and flesh mapping of seed 001.

Every point of the hand at rest (skin vertex or flesh node, volume nodes included) is
localised once against the skeleton, then mapped for any pose by :meth:`JLDMap.map`. The
steps follow Magnenat-Thalmann, Laperrière and Thalmann (seed 001, sections 3 to 6):

Localisation (section 4, Fig. 4)
    *Proximal assignment*: a point belongs to the bone whose axis segment is nearest
    (a node fixed to a bone belongs to that bone). Its *projection* on the segment gives the
    *ratio* ``R = L1 / LT`` from the proximal joint, its *thickness* ``E`` is the distance
    to the projection. The ratio is measured between the two planes that bisect the
    segment and its neighbours at the joints (the plane normal to the segment where it has
    no neighbour), so that two segments share their joint plane exactly; a point beyond a
    joint plane is handed to the neighbouring segment.
Areas (section 5.1, Fig. 6)
    Along a segment: a *proximal area* ``R < prox_P``, a *buffer* and a *distal area*
    ``R > 1 - prox_D``; the proximities are the animator's parameters of each joint.
Coordinate bases (sections 4, 5.3, 5.4, Figs. 3, 8, 9, 10)
    The buffer moves rigidly with its bone (its normals are the segment's original ones).
    In the two areas at a joint the basis turns from the original normal of one segment
    to the other's through the *modified normal*: the point's basis is its parent bone's
    turned by the fraction ``s`` of the joint's rotation (flexion and pivot), so the
    normal is the initial one at ``s = 0``, the final one at ``s = 1`` and their average
    (normalised) at ``s = 1/2``. The fraction follows the area ratio as in Fig. 8 (at the
    end of the area ``s`` reaches the segment's own basis) combined with where the point
    lies between the two bones: with ``dA`` and ``dB`` its distances to the surfaces of
    the parent and child bones, ``b = sqrt(dA) / (sqrt(dA) + sqrt(dB))``; child side
    ``s = 1 - (1 - b)(1 - g(R / prox_P))``, parent side ``s = b (1 - g((1 - R) / prox_D))``,
    ``g`` a smoothstep. Both sides give the same ``s`` on the joint plane, so the mapping
    is continuous there, and a point on a bone's surface gets exactly that bone's motion,
    as the nodes fixed to it do. (The seed interpolates by the ratio alone and keeps the
    segment as x-axis: a shear that folds the palmar flesh of a deep flexion and tears
    the flesh from bones that are rigid right up to the joint; fine for a skin, not for a
    tetrahedral volume.) A joint whose parent bone carries several joints (the
    carpometacarpal joints on the carpus) has its parent-side area on that bone's end,
    handed to the nearest child.
Two-segment covering of the palm (sections 4 and 5.2, Figs. 5 and 7)
    The rays are the chains of bones on the carpus (a metacarpal and its finger). A free
    point of a metacarpal or a proximal phalanx is also localised on the neighbouring rays
    (proximal assignment within each ray); the *virtual segment* joins its projections.
    Its ratio ``t`` between the two bone surfaces splits it into an area along each
    segment (``t < palm_proximity``), mapped by that segment alone, and an in-between
    area where the rays' mappings blend, half and half at the middle (Fig. 5: the bases
    interpolate from one segment's to the other's). The blend weights are inverse cubes
    of the distances to the rays' bones, normalised: the same formula for every palm
    point, so the mapping is continuous between rays. Along a proximal phalanx the
    neighbours fade out past the web. The *scale factor* ``F`` (virtual segment at rest
    over posed) thickens the palm between two rays that come closer, by ``F ** palm_bulge``
    midway.
Joint rounding and muscle inflation (section 6)
    With the flexion ratio ``FR = flexion / maximal flexion`` of a joint, dorsal points in
    its two areas move away from the segment axis by ``rounding * FR * (1 - R/prox)^2``
    of their flesh thickness beyond the bone (largest at the joint, none at the area's
    end); palmar points of a finger segment by ``muscle * FR * f(R)``, ``f`` two
    exponential functions ``(a e^(1-a))^b`` joined at the animator's ``muscle_peak``,
    ``a = R / peak`` before it and ``(1 - R) / (1 - peak)`` after (``f`` is 0 at both
    joints and 1 at the join point).

Exactness: :meth:`JLDMap.displacement` is ``map(pose) - map(rest)`` computed by the same
arithmetic, so every point maps to itself bit for bit at the rest angles. Points fixed to a
bone move exactly rigidly with it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from .rigspec import ROOT
from .skeleton import PIVOT_SUFFIX, Skeleton

__all__ = ["JLDMap", "SkeletonTopology", "muscle_profile", "smoothstep"]

_EPS = 1e-12
#: Along a proximal phalanx, the blend with the neighbouring finger fades out between these
#: ratios (the web between the fingers ends about mid-phalanx in the shipped hand).
_WEB = (0.55, 0.8)


def smoothstep(t: ArrayLike) -> NDArray[np.float64]:
    """``3 t^2 - 2 t^3`` of ``t`` clipped to [0, 1]: 0 below, 1 above, C1 in between."""
    t = np.clip(np.asarray(t, dtype=np.float64), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def muscle_profile(ratio: ArrayLike, peak: ArrayLike, power: ArrayLike) -> NDArray[np.float64]:
    """Two exponential functions joined at ``peak`` (seed 001, Fig. 11).

    ``f = (a exp(1 - a)) ** power`` with ``a = ratio / peak`` before the join point and
    ``a = (1 - ratio) / (1 - peak)`` after it: 0 at both ends, 1 at ``peak`` where the two
    join with zero slope.
    """
    r = np.clip(np.asarray(ratio, dtype=np.float64), 0.0, 1.0)
    peak = np.asarray(peak, dtype=np.float64)
    a = np.where(r <= peak, r / peak, (1.0 - r) / (1.0 - peak))
    return (a * np.exp(1.0 - a)) ** power


def _rotate(v: NDArray, axis: NDArray, angle: NDArray) -> NDArray:
    """Rotate vectors ``v`` about unit ``axis`` by ``angle`` (radians), row by row.

    Rodrigues' formula written on the columns (numpy's reductions along the short
    axis of an (n, 3) array are several times slower).
    """
    c, s = np.cos(angle), np.sin(angle)
    kv = axis[:, 0] * v[:, 0] + axis[:, 1] * v[:, 1] + axis[:, 2] * v[:, 2]
    kv *= 1.0 - c
    out = v * c[:, None]
    out += _cross(axis, v) * s[:, None]
    out += axis * kv[:, None]
    return out


def _apply(t: NDArray, x: NDArray) -> NDArray:
    """``t[:, :3, :3] x + t[:, :3, 3]`` row by row for transforms ``t`` (n, 4, 4)."""
    out = t[:, :3, 0] * x[:, :1]
    out += t[:, :3, 1] * x[:, 1:2]
    out += t[:, :3, 2] * x[:, 2:]
    out += t[:, :3, 3]
    return out


def _cross(a: NDArray, b: NDArray) -> NDArray:
    """Row-wise cross product of (n, 3) arrays (``np.cross`` without its axis set-up)."""
    a0, a1, a2 = a[:, 0], a[:, 1], a[:, 2]
    b0, b1, b2 = b[:, 0], b[:, 1], b[:, 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=1)


def _close(a: NDArray, b: NDArray) -> bool:
    """``np.allclose(a, b, atol=1e-9)`` of two small arrays, without its set-up."""
    return bool((np.abs(a - b) <= 1e-9 + 1e-5 * np.abs(b)).all())


def _unit(v: NDArray) -> NDArray:
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
            if len(kids) == 1 and _close(start[kids[0]], end[a]):
                child[a] = kids[0]
        chained = np.zeros(len(names), dtype=bool)
        chained[child[child >= 0]] = True
        return cls(names, start, end, _unit(end - start), joint, parent, chained, child)


class JLDMap:
    """The JLD mapping of a fixed set of rest points, localised once, mapped per pose.

    Parameters
    ----------
    skeleton : Skeleton
        The rig (its ``spec`` holds the animator's JLD parameters).
    points : array_like, shape (N, 3)
        Rest positions (flesh nodes, skin vertices).
    bone_id : array_like of int, shape (N,), optional
        Bone each point is fixed to (-1: free). Fixed points move rigidly with their bone.
    reference : (points, bone_id), optional
        Rest points fixed to bones that measure the distance to each bone's surface (the
        flesh nodes of the hand when mapping its skin); default: the fixed ``points``.

    Examples
    --------
    >>> m = JLDMap(hand.skeleton, hand.flesh.points, hand.bone_id)  # doctest: +SKIP
    >>> posed = m.map({"index_mcp": 45.0})  # doctest: +SKIP
    """

    def __init__(
        self,
        skeleton: Skeleton,
        points: ArrayLike,
        bone_id: ArrayLike | None = None,
        reference: tuple[ArrayLike, ArrayLike] | None = None,
    ) -> None:
        x = np.ascontiguousarray(points, dtype=np.float64)
        if x.ndim != 2 or x.shape[1] != 3:
            raise ValueError(f"points must have shape (N, 3), got {x.shape}")
        n = len(x)
        bid = np.full(n, -1, np.int64) if bone_id is None else np.asarray(bone_id, np.int64)
        if bid.shape != (n,):
            raise ValueError(f"bone_id must have shape ({n},), got {bid.shape}")
        self.skeleton = skeleton
        self.topology = topo = SkeletonTopology.from_skeleton(skeleton)
        if bid.max(initial=-1) >= len(topo.names) or bid.min(initial=-1) < -1:
            raise ValueError(f"bone_id must lie in -1..{len(topo.names) - 1}")
        self.points = x
        self.bone_id = bid
        self._fixed = np.flatnonzero(bid >= 0)  # the bone nodes, moved rigidly
        self._joint_names = skeleton.joint_names
        self._jidx = {j: i for i, j in enumerate(self._joint_names)}
        self._joint_setup()
        ref_x, ref_id = (x, bid) if reference is None else reference
        ref_x = np.asarray(ref_x, dtype=np.float64)
        ref_id = np.asarray(ref_id, dtype=np.int64)
        order = np.argsort(ref_id, kind="stable")
        cut = np.searchsorted(ref_id[order], np.arange(len(topo.names) + 1))
        self._ref = {  # each bone's reference nodes; their k-d trees are built on first use
            b: ref_x[order[cut[b] : cut[b + 1]]]
            for b in range(len(topo.names))
            if cut[b + 1] > cut[b]
        }
        self._trees: dict[int, cKDTree] = {}
        seg = self._assign(x, bid)
        self.segment = seg
        self._main = self._localise(x, seg)
        self._palm_setup(x, seg, bid)
        self._rest = self._map(self._pose_data({}))

    # --- set-up ---------------------------------------------------------------------

    def _joint_setup(self) -> None:
        """Per joint: centre, axes, plane, the bones it joins and the animator's values."""
        sk, topo = self.skeleton, self.topology
        nj = len(self._joint_names)
        spec = sk.spec
        self._jpos = np.stack([sk.joints[j].position for j in self._joint_names])
        self._jflex = np.stack([sk.joints[j].flexion_axis for j in self._joint_names])
        self._jpiv = np.stack(
            [
                sk.joints[j].pivot_axis if sk.joints[j].pivot_axis is not None else [0, 0, 1.0]
                for j in self._joint_names
            ]
        )
        self._jmax = np.array(
            [max(sk.joints[j].flexion_limits[1], _EPS) for j in self._joint_names]
        )
        child_bone = np.array([topo.joint.index(j) for j in self._joint_names])
        self._jchild = child_bone
        # columns of each joint's flexion and pivot in the skeleton's angle vector, and
        # each bone's joint in its transform stack (the root last: the identity)
        col = {n: i for i, n in enumerate(sk.angle_names)}
        self._flex_col = np.array([col[j] for j in self._joint_names])
        self._piv_col = np.array([col.get(j + PIVOT_SUFFIX, -1) for j in self._joint_names])
        self._bone_joint = np.array([self._jidx.get(j, nj) for j in topo.joint])
        self._jparent = topo.parent[child_bone]
        self._jtwo = topo.chained[child_bone]
        params = [spec.jld_params(j) for j in self._joint_names]
        for key in ("proximal", "distal", "rounding", "muscle", "muscle_peak", "muscle_power"):
            setattr(self, f"_j_{key}", np.array([getattr(p, key) for p in params]))
        # joint plane (bisector of the two bones, or normal to the child) and its frame
        d_child = topo.direction[child_bone]
        d_par = np.where(self._jtwo[:, None], topo.direction[np.maximum(self._jparent, 0)], d_child)
        m = _unit(d_child + d_par)
        a = self._jflex - np.einsum("ij,ij->i", self._jflex, m)[:, None] * m
        a = _unit(a)
        self._jm, self._ja = m, a
        self._jn = np.cross(m, a)  # dorsal normal of the joint plane (y x flexion axis)
        # each bone's planes: proximal (its joint's, or normal to it) and distal
        nb = len(topo.names)
        self._bjoint = np.array([self._jidx.get(j, -1) for j in topo.joint])
        self._p_pt = topo.start.copy()
        self._p_n = np.where(
            (self._bjoint >= 0)[:, None], self._jm[np.maximum(self._bjoint, 0)], topo.direction
        )
        self._p_n[~topo.chained] = topo.direction[~topo.chained]
        self._d_pt = topo.end.copy()
        self._d_n = topo.direction.copy()
        self._d_joint = np.full(nb, -1, np.int64)
        for b in range(nb):
            c = topo.child[b]
            if c >= 0:
                self._d_n[b] = self._p_n[c]
                self._d_joint[b] = self._bjoint[c]
        bones = list(sk.bones.values())
        self._shaft = np.array([b.shaft.mean() for b in bones])
        hubs = [b for b in range(nb) if topo.child[b] < 0 and (topo.parent == b).sum() > 1]
        self._hubs = np.array(hubs, dtype=np.int64)
        self._hub_children = [int(c) for c in np.flatnonzero(np.isin(topo.parent, hubs))]
        self._b_normal = np.stack([b.frame[:, 2] for b in bones])  # dorsal
        self._b_finger = np.array([b.part != spec.base_group for b in bones]) & (self._bjoint >= 0)

    def _clamped_distance(self, x: NDArray, bones: NDArray | None = None) -> NDArray:
        """Distance of every point to every bone's axis segment (or to ``bones``)."""
        topo = self.topology
        idx = np.arange(len(topo.names)) if bones is None else bones
        a, ab = topo.start[idx], topo.end[idx] - topo.start[idx]
        t = np.clip(((x[:, None] - a) * ab).sum(-1) / (ab * ab).sum(-1), 0.0, 1.0)
        return np.linalg.norm(x[:, None] - (a + t[..., None] * ab), axis=-1)

    def _ratio(self, x: NDArray, seg: NDArray) -> NDArray:
        """Ratio between the bone's proximal and distal planes (0 and 1 on them)."""
        sp = ((x - self._p_pt[seg]) * self._p_n[seg]).sum(-1)
        sd = ((x - self._d_pt[seg]) * self._d_n[seg]).sum(-1)
        # far from the segment the two planes may converge: bound the denominator from
        # below (continuously) by a fifth of the planes' distance along the axis
        span = ((self._d_pt[seg] - self._p_pt[seg]) * self._p_n[seg]).sum(-1)
        return sp / np.maximum(sp - sd, 0.2 * span)

    def _assign(self, x: NDArray, bid: NDArray) -> NDArray:
        """Proximal assignment: nearest axis, then across joint planes to the neighbour."""
        topo = self.topology
        seg = np.argmin(self._clamped_distance(x), axis=1)
        free = bid < 0
        seg[~free] = bid[~free]
        for _ in range(3):
            r = self._ratio(x, seg)
            back = free & (r < 0.0) & topo.chained[seg]
            seg[back] = topo.parent[seg[back]]
            fwd = free & ~back & (r >= 1.0) & (topo.child[seg] >= 0)
            seg[fwd] = topo.child[seg[fwd]]
            # a one-sided child (a metacarpal on the carpus): behind its plane, the parent
            r = self._ratio(x, seg)
            off = free & (r < 0.0) & ~topo.chained[seg] & (topo.parent[seg] >= 0)
            seg[off] = topo.parent[seg[off]]
        return seg

    def _tree(self, bone: int) -> cKDTree | None:
        """k-d tree of the reference nodes fixed to ``bone`` (None without any)."""
        if bone not in self._trees and bone in self._ref:
            self._trees[bone] = cKDTree(self._ref[bone])
        return self._trees.get(bone)

    def _surface_distance(self, x: NDArray, bones: NDArray) -> NDArray:
        """Distance from each point to the surface of the bone ``bones[i]`` (m).

        Measured to the nearest rest node fixed to that bone (the nodes that move rigidly
        with it); without such nodes, to the bone's axis less its mean shaft half-width.
        """
        out = np.empty(len(x))
        for b in np.unique(bones):
            at = bones == b
            tree = self._tree(int(b))
            if tree is not None:
                out[at] = tree.query(x[at])[0]
            else:
                d = self._clamped_distance(x[at], np.array([b]))[:, 0]
                out[at] = np.maximum(d - self._shaft[b], 0.0)
        return out

    def _assign_in(self, x: NDArray, allowed: NDArray) -> NDArray:
        """Proximal assignment of points to one of the ``allowed`` bones (one ray)."""
        topo = self.topology
        seg = allowed[np.argmin(self._clamped_distance(x, allowed), axis=1)]
        r = self._ratio(x, seg)
        back = (r < 0.0) & topo.chained[seg] & np.isin(topo.parent[seg], allowed)
        seg[back] = topo.parent[seg[back]]
        fwd = ~back & (r >= 1.0) & np.isin(topo.child[seg], allowed)
        seg[fwd] = topo.child[seg[fwd]]
        return seg

    def _localise(self, x: NDArray, seg: NDArray) -> dict[str, NDArray]:
        """Segment, zone joint, weight and rounding/inflation coefficients of points."""
        topo = self.topology
        n = len(x)
        r = self._ratio(x, seg)
        proj = topo.start[seg] + r[:, None] * (topo.end[seg] - topo.start[seg])
        off = x - proj
        thick = np.linalg.norm(off, axis=1)
        pj, dj = self._bjoint[seg], self._d_joint[seg]
        has_p = (pj >= 0) & (topo.parent[seg] >= 0)
        # several joints on the segment's far end (the carpus): the nearest one's areas
        many = np.isin(seg, self._hubs) & (dj < 0)
        if many.any():
            kids = self._hub_children
            dk = np.stack([self._surface_distance(x[many], np.full(many.sum(), c)) for c in kids])
            best = np.array(kids)[np.argmin(dk, axis=0)]
            ok = topo.parent[best] == seg[many]
            dj = dj.copy()
            dj[np.flatnonzero(many)[ok]] = self._bjoint[best[ok]]
        has_d = dj >= 0
        # zone: the child side of the proximal joint, or the parent side of the distal one
        child_side = has_p & ((r < 0.5) | ~has_d)
        parent_side = has_d & ~child_side
        zone = np.full(n, -1, np.int64)
        zone[child_side] = pj[child_side]
        zone[parent_side] = dj[parent_side]
        zj = np.maximum(zone, 0)
        # the weight between the two bones of the joint: their surface distances
        inz = zone >= 0
        d_par = np.zeros(n)
        d_chi = np.zeros(n)
        d_par[inz] = self._surface_distance(x[inz], self._jparent[zj[inz]])
        d_chi[inz] = self._surface_distance(x[inz], self._jchild[zj[inz]])
        dp, dc = np.sqrt(d_par), np.sqrt(d_chi)
        between = dp / np.maximum(dp + dc, _EPS)
        s = np.zeros(n)
        cs = child_side
        s[cs] = 1.0 - (1.0 - between[cs]) * (1.0 - smoothstep(r[cs] / self._j_proximal[zj][cs]))
        # behind the plane of a child of several (a metacarpal's point on the carpus, as a
        # neighbouring ray sees it): the parent side's formula, on the parent's ratio
        back = cs & (r < 0.0) & ~self._jtwo[zj]
        if back.any():
            rp = self._ratio(x[back], self._jparent[zj[back]])
            s[back] = between[back] * (1.0 - smoothstep((1.0 - rp) / self._j_distal[zj[back]]))
        ps = parent_side
        s[ps] = between[ps] * (1.0 - smoothstep((1.0 - r[ps]) / self._j_distal[zj][ps]))
        base = np.where(child_side, topo.parent[seg], seg)
        # rounding (dorsal, in the areas of two-sided joints) and muscle inflation (palmar)
        beyond = np.clip(self._surface_distance(x, seg) / np.maximum(thick, _EPS), 0.0, 1.0)
        # at a joint: beyond the nearer of its two bones (the same on both sides)
        near_bone = np.where(inz, np.minimum(d_par, d_chi), 0.0)
        beyond_j = np.clip(near_bone / np.maximum(thick, _EPS), 0.0, 1.0)
        round_j = np.full(n, -1, np.int64)
        round_k = np.zeros(n)
        near_p = has_p & self._jtwo[np.maximum(pj, 0)]
        t_p = r / self._j_proximal[np.maximum(pj, 0)]
        in_p = near_p & (t_p < 1.0)
        round_j[in_p] = pj[in_p]
        round_k[in_p] = (1.0 - np.clip(t_p[in_p], 0.0, 1.0)) ** 2
        d_two = (self._d_joint[seg] >= 0) & self._jtwo[np.maximum(self._d_joint[seg], 0)]
        t_d = (1.0 - r) / self._j_distal[np.maximum(self._d_joint[seg], 0)]
        in_d = d_two & ~in_p & (t_d < 1.0)
        round_j[in_d] = self._d_joint[seg][in_d]
        round_k[in_d] = (1.0 - np.clip(t_d[in_d], 0.0, 1.0)) ** 2
        rj = np.maximum(round_j, 0)
        cos_j = (off * self._jn[rj]).sum(-1) / np.maximum(thick, _EPS)
        round_k *= self._j_rounding[rj] * np.clip(cos_j, 0.0, 1.0) * beyond_j
        round_k[round_j < 0] = 0.0
        musc_j = np.where(self._b_finger[seg], pj, -1)
        mj = np.maximum(musc_j, 0)
        cos_b = (off * self._b_normal[seg]).sum(-1) / np.maximum(thick, _EPS)
        musc_k = (
            self._j_muscle[mj]
            * muscle_profile(r, self._j_muscle_peak[mj], self._j_muscle_power[mj])
            * np.clip(-cos_b, 0.0, 1.0)
            * beyond
        )
        musc_k[musc_j < 0] = 0.0
        return {
            "seg": seg,
            "base": base,
            "zone": zone,
            "s": s,
            "offset": off,
            "ratio": r,
            "thickness": thick,
            "round_j": round_j,
            "round_k": round_k,
            "musc_j": musc_j,
            "musc_k": musc_k,
        }

    def _palm_setup(self, x: NDArray, seg: NDArray, bid: NDArray) -> None:
        """Covering of the palm by neighbouring rays (metacarpals and proximal phalanges).

        The rays are the chains of bones hanging on the carpus (one per metacarpal), in
        order across the hand (by the x of the metacarpal's end). A free point of a
        metacarpal or a proximal phalanx is mapped by every such bone near it: its own
        and its neighbours', each single-segment mapping weighted by the inverse cube of
        the point's distance to that bone's surface (normalised). For two bones the
        weight of the neighbour is ``t^3 / (t^3 + (1 - t)^3)`` with ``t`` the point's
        ratio on the virtual segment between the two bone surfaces: 0 on its own bone,
        1/2 midway (the in-between area of Fig. 7), and the areas along each segment
        (``t < palm_proximity``) are mapped by that segment alone. Every palm point uses
        the same bones and formula, so the mapping is continuous across the palm. Along a
        proximal phalanx the neighbours fade out past the web (``_WEB``), where the
        fingers part. The nearest neighbour's virtual segment gives the scale factor F.
        """
        topo = self.topology
        nbones = len(topo.names)
        carpal = [
            b
            for b in range(nbones)
            if topo.parent[b] >= 0 and not topo.chained[b] and topo.child[b] >= 0
        ]
        carpal.sort(key=lambda b: topo.end[b][0])  # radial to ulnar
        self.palm_bones = [topo.names[b] for b in carpal]
        depth = np.full(nbones, -1, np.int64)
        ray = np.full(nbones, -1, np.int64)
        for k, b in enumerate(carpal):
            d, c = 0, b
            while c >= 0:
                depth[c], ray[c] = d, k
                c, d = topo.child[c], d + 1
        cand = np.flatnonzero((depth >= 0) & (depth <= 1))
        # the hub's points in the areas of its joints (the carpus near the metacarpals)
        zone = self._main["zone"]
        hub_pt = np.isin(seg, self._hubs) & (zone >= 0)
        hub_pt &= ~self._jtwo[np.maximum(zone, 0)] & (self._jparent[np.maximum(zone, 0)] == seg)
        idx = np.flatnonzero((np.isin(seg, cand) | hub_pt) & (bid < 0))
        self._pairs = None
        self._extra = None
        if len(idx) == 0 or len(carpal) < 2:
            return
        xp, sp = x[idx], seg[idx]
        hub = hub_pt[idx]
        nray = len(carpal)
        members = [np.flatnonzero((ray == k) & (depth >= 0) & (depth <= 1)) for k in range(nray)]
        dist = np.stack(
            [
                np.min([self._surface_distance(xp, np.full(len(idx), b)) for b in mem], axis=0)
                for mem in members
            ],
            1,
        )
        dist = np.maximum(dist, _EPS)
        own_ray = np.where(hub, np.argmin(dist, axis=1), ray[sp])
        own = np.arange(nray)[None, :] == own_ray[:, None]
        t0 = self.skeleton.spec.palm_proximity
        d_own = dist[own]
        # the area along the own ray: neighbours act only beyond palm_proximity
        tt = d_own[:, None] / (d_own[:, None] + dist)
        infl = np.where(own, 1.0, smoothstep(tt / max(t0, _EPS)) * (tt / (1.0 - tt)) ** 3)
        r = self._main["ratio"][idx]
        deep = (depth[sp] >= 1) & ~hub
        fade = np.where(deep, 1.0 - smoothstep((r - _WEB[0]) / (_WEB[1] - _WEB[0])), 1.0)
        infl[~own] *= np.repeat(fade, nray - 1)
        w = infl / infl.sum(1, keepdims=True)
        # drop the negligible weights continuously (a cut at 1e-4 jumps by 1e-4 of the
        # difference between two rays' mappings, microns where they differ by centimetres)
        w = np.maximum(w - 1e-4 * w.max(axis=1, keepdims=True), 0.0)
        w /= w.sum(1, keepdims=True)
        # a hub point is mapped by the rays only (its own ray too); others add neighbours
        rows, cols = np.nonzero(w * (~own | hub[:, None]))
        pidx = idx[rows]
        pb = np.empty(len(rows), np.int64)
        for k in range(nray):
            at = cols == k
            pb[at] = self._assign_in(x[pidx[at]], members[k])
        self._pairs = {
            "idx": pidx,
            "w": w[rows, cols],
            "loc": self._localise(x[pidx], pb),
            "own_w": np.bincount(pidx, w[rows, cols], minlength=len(x)),
        }
        nbone = np.full(w.shape, -1, np.int64)
        nbone[rows, cols] = pb
        prow = np.full(w.shape, -1, np.int64)
        prow[rows, cols] = np.arange(len(rows))
        ploc = self._pairs["loc"]
        rr = np.arange(len(idx))
        # the own segment's localisation: the main one, or for a hub point its own ray's
        if len(rows) == 0:
            return
        own_col = np.argmax(own, axis=1)
        pr = np.maximum(prow[rr, own_col], 0)  # a pair only for hub points (where used)
        own_seg = np.where(hub, ploc["seg"][pr], sp)
        own_off = np.where(hub[:, None], ploc["offset"][pr], self._main["offset"][idx])
        own_r = np.where(hub, ploc["ratio"][pr], self._main["ratio"][idx])
        # the scale factor F of the nearest neighbour's virtual segment thickens the palm
        other = np.where(own, -1.0, w)
        order = np.argsort(-other, axis=1)
        top, second = order[:, 0], order[:, 1]
        w_own, w_nb = w[own], other[rr, top]
        d_rays = np.minimum(dist[own], dist[rr, top])
        # 1 midway between two rays; 0 where the nearest neighbour changes (continuous)
        low = np.minimum(w_own, w_nb)
        lead = np.clip(low - np.maximum(other[rr, second], 0.0), 0.0, None) / np.maximum(low, _EPS)
        lead *= 4.0 * w_own * w_nb / np.maximum((w_own + w_nb) ** 2, _EPS)
        # none on the carpus: it fades in along the metacarpals' first fifth, by the mean
        # ratio on the two segments (the same seen from either ray: continuous where the
        # proximal assignment switches from one metacarpal to the other)
        nb_r = ploc["ratio"][np.maximum(prow[rr, top], 0)]
        r_pair = np.where(prow[rr, top] >= 0, 0.5 * (own_r + nb_r), own_r)
        lead *= np.where(depth[own_seg] == 0, smoothstep(r_pair / 0.2), 1.0)
        has = (w_nb > 0.0) & (lead > 0.0)
        nb_row = prow[has, top[has]]
        idx, sp, lead, d_rays = idx[has], own_seg[has], lead[has], d_rays[has]
        if len(idx) == 0:
            return
        # the virtual segment joins the projections on the two segments (at their ratios)
        ps = x[idx] - own_off[has]
        pn = x[idx] - ploc["offset"][nb_row]
        nb = ploc["seg"][nb_row]
        v = pn - ps
        t = ((x[idx] - ps) * v).sum(-1) / np.maximum((v * v).sum(-1), _EPS)
        ov = x[idx] - (ps + t[:, None] * v)
        ev = np.linalg.norm(ov, axis=1)
        beyond = np.clip(d_rays / np.maximum(ev, _EPS), 0.0, 1.0)
        self._extra = {
            "idx": idx,
            "own": sp,
            "neighbour": nb,
            "ps": ps,
            "pn": pn,
            "bulge": (lead * beyond)[:, None] * ov,
        }

    def _project(self, x: NDArray, seg: NDArray) -> NDArray:
        """Orthogonal projection on each point's bone axis segment, clamped to it."""
        a, ab = self.topology.start[seg], self.topology.end[seg] - self.topology.start[seg]
        t = np.clip(((x - a) * ab).sum(-1) / (ab * ab).sum(-1), 0.0, 1.0)
        return a + t[:, None] * ab

    # --- mapping --------------------------------------------------------------------

    def _pose_data(self, angles: Mapping[str, ArrayLike] | None) -> dict[str, NDArray]:
        """Bone transforms, flexions, pivots and flexion ratios of one pose."""
        sk = self.skeleton
        vec = sk.angle_vector(angles)
        if vec.ndim != 1:
            raise ValueError("JLDMap maps one pose at a time (scalar angles)")
        world = np.concatenate([sk.transform_stack(vec), np.eye(4)[None]])
        flex = vec[self._flex_col]
        piv = np.where(self._piv_col >= 0, vec[np.maximum(self._piv_col, 0)], 0.0)
        return {
            "T": world[self._bone_joint],
            "flex": flex,
            "piv": piv,
            "fr": np.clip(flex / self._jmax, 0.0, 1.0),
        }

    def _map_local(self, x: NDArray, loc: dict[str, NDArray], pose: dict) -> NDArray:
        """Single-segment mapping of points ``x`` localised as ``loc``."""
        fr = pose["fr"]
        grow = loc["round_k"] * fr[np.maximum(loc["round_j"], 0)]
        grow += loc["musc_k"] * fr[np.maximum(loc["musc_j"], 0)]
        xt = x + grow[:, None] * loc["offset"]
        zone = loc["zone"]
        zj = np.maximum(zone, 0)
        s = np.where(zone >= 0, loc["s"], 0.0)
        c = np.take(self._jpos, zj, axis=0)
        v = _rotate(xt - c, np.take(self._jflex, zj, axis=0), np.radians(s * pose["flex"][zj]))
        v = _rotate(v, np.take(self._jpiv, zj, axis=0), np.radians(s * pose["piv"][zj]))
        v += c
        return _apply(np.take(pose["T"], loc["base"], axis=0), v)

    def _map(self, pose: dict) -> NDArray:
        x = self.points
        ex = self._extra
        if ex is not None:
            T = pose["T"]
            sp, nb = ex["own"], ex["neighbour"]
            vf = _apply(np.take(T, nb, axis=0), ex["pn"])
            vf -= _apply(np.take(T, sp, axis=0), ex["ps"])
            f = np.linalg.norm(ex["pn"] - ex["ps"], axis=1) / np.maximum(
                np.linalg.norm(vf, axis=1), _EPS
            )
            x = x.copy()
            x[ex["idx"]] += (f**self.skeleton.spec.palm_bulge - 1.0)[:, None] * ex["bulge"]
        out = self._map_local(x, self._main, pose)
        pairs = self._pairs
        if pairs is not None:
            out *= (1.0 - pairs["own_w"])[:, None]
            y = self._map_local(x[pairs["idx"]], pairs["loc"], pose) * pairs["w"][:, None]
            for k in range(3):
                out[:, k] += np.bincount(pairs["idx"], y[:, k], minlength=len(x))
        fixed = self._fixed
        if len(fixed):
            T = np.take(pose["T"], self.bone_id[fixed], axis=0)
            out[fixed] = _apply(T, self.points[fixed])
        return out

    def displacement(self, angles: Mapping[str, ArrayLike] | None = None) -> NDArray[np.float64]:
        """Displacement of every point from rest to the pose, shape (N, 3).

        Parameters
        ----------
        angles : mapping of str to float, optional
            Degrees by angle name; omitted angles stay at 0.

        Returns
        -------
        ndarray, shape (N, 3)
            Exactly 0 at the rest angles.

        Raises
        ------
        RigError
            On an unknown angle or one outside its limits.
        """
        return self._map(self._pose_data(angles)) - self._rest

    def map(self, angles: Mapping[str, ArrayLike] | None = None) -> NDArray[np.float64]:
        """Posed positions of the points, shape (N, 3); the rest points at rest angles."""
        return self.points + self.displacement(angles)

    @cached_property
    def zone_joint(self) -> NDArray[np.int64]:
        """Joint whose areas hold each point (index in ``skeleton.joint_names``).

        -1 marks the buffer of a segment; fixed points get their bone's joint.
        """
        z = self._main["zone"].copy()
        fixed = self.bone_id >= 0
        z[fixed] = self._bjoint[self.bone_id[fixed]]
        return z

    @property
    def ratio(self) -> NDArray[np.float64]:
        """Ratio of each point along its segment (0 proximal joint plane, 1 distal)."""
        return self._main["ratio"]

    @property
    def thickness(self) -> NDArray[np.float64]:
        """Distance of each point from its projection on its segment (m)."""
        return self._main["thickness"]

    @property
    def weight(self) -> NDArray[np.float64]:
        """Fraction ``s`` of its zone joint's rotation each point takes (see module doc)."""
        return self._main["s"]
