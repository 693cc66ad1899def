"""Objects associated with a joint for a time: they follow it.

The OBJECTS command of Magnenat-Thalmann, Laperrière and Thalmann 1988: ``OBJECTS APPLE
INDEX RIGHT KNUCKLES2 5 10``: until time 5 the apple is drawn at its initial place, from 5
to 10 it follows the motion of the joint, after 10 it stays where it was at 10 (its final
place). The basis attached to the joint has its origin at the joint, x along the flexion
axis, y along the joint's segment and z their cross product: the posed frame of
:meth:`Skeleton.joint_frames`. The object's rigid transform at time ``t`` is::

    T(t) = F(clip(t, start, stop)) @ inv(F(start))

with ``F(t)`` the joint's frame in the pose at time ``t``: the identity before ``start``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import RigError
from .skeleton import Skeleton

__all__ = ["ObjectAssociation", "transform_points"]

AnglesAt = Callable[[float], Mapping[str, float]]


@dataclass(frozen=True)
class ObjectAssociation:
    """An object that follows a joint between two times.

    Attributes
    ----------
    name : str
        The object's identifier.
    joint : str
        The joint it follows (a joint name of the skeleton).
    start, stop : float
        Times of the association, ``start <= stop``.
    """

    name: str
    joint: str
    start: float
    stop: float

    def check(self, skeleton: Skeleton) -> None:
        """Raise :class:`RigError` naming the object for an unknown joint or bad times."""
        if self.joint not in skeleton.joint_names:
            raise RigError(
                f"object {self.name}: unknown joint {self.joint!r} (joints: "
                f"{', '.join(skeleton.joint_names)})"
            )
        if not (np.isfinite(self.start) and np.isfinite(self.stop)) or self.stop < self.start:
            raise RigError(
                f"object {self.name}: association times must be finite with start <= stop "
                f"(got {self.start:g}, {self.stop:g})"
            )

    def transform(self, skeleton: Skeleton, angles_at: AnglesAt, time: float) -> NDArray:
        """Rigid 4x4 transform of the object from its initial place at ``time``.

        Parameters
        ----------
        skeleton : Skeleton
        angles_at : callable
            ``time -> angles`` (degrees by name), e.g. :meth:`Keyframes.pose`.
        time : float

        Returns
        -------
        ndarray, shape (4, 4)
        """
        self.check(skeleton)
        if time <= self.start:
            return np.eye(4)
        t = min(time, self.stop)
        f0 = skeleton.joint_frames(angles_at(self.start))[self.joint]
        f1 = skeleton.joint_frames(angles_at(t))[self.joint]
        return f1 @ np.linalg.inv(f0)


def transform_points(points: ArrayLike, transform: ArrayLike) -> NDArray[np.float64]:
    """Apply a 4x4 rigid transform to points ``(n, 3)``."""
    x = np.asarray(points, dtype=np.float64)
    t = np.asarray(transform, dtype=np.float64)
    return x @ t[:3, :3].T + t[:3, 3]
