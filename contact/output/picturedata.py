"""What a frame's pictures are drawn from: each body's surface and contacts, the frame's forces.

The data both :mod:`contact.output.pictures` (which makes it and renders it) and
:mod:`contact.output.drawing` (which draws its pieces) read: below both, so that neither
imports the other.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from .forces import FrameForces
from .status import StatusMarkers

if TYPE_CHECKING:
    import pyvista

__all__ = ["BodyPicture", "Picture", "held_body"]


@dataclass
class BodyPicture:
    """A body as a frame's picture draws it.

    Attributes
    ----------
    name : str
    surface : pyvista.PolyData
        The deformed outer surface, point data ``von_mises`` (Pa, nodal average) and,
        for the held body, ``contact_pressure`` (Pa).
    top : float
        The body's largest cell-average von Mises stress in the frame (Pa).
    noise : float
        Stress below which the body's stress is round-off (Pa).
    contact : ndarray (k, 3)
        Deformed positions of its nodes in contact.
    points : ndarray (N, 3)
        All its deformed nodal positions (for the framing).
    pushes : ndarray (k,)
        The normal contact forces of the nodes of ``contact`` (N).
    """

    name: str
    surface: pyvista.PolyData
    top: float
    noise: float
    contact: NDArray[np.float64]
    points: NDArray[np.float64]
    pushes: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))


@dataclass
class Picture:
    """What a frame's pictures need.

    Attributes
    ----------
    index : int
        Frame number (the ``NNNN`` of ``frame_NNNN.png``).
    time : float
        Frame time.
    bodies : list of BodyPicture
    planes : list of (str, ndarray (3,), ndarray (3,))
        Name, a point and the unit normal of each plane at the frame.
    forces : FrameForces
        The pushes of the fingers and planes, the grip force.
    verdict : dict
        ``{"realistic": bool, "reason": str}`` of ``summary.json``.
    converged : bool
    stop_reason : str
    status : StatusMarkers or None
        The stick and slip contact nodes where the frame has friction (its
        ``status_NNNN.png``), else None.
    pressure : str or None
        The body whose contact pressure the frame's ``pressure_NNNN.png`` draws (the
        held one, where it touches), else None.
    held : str or None
        The held body (:func:`held_body`), the same in every frame of a run: its view
        carries the force arrows and the framing centres on it. None: the renderer
        names it from the frame's points by the same rule.
    """

    index: int
    time: float
    bodies: list[BodyPicture]
    planes: list[tuple[str, NDArray[np.float64], NDArray[np.float64]]]
    forces: FrameForces
    verdict: dict = field(default_factory=lambda: {"realistic": True, "reason": ""})
    converged: bool = True
    stop_reason: str = "converged"
    status: StatusMarkers | None = None
    pressure: str | None = None
    held: str | None = None


def held_body(points: Mapping[str, NDArray[np.float64]]) -> str:
    """The body the grasp holds: the smallest, by its bounding box's diagonal.

    Parameters
    ----------
    points : mapping of str to ndarray (N, 3)
        Each body's nodal positions; the writer passes the reference meshes, so that
        one body is named for the whole run, whatever the bodies do in it.

    Returns
    -------
    str
        The name; the first of equal ones in ``points``' order.
    """
    if not points:
        raise ValueError("held_body needs at least one body")
    return min(points, key=lambda n: float(np.linalg.norm(np.ptp(points[n], axis=0))))
