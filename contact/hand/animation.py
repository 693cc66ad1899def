"""Pictures of a keyframed sequence: one PNG per frame, rendered off-screen, and a GIF.

Each frame poses the hand (:class:`~contact.hand.posing.HandPoser`): the bones by forward
kinematics and the skin surface by the JLD mapping, drawn by
:func:`contact.hand.plot.render_hand`; the GIF by :func:`contact.output.rendering.write_gif`.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from ..output.rendering import write_gif
from .keyframes import Keyframes
from .plot import DORSAL_VIEW, render_hand
from .posing import HandPoser

__all__ = ["render_sequence", "write_gif"]


def render_sequence(
    poser: HandPoser,
    keyframes: Keyframes,
    times: ArrayLike,
    out: str | os.PathLike,
    *,
    gif: bool = True,
    fps: float = 10.0,
    window_size: tuple[int, int] = (640, 480),
    camera: tuple = DORSAL_VIEW,
    prefix: str = "frame",
) -> list[Path]:
    """Render the hand at each time to ``out/<prefix>_NNNN.png`` and ``out/<prefix>.gif``.

    Parameters
    ----------
    poser : HandPoser
        The hand to pose.
    keyframes : Keyframes
        Angles at any time (clamps are reported as they happen).
    times : array_like
        Frame times.
    out : path-like
        Folder, created if needed.
    gif : bool
        Also write the GIF.
    fps : float
        GIF frame rate.
    window_size : (int, int)
    camera : tuple
        pyvista camera position (see :mod:`contact.hand.plot`).
    prefix : str

    Returns
    -------
    list of Path
        The PNG files, then the GIF if written.
    """
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    skin = poser.hand.skin.copy()
    pngs = []
    for i, t in enumerate(np.atleast_1d(np.asarray(times, dtype=np.float64))):
        angles = keyframes.pose(float(t))
        skin.points = poser.skin_points(angles)
        transforms = poser.hand.skeleton.forward_kinematics(angles)
        path = folder / f"{prefix}_{i:04d}.png"
        render_hand(
            path,
            poser.hand.bones,
            skin=skin,
            transforms=transforms,
            camera=camera,
            title=f"t = {t:.2f}",
            window_size=window_size,
            zoom=1.2,
        )
        pngs.append(path)
    if gif:
        pngs.append(write_gif(pngs, folder / f"{prefix}.gif", fps))
    return pngs
