"""Pictures of the hand: semi-transparent skin with the bones inside, rendered off-screen."""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ..errors import ContactError
from ..output import rendering

if TYPE_CHECKING:
    import pyvista

__all__ = ["render_hand"]

_SKIN = "#e8b896"
_BONE = "#f3ecd8"
#: Camera (position, focal point, view up) looking at the back of the hand from above the
#: thumb side, in the rig frame (x ulnar, y distal, z dorsal).
DORSAL_VIEW = ((-0.20, -0.13, 0.26), (0.0, 0.07, -0.01), (0.25, 0.55, 0.8))
#: Looking at a closed hand from the thumb side, in front of the knuckles.
SIDE_VIEW = ((-0.20, 0.28, 0.16), (0.0, 0.06, -0.01), (0.2, -0.4, 0.9))


def render_hand(
    path: str | os.PathLike,
    bones: Mapping[str, pyvista.PolyData],
    skin: pyvista.PolyData | None = None,
    transforms: Mapping[str, NDArray] | None = None,
    camera: tuple = DORSAL_VIEW,
    title: str | None = None,
    window_size: tuple[int, int] = (1200, 900),
    zoom: float = 1.35,
) -> NDArray[np.uint8]:
    """Render bones (posed by ``transforms``) and an optional semi-transparent skin to PNG.

    Parameters
    ----------
    path : path-like
        PNG file to write.
    bones : mapping of str to pyvista.PolyData
        Bone surfaces at rest, by name.
    skin : pyvista.PolyData, optional
        Skin surface, drawn at 35 % opacity.
    transforms : mapping of str to ndarray (4, 4), optional
        Rest-to-posed transform of each bone (``Skeleton.forward_kinematics``).
    camera : tuple
        pyvista camera position (position, focal point, view up); the view direction is
        kept and the distance fitted to the scene.
    title : str, optional
        Text in the upper left corner.
    window_size : tuple of int
    zoom : float
        Camera zoom after fitting the scene.

    Returns
    -------
    ndarray of uint8, shape (height, width, 3)
        The image.

    Raises
    ------
    ContactError
        No off-screen rendering here (:func:`contact.output.rendering.rendering_available` says
        why), rather than a VTK failure that can abort the process.
    """
    import pyvista as pv

    ok, reason = rendering.rendering_available()
    if not ok:
        raise ContactError(f"cannot render {os.fspath(path)}: {reason}")

    plotter = pv.Plotter(off_screen=True, window_size=list(window_size))
    plotter.set_background("white")
    for name, poly in bones.items():
        shown = poly if transforms is None else poly.transform(transforms[name], inplace=False)
        plotter.add_mesh(shown, color=_BONE, smooth_shading=True, specular=0.2)
    if skin is not None:
        plotter.add_mesh(skin, color=_SKIN, opacity=0.35, smooth_shading=True)
    if title:
        plotter.add_text(title, font_size=12, color="black")
    plotter.camera_position = list(camera)
    plotter.reset_camera()  # keep the view direction, fit everything in
    plotter.camera.zoom(zoom)
    plotter.enable_anti_aliasing("ssaa")
    image = plotter.screenshot(str(path), return_img=True)
    plotter.close()
    return image
