"""Posing the hand: bone transforms and the JLD-mapped flesh for given joint angles (step 1).

The contact solver poses the hand, then builds the FE stiffness on the posed mesh and
prescribes the bone nodes::

    from contact import load_hand, pose_hand

    hand = load_hand("coarse")
    pose = pose_hand(hand, {"index_mcp": 30.0, "index_pip": 20.0})
    pose.points          # (N, 3) posed flesh nodes (JLD mapping, bones rigid)
    pose.transforms      # bone name -> 4x4 rest-to-posed transform
    pose.mesh()          # fem.Mesh on the posed points (validated: positive volumes)

:class:`HandPoser` localises the nodes once and then poses vectorised over nodes;
:func:`pose_hand` keeps one poser per hand. A pose that inverts a tetrahedron raises
:class:`~contact.errors.PoseError` naming the joint and the element (``check=False``
returns the pose with :attr:`Pose.inverted` filled instead). Where the JLD mapping
(:mod:`contact.hand.jld`) degrades tetrahedra, the flesh relaxer
(:class:`~contact.hand.relax.FleshRelaxer`) corrects the free nodes around them.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

import fem

from ..errors import PoseError
from .jld import JLDMap
from .quality import tet_quality, tet_volumes
from .relax import FleshRelaxer
from .shipped import Hand
from .skeleton import PIVOT_SUFFIX

__all__ = ["HandPoser", "Pose", "pose_hand"]


@dataclass(frozen=True)
class Pose:
    """The hand in one pose.

    Attributes
    ----------
    angles : dict of str to float
        Every angle (degrees), omitted ones 0.
    points : ndarray, shape (N, 3)
        Posed flesh nodes.
    displacement : ndarray, shape (N, 3)
        ``points - rest``; exactly 0 at rest. Rows of bone nodes are their prescribed
        displacements (``Uk`` of the seed).
    transforms : dict of str to ndarray (4, 4)
        Rest-to-posed rigid transform of every bone.
    tets : ndarray, shape (M, 4)
        The flesh tetrahedra (for :meth:`mesh` and the quality).
    regions : ndarray, shape (M,)
    inverted : ndarray of int
        Tetrahedra with a non-positive volume (empty unless posed with ``check=False``).
    relaxed : int
        Free nodes the :class:`FleshRelaxer` moved off their JLD positions.
    correction : ndarray, shape (N, 3), optional
        ``points`` minus their JLD mapping: non-zero on the relaxed nodes alone (the
        next frame's warm start, see :meth:`HandPoser.pose`).
    """

    angles: dict[str, float]
    points: NDArray[np.float64]
    displacement: NDArray[np.float64]
    transforms: dict[str, NDArray[np.float64]]
    tets: NDArray[np.int64]
    regions: NDArray[np.int64]
    inverted: NDArray[np.int64]
    relaxed: int = 0
    correction: NDArray[np.float64] | None = None

    @cached_property
    def quality(self) -> NDArray[np.float64]:
        """Shape quality of every tetrahedron (see :func:`tet_quality`)."""
        return tet_quality(self.points, self.tets)

    @property
    def min_quality(self) -> float:
        """Worst tetrahedron quality of the pose."""
        return float(self.quality.min())

    def mesh(self) -> fem.Mesh:
        """The posed flesh as a validated :class:`fem.Mesh` (raises on inverted cells)."""
        return fem.Mesh(self.points, {"tetra": self.tets}, {"tetra": self.regions})


class HandPoser:
    """Poses one hand: JLD mapping of its flesh (and skin) localised once.

    Parameters
    ----------
    hand : Hand
        From :func:`contact.load_hand`.
    relax : bool
        Relax the flesh around the tetrahedra the JLD mapping degrades
        (:class:`FleshRelaxer`); False: the JLD mapping alone.

    Examples
    --------
    >>> poser = HandPoser(load_hand("coarse"))  # doctest: +SKIP
    >>> pose = poser.pose({"index_mcp": 30.0})  # doctest: +SKIP
    >>> skin = poser.skin_points({"index_mcp": 30.0})  # doctest: +SKIP
    """

    def __init__(self, hand: Hand, relax: bool = True) -> None:
        self.hand = hand
        self.flesh_map = JLDMap(hand.skeleton, hand.flesh.points, hand.bone_id)
        self._tets = np.ascontiguousarray(hand.flesh.cells["tetra"])
        self._regions = np.asarray(hand.flesh.regions["tetra"])
        self.relaxer = (
            FleshRelaxer(hand.flesh.points, self._tets, hand.bone_id >= 0, bone_id=hand.bone_id)
            if relax
            else None
        )

    @cached_property
    def skin_map(self) -> JLDMap:
        """JLD mapping of the skin surface's vertices (``hand.skin``)."""
        h = self.hand
        return JLDMap(
            h.skeleton,
            np.asarray(h.skin.points),
            reference=(h.flesh.points, h.bone_id),
        )

    def pose(
        self,
        angles: Mapping[str, float] | None = None,
        check: bool = True,
        start: Pose | None = None,
    ) -> Pose:
        """Pose the flesh for joint angles.

        Parameters
        ----------
        angles : mapping of str to float, optional
            Degrees by angle name; omitted angles stay at 0 (rest).
        check : bool
            Raise :class:`PoseError` if a tetrahedron inverts; otherwise record them.
        start : Pose, optional
            A nearby pose, typically the previous frame of a sequence (a warm start): its
            :attr:`Pose.correction` added to this pose's mapping is one more start of the
            relaxer's first pass, used on each patch the mapping degrades where its energy
            is lowest (:meth:`FleshRelaxer.relax_quality`). The mapping and the nodes it
            leaves in place do not depend on it; at rest the pose is still the identity.

        Returns
        -------
        Pose

        Raises
        ------
        RigError
            An unknown angle, or one outside its limits.
        PoseError
            With ``check``, naming the joint and the first inverted element.
        ValueError
            A ``start`` pose of another mesh.
        """
        sk = self.hand.skeleton
        full = {k: float(v) for k, v in sk.check_angles(angles).items()}
        rest = self.hand.flesh.points
        points = rest + self.flesh_map.displacement(full)
        tf = sk.forward_kinematics(full)
        moved = 0
        correction = None
        if self.relaxer is not None:
            warm = None
            if start is not None and start.correction is not None:
                if start.correction.shape != points.shape:
                    raise ValueError(
                        f"start: a pose of another mesh ({len(start.correction)} nodes; "
                        f"this hand's flesh has {len(points)})"
                    )
                warm = points + self._carried(start, tf)
            mapped = points
            points, moved, q = self.relaxer.relax_quality(points, warm)
            correction = points - mapped
        else:
            q = tet_quality(points, self._tets)
        disp = points - rest
        inverted = np.flatnonzero(q <= 0.0)
        if check and len(inverted):
            raise self.inversion_error(full, inverted)
        return Pose(full, points, disp, tf, self._tets, self._regions, inverted, moved, correction)

    def _carried(
        self, start: Pose, transforms: Mapping[str, NDArray[np.float64]]
    ) -> NDArray[np.float64]:
        """``start``'s correction carried to a pose of bone ``transforms``: the warm start.

        A correction is a local reshaping of the flesh around a joint: it turns with the
        node's segment (its JLD assignment). Each node's correction is turned by its
        segment's rotation from ``start`` to this pose: a better start than the correction
        taken as it is (fewer Newton steps, the same qualities). Not by the mapping's own
        local rotation: the mapping is distorted exactly where there is a correction.
        """
        names = self.flesh_map.topology.names
        turn = np.stack([transforms[b][:3, :3] @ start.transforms[b][:3, :3].T for b in names])
        return np.einsum("nij,nj->ni", turn[self.flesh_map.segment], start.correction)

    def skin_points(self, angles: Mapping[str, float] | None = None) -> NDArray[np.float64]:
        """Posed vertices of the skin surface ``hand.skin``, shape (n_skin, 3)."""
        return self.skin_map.map(angles)

    def culprit(self, angles: Mapping[str, float], element: int) -> str:
        """The joint blamed for an inverted element.

        Each bent joint in turn is put back to rest (flexion and pivot) and the element's
        four nodes re-mapped; the joint whose return gives the element the largest volume
        is the culprit (ties go to the most bent).
        """
        h = self.hand
        nodes = self._tets[element]
        m = JLDMap(h.skeleton, h.flesh.points[nodes], h.bone_id[nodes], (h.flesh.points, h.bone_id))
        bent = {
            j: abs(angles.get(j, 0.0)) + abs(angles.get(j + PIVOT_SUFFIX, 0.0))
            for j in h.skeleton.joint_names
        }
        best, best_key = h.skeleton.joint_names[0], (-np.inf, -np.inf)
        for j, b in bent.items():
            if b == 0.0:
                continue
            trial = dict(angles)
            trial[j] = 0.0
            if j + PIVOT_SUFFIX in trial:
                trial[j + PIVOT_SUFFIX] = 0.0
            v = tet_volumes(m.map(trial), np.arange(4)[None])[0]
            if (v, b) > best_key:
                best, best_key = j, (v, b)
        return best

    def inversion_error(self, angles: Mapping[str, float], inverted: NDArray) -> PoseError:
        """The :class:`PoseError` for a pose that inverts ``inverted`` elements."""
        first = int(inverted[0])
        joint = self.culprit(angles, first)
        nodes = self._tets[first]
        fixed = self.hand.bone_id[nodes]
        names = self.hand.skeleton.bone_names
        bones = sorted({names[b] for b in fixed if b >= 0})
        how = (
            f"all four nodes are fixed to bones ({', '.join(bones)}): the mesh cannot take "
            "this rotation"
            if (fixed >= 0).all()
            else f"nodes {nodes.tolist()}"
        )
        bent = angles.get(joint, 0.0)
        return PoseError(
            f"pose inverts {len(inverted)} tetrahedra; the first, element {first} "
            f"({how}), at joint {joint} (flexion {bent:g} deg)",
            joint,
            first,
            tuple(int(i) for i in inverted),
        )


def pose_hand(hand: Hand, angles: Mapping[str, float] | None = None, check: bool = True) -> Pose:
    """Pose a hand for joint angles (degrees); see :meth:`HandPoser.pose`.

    The hand's :class:`HandPoser` is built on the first call and kept with the hand
    (:attr:`Hand.derived`), so posing frame after frame costs only the mapping.
    """
    poser = hand.derived.get("poser")
    if poser is None:
        poser = hand.derived["poser"] = HandPoser(hand)
    return poser.pose(angles, check=check)
