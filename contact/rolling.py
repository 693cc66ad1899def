"""A free ball that rolls: its rigid turn taken into its placement.

The contact solve is linear: a free body's rigid rotation is the infinitesimal one,
``u = t + omega x r``, which moves a point along the tangent of its circle and so
stretches the body by about ``|omega|^2 / 2``: a ball rolled 11 degrees between two
fingertips grows by 2 % of its radius at the contacts, as much as it is pressed. So, as
a co-rotational method does, a free ball that turned past :data:`ROLL` in a frame is
placed anew, turned by the finite rotation of ``omega`` (Rodrigues) and moved by ``t``,
and the frame is solved again from there (the history re-expressed from the new
placement, :meth:`contact.solver.anchors.Anchors.displaced`): the ball's stiffness is
the same, turned, and what the solve is left with is the small rest of the turn.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["MAX_ROLLS", "ROLL", "turned_placement"]

#: A free ball's rigid turn (rad) in a frame past which it is placed anew and the frame
#: solved again: half the largest turn the linear model is trusted with
#: (:data:`contact.solver.held.MAX_TURN`).
ROLL = 0.05
#: Solves of a frame again after a placement anew.
MAX_ROLLS = 3


def turned_placement(
    points: NDArray[np.float64], t: NDArray[np.float64], omega: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The 4x4 placement that turns ``points`` by the finite rotation ``omega`` and moves them.

    About their centroid ``c``: ``x -> R (x - c) + c + t``, ``R`` the rotation by
    ``|omega|`` about ``omega`` (Rodrigues).
    """
    c = np.asarray(points, dtype=np.float64).mean(axis=0)
    angle = float(np.linalg.norm(omega))
    rot = np.eye(3)
    if angle > 0:
        k = np.asarray(omega, dtype=np.float64) / angle
        kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
        rot = rot + np.sin(angle) * kx + (1.0 - np.cos(angle)) * kx @ kx
    out = np.eye(4)
    out[:3, :3] = rot
    out[:3, 3] = c + np.asarray(t, dtype=np.float64) - rot @ c
    return out
