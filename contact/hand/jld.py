"""Joint-dependent local deformations (JLD): the skin and flesh mapping.

Every point of the hand at rest (skin vertex or flesh node, volume nodes included) is
localised once against the skeleton, then mapped for any pose by :meth:`JLDMap.map`. The
steps follow Magnenat-Thalmann, Laperrière and Thalmann (1988), sections 3 to 6; the
segments and joint planes are :mod:`contact.hand.jldframes`', the localisation
:mod:`contact.hand.jldlocalise`'s, the palm's covering :mod:`contact.hand.jldpalm`'s:

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
    as the nodes fixed to it do. (The paper interpolates by the ratio alone and keeps the
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
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .jldframes import EPS, JointFrames, apply, rotate
from .jldlocalise import BoneSurfaces, localise
from .jldpalm import palm_covering
from .skeleton import Skeleton

__all__ = ["JLDMap"]


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
        self.frames = frames = JointFrames(skeleton)
        self.topology = topo = frames.topology
        if bid.max(initial=-1) >= len(topo.names) or bid.min(initial=-1) < -1:
            raise ValueError(f"bone_id must lie in -1..{len(topo.names) - 1}")
        self.points = x
        self.bone_id = bid
        self._fixed = np.flatnonzero(bid >= 0)  # the bone nodes, moved rigidly
        ref_x, ref_id = (x, bid) if reference is None else reference
        self._surfaces = BoneSurfaces(frames, ref_x, ref_id)
        seg = frames.assign(x, bid)
        self.segment = seg
        self._main = localise(frames, self._surfaces, x, seg)
        self.palm_bones, self._pairs, self._extra = palm_covering(
            frames, self._surfaces, self._main, x, seg, bid, skeleton.spec.palm_proximity
        )
        self._rest = self._map(self._pose_data({}))

    def _pose_data(self, angles: Mapping[str, ArrayLike] | None) -> dict[str, NDArray]:
        """Bone transforms, flexions, pivots and flexion ratios of one pose."""
        sk = self.skeleton
        vec = sk.angle_vector(angles)
        if vec.ndim != 1:
            raise ValueError("JLDMap maps one pose at a time (scalar angles)")
        world = np.concatenate([sk.transform_stack(vec), np.eye(4)[None]])
        flex = vec[self.frames.flex_col]
        piv = np.where(self.frames.piv_col >= 0, vec[np.maximum(self.frames.piv_col, 0)], 0.0)
        return {
            "T": world[self.frames.bone_joint],
            "flex": flex,
            "piv": piv,
            "fr": np.clip(flex / self.frames.jmax, 0.0, 1.0),
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
        c = np.take(self.frames.jpos, zj, axis=0)
        v = rotate(xt - c, np.take(self.frames.jflex, zj, axis=0), np.radians(s * pose["flex"][zj]))
        v = rotate(v, np.take(self.frames.jpiv, zj, axis=0), np.radians(s * pose["piv"][zj]))
        v += c
        return apply(np.take(pose["T"], loc["base"], axis=0), v)

    def _map(self, pose: dict) -> NDArray:
        x = self.points
        ex = self._extra
        if ex is not None:
            T = pose["T"]
            sp, nb = ex["own"], ex["neighbour"]
            vf = apply(np.take(T, nb, axis=0), ex["pn"])
            vf -= apply(np.take(T, sp, axis=0), ex["ps"])
            f = np.linalg.norm(ex["pn"] - ex["ps"], axis=1) / np.maximum(
                np.linalg.norm(vf, axis=1), EPS
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
            out[fixed] = apply(T, self.points[fixed])
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
        z[fixed] = self.frames.bjoint[self.bone_id[fixed]]
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
