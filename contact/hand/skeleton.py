"""The hand skeleton: joints with flexion and pivot angles, limits, forward kinematics.

As in Magnenat-Thalmann, Laperrière and Thalmann (1988, sections 2 and 9), the skeleton
is a tree of joints, each moving the bone distal to it. Every joint has a flexion angle; the
finger bases, the thumb base and the wrist also have a pivot angle (abduction, a rotation
about an axis fixed in the parent, applied after the flexion). Angles are in degrees, 0 at
the rest pose of the rig file, positive by the right-hand rule about the joint's axes.

Forward kinematics gives, for every bone, the rigid transform from its rest position to its
posed position::

    T_joint = T_parent @ Trans(p) @ R(pivot_axis, pivot) @ R(flexion_axis, flexion) @ Trans(-p)

with ``p`` the joint's rest position and the axes taken in the rest frame. Angles may be
arrays (one value per pose); transforms then have shape ``(*batch, 4, 4)``.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import RigError
from .rigspec import ROOT, BoneSpec, JointSpec, Primitive, RigSpec, read_rig

__all__ = ["PIVOT_SUFFIX", "Skeleton", "load_skeleton", "rotation_matrices"]

#: The pivot angle of joint ``j`` is named ``j + PIVOT_SUFFIX``; its flexion is named ``j``.
PIVOT_SUFFIX = "_pivot"
_TOL = 1e-9


def rotation_matrices(axes: ArrayLike, degrees: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrices about unit axes by angles (Rodrigues), vectorised.

    Parameters
    ----------
    axes : array_like, shape (..., 3)
        Unit rotation axes.
    degrees : array_like, shape (...)
        Angles, right-hand rule; broadcast against ``axes[..., 0]``.

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    a = np.asarray(axes, dtype=np.float64)
    t = np.radians(np.asarray(degrees, dtype=np.float64))
    shape = np.broadcast_shapes(a.shape[:-1], t.shape)
    a = np.broadcast_to(a, (*shape, 3))
    t = np.broadcast_to(t, shape)[..., None, None]
    k = _skew(a)
    return np.eye(3) + np.sin(t) * k + (1.0 - np.cos(t)) * (k @ k)


def _skew(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """Cross-product matrices ``(..., 3, 3)`` of vectors ``(..., 3)``: ``k v = a x v``."""
    k = np.zeros((*a.shape[:-1], 3, 3))
    k[..., 0, 1], k[..., 0, 2], k[..., 1, 2] = -a[..., 2], a[..., 1], -a[..., 0]
    k -= np.swapaxes(k, -1, -2)
    return k


def _cross_matrices(axes: NDArray[np.float64]) -> dict[str, NDArray[np.float64]]:
    """Cross-product matrices ``k`` of unit axes (n, 3) and their squares ``kk``.

    ``I + sin(t) k + (1 - cos(t)) kk`` is then :func:`rotation_matrices` term by term.
    """
    k = _skew(axes)
    return {"k": k, "kk": k @ k}


class Skeleton:
    """Joints, bones and skin primitives of a hand rig, with forward kinematics.

    Parameters
    ----------
    spec : RigSpec
        A validated rig (see :func:`contact.hand.rigspec.read_rig`).

    Examples
    --------
    >>> sk = load_skeleton("meshes/hand/rig.toml")  # doctest: +SKIP
    >>> T = sk.forward_kinematics({"index_mcp": 45.0})  # doctest: +SKIP
    >>> T["index_proximal"].shape  # doctest: +SKIP
    (4, 4)
    """

    def __init__(self, spec: RigSpec) -> None:
        self.spec = spec
        order: list[str] = []
        depth = {ROOT: -1}
        pending = dict(spec.joints)
        while pending:  # parents first
            ready = [n for n, j in pending.items() if j.parent in depth]
            for n in ready:
                depth[n] = depth[pending.pop(n).parent] + 1
                order.append(n)
        self._order = order
        self._depth = np.array([depth[n] for n in order])

    # --- names and limits -------------------------------------------------------------

    @property
    def joints(self) -> dict[str, JointSpec]:
        """Joints by name, parents before children."""
        return dict(self._joints)

    @cached_property
    def _joints(self) -> dict[str, JointSpec]:
        return {n: self.spec.joints[n] for n in self._order}

    @property
    def bones(self) -> dict[str, BoneSpec]:
        """Bones by name, in file order."""
        return self.spec.bones

    @property
    def primitives(self) -> tuple[Primitive, ...]:
        """Skin metaball primitives, in their joints' frames."""
        return self.spec.primitives

    @property
    def joint_names(self) -> list[str]:
        """Joint names, parents before children."""
        return list(self._order)

    @property
    def bone_names(self) -> list[str]:
        """Bone names, in file order (a bone's index here is its ``bone_id``)."""
        return list(self.spec.bones)

    @cached_property
    def limits(self) -> dict[str, tuple[float, float]]:
        """Limits (degrees) of every angle: flexion ``j`` and pivot ``j + '_pivot'``."""
        out = {}
        for n in self._order:
            j = self.spec.joints[n]
            out[n] = j.flexion_limits
            if j.pivot_limits is not None:
                out[n + PIVOT_SUFFIX] = j.pivot_limits
        return out

    @property
    def angle_names(self) -> list[str]:
        """Names of every angle, flexions and pivots, parents first."""
        return list(self.limits)

    def bone_lengths(self) -> dict[str, float]:
        """Length of each bone's axis (m)."""
        return {n: b.length for n, b in self.spec.bones.items()}

    # --- kinematics -------------------------------------------------------------------

    @cached_property
    def _table(self) -> dict[str, NDArray]:
        """Per angle its limits, per joint its axes, position, angle columns and parent."""
        names = list(self.limits)
        col = {n: i for i, n in enumerate(names)}
        joints = [self.spec.joints[n] for n in self._order]
        index = {n: i for i, n in enumerate(self._order)}
        return {
            "col": col,
            "lo": np.array([self.limits[n][0] for n in names]) - _TOL,
            "hi": np.array([self.limits[n][1] for n in names]) + _TOL,
            "flex_col": np.array([col[j.name] for j in joints]),
            "piv_col": np.array([col.get(j.name + PIVOT_SUFFIX, -1) for j in joints]),
            "pos": np.stack([j.position for j in joints]),
            # Rodrigues' cross-product matrices K and K @ K of the flexion, then pivot, axes
            **_cross_matrices(
                np.concatenate(
                    [
                        np.stack([j.flexion_axis for j in joints]),
                        np.stack(
                            [
                                j.pivot_axis if j.pivot_axis is not None else [0, 0, 1.0]
                                for j in joints
                            ]
                        ),
                    ]
                )
            ),
            "parent": np.array([index.get(j.parent, -1) for j in joints]),
            "levels": [np.flatnonzero(self._depth == d) for d in range(int(self._depth.max()) + 1)],
        }

    def angle_vector(self, angles: Mapping[str, ArrayLike] | None) -> NDArray[np.float64]:
        """Validated angles as one array, columns in :attr:`angle_names` order.

        Parameters
        ----------
        angles : mapping of str to float or array_like, optional
            Degrees, by angle name; missing angles are 0 (rest).

        Returns
        -------
        ndarray, shape (*batch, n_angles)
            Every angle, broadcast to the common batch shape.

        Raises
        ------
        RigError
            Naming an unknown joint angle, an angle that is not finite, or one outside
            its joint's limits (the first such angle in :attr:`angle_names` order).
        """
        tab = self._table
        col = tab["col"]
        values = {}
        for name, v in (angles or {}).items():
            if name not in col:
                raise RigError(
                    f"unknown joint angle {name!r} (flexions are named after the joint, "
                    f"pivots '<joint>{PIVOT_SUFFIX}'; joints: {', '.join(self._order)})"
                )
            values[col[name]] = np.asarray(v, dtype=np.float64)
        shapes = {v.shape for v in values.values()}
        shape = shapes.pop() if len(shapes) == 1 else np.broadcast_shapes(*shapes)
        vec = np.zeros((*shape, len(col)))
        for i, v in values.items():
            vec[..., i] = v
        flat = vec.reshape(-1, len(col))
        bad = ~np.isfinite(flat) | (flat < tab["lo"]) | (flat > tab["hi"])
        if bad.any():
            self._angle_error(flat, bad)
        return vec

    def _angle_error(self, flat: NDArray, bad: NDArray) -> None:
        """Raise the :class:`RigError` of the first bad angle column."""
        names = list(self.limits)
        i = int(np.flatnonzero(bad.any(axis=0))[0])
        name, (lo, hi) = names[i], self.limits[names[i]]
        if not np.isfinite(flat[:, i]).all():
            raise RigError(f"joint angle {name} is not finite")
        value = flat[bad[:, i], i][0]
        raise RigError(f"joint angle {name} = {value:g} deg is outside its limits [{lo:g}, {hi:g}]")

    def check_angles(self, angles: Mapping[str, ArrayLike] | None) -> dict[str, NDArray]:
        """Validate angles against names and limits; missing angles are 0 (rest).

        Parameters
        ----------
        angles : mapping of str to float or array_like, optional
            Degrees, by angle name (:attr:`angle_names`).

        Returns
        -------
        dict of str to ndarray
            Every angle, broadcast to the common batch shape.

        Raises
        ------
        RigError
            Naming an unknown joint angle, or an angle outside its joint's limits.
        """
        vec = self.angle_vector(angles)
        return {n: vec[..., i] for i, n in enumerate(self.limits)}

    def transform_stack(self, vector: NDArray[np.float64]) -> NDArray[np.float64]:
        """Rigid transforms (rest to posed) of the joints from an :meth:`angle_vector`.

        Parameters
        ----------
        vector : ndarray, shape (*batch, n_angles)
            Validated angles (degrees), columns in :attr:`angle_names` order.

        Returns
        -------
        ndarray, shape (*batch, n_joints, 4, 4)
            In :attr:`joint_names` order.
        """
        tab = self._table
        shape = vector.shape[:-1]
        pos = tab["pos"]
        n = len(pos)
        piv_col = tab["piv_col"]
        piv_deg = np.where(piv_col >= 0, vector[..., np.maximum(piv_col, 0)], 0.0)
        t = np.radians(np.concatenate([vector[..., tab["flex_col"]], piv_deg], axis=-1))
        t = t[..., None, None]
        r = np.eye(3) + np.sin(t) * tab["k"] + (1.0 - np.cos(t)) * tab["kk"]  # Rodrigues
        rot = r[..., n:, :, :] @ r[..., :n, :, :]  # (*batch, n_joints, 3, 3)
        local = np.zeros((*shape, len(pos), 4, 4))
        local[..., :3, :3] = rot
        local[..., :3, 3] = pos - np.einsum("...ij,...j->...i", rot, pos)
        local[..., 3, 3] = 1.0
        world = np.empty_like(local)
        parents = tab["parent"]
        for d, at in enumerate(tab["levels"]):  # one batched product per tree level
            if d == 0:
                world[..., at, :, :] = local[..., at, :, :]
            else:
                world[..., at, :, :] = world[..., parents[at], :, :] @ local[..., at, :, :]
        return world

    def joint_transforms(
        self, angles: Mapping[str, ArrayLike] | None = None
    ) -> dict[str, NDArray[np.float64]]:
        """Rigid transform (rest to posed) of what each joint carries, and of the root.

        Parameters
        ----------
        angles : mapping of str to float or array_like, optional
            Degrees by angle name; omitted angles stay at 0.

        Returns
        -------
        dict of str to ndarray, shape (*batch, 4, 4)
            Keyed by joint name, plus ``"root"`` (the identity).
        """
        vec = self.angle_vector(angles)
        world = self.transform_stack(vec)
        out = {n: world[..., i, :, :] for i, n in enumerate(self._order)}
        out[ROOT] = np.broadcast_to(np.eye(4), (*vec.shape[:-1], 4, 4))
        return out

    def forward_kinematics(
        self, angles: Mapping[str, ArrayLike] | None = None
    ) -> dict[str, NDArray[np.float64]]:
        """Rigid transform of every bone from its rest to its posed position.

        Parameters
        ----------
        angles : mapping of str to float or array_like, optional
            Degrees by angle name (flexion ``"index_pip"``, pivot ``"index_mcp_pivot"``);
            omitted angles stay at 0. Arrays give a batch of poses.

        Returns
        -------
        dict of str to ndarray, shape (*batch, 4, 4)
            Keyed by bone name: ``x_posed = T[:3, :3] @ x_rest + T[:3, 3]``.

        Raises
        ------
        RigError
            On an unknown angle name or an angle outside its limits.
        """
        jt = self.joint_transforms(angles)
        return {n: jt[b.joint] for n, b in self.spec.bones.items()}

    def joint_frames(
        self, angles: Mapping[str, ArrayLike] | None = None
    ) -> dict[str, NDArray[np.float64]]:
        """Posed frame of each joint as a 4x4 (columns x, y, z axes and origin), and root."""
        jt = self.joint_transforms(angles)
        out = {}
        for n, t in jt.items():
            rest = np.eye(4)
            if n != ROOT:
                j = self.spec.joints[n]
                rest[:3, :3], rest[:3, 3] = j.frame, j.position
            out[n] = t @ rest
        return out


def load_skeleton(path: str | os.PathLike) -> Skeleton:
    """Read, validate and build the skeleton of a rig file.

    Parameters
    ----------
    path : str or path-like
        A rig TOML file, e.g. ``meshes/hand/rig.toml``.

    Returns
    -------
    Skeleton

    Raises
    ------
    RigError
        One line naming the file and key path of the first problem.
    """
    return Skeleton(read_rig(path))
