"""The held body's contact pressure: its own picture, ``frames/pressure_NNNN.png``.

The frame's picture colours every body by its von Mises stress; on a pressurised hollow
ball the wall's hoop stress is everywhere, and what the contacts do does not show over
it. This picture shows the held (smallest) body alone, coloured by its contact pressure:
each node's normal contact force over its tributary boundary area
(:func:`contact_pressure`, the ``peak_pressure`` of ``summary.json``), light grey where
nothing touches. Up to :data:`VIEWS` panels each look at a group of its contacts from
outside the body (:func:`pressure_views`), titled with the fingers and planes whose
pushes they see. Cameras and colour scale are the run's, so that frames compare.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

import fem
from contact.geometry.plane import tributary_areas

from .framing import View, view_from
from .summary import pressure_over_area

if TYPE_CHECKING:
    from .picturedata import Picture

__all__ = [
    "COVER",
    "VIEWS",
    "PressureScale",
    "contact_pressure",
    "pressure_views",
    "shoot_pressure",
]

#: Most panels of a pressure picture.
VIEWS = 3
#: A view covers the contacts whose direction from the body's centre lies within this
#: angle (rad) of its own: seen from there, they face the camera.
COVER = np.deg2rad(55.0)
#: Contact points a view choice looks at, at most (a deterministic sample).
_SAMPLE = 400
_NONE = "#d0d0d0"
#: The camera's zoom on the body's box (the box's bounding sphere leaves a wide margin).
ZOOM = 1.4
_CMAP = "YlOrRd"


@dataclass(frozen=True)
class PressureScale:
    """The run's contact pressure scale: top (Pa), unit factor, bar title."""

    top: float
    scale: float
    title: str

    @classmethod
    def of(cls, name: str, top: float) -> PressureScale:
        """The scale of ``name``'s pressures up to ``top`` (Pa), in kPa or MPa."""
        unit, scale = ("MPa", 1e-6) if top >= 1e6 else ("kPa", 1e-3)
        return cls(top, scale, f"{name}: contact pressure ({unit})")


def contact_pressure(
    mesh: fem.Mesh, points: NDArray[np.float64], normal_force: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Each node's normal contact force over its tributary boundary area (Pa), 0 off contact.

    Parameters
    ----------
    mesh : fem.Mesh
        The body (its boundary faces).
    points : ndarray (N, 3)
        Its deformed nodal positions: the areas are measured there.
    normal_force : ndarray (N,)
        Nodal normal contact force (N).
    """
    area = tributary_areas(np.asarray(points, dtype=np.float64), mesh.boundary.faces)
    return pressure_over_area(normal_force, area)


def pressure_views(
    contacts: Sequence[tuple[NDArray[np.float64], NDArray[np.float64]]],
    frames: Sequence[NDArray[np.float64]],
    n_views: int = VIEWS,
) -> list[View]:
    """Cameras that together see the held body's contacts of every frame from outside.

    Parameters
    ----------
    contacts : sequence of (ndarray (k, 3), ndarray (k,))
        Per frame, the body's contact nodes (deformed) and their normal forces.
    frames : sequence of ndarray (N, 3)
        Per frame, all its deformed points (its box and centre).
    n_views : int
        Most views.

    Returns
    -------
    list of View
        Greedily, by force: the direction (from the body's centre) around which the
        most force not yet seen lies within :data:`COVER`, until every contact is seen
        or ``n_views`` are taken; each view looks from there at the centre. Empty when
        the body never touches.
    """
    pts = np.concatenate([np.zeros((0, 3)), *(np.asarray(c, float) for c, _ in contacts)])
    w = np.concatenate([np.zeros(0), *(np.asarray(f, float) for _, f in contacts)])
    box = np.array([np.min([f.min(axis=0) for f in frames], axis=0),
                    np.max([f.max(axis=0) for f in frames], axis=0)])  # fmt: skip
    centre = box.mean(axis=0)
    d = pts - centre
    r = np.linalg.norm(d, axis=1)
    keep = (w > 0) & (r > 0)
    d, w = d[keep] / r[keep, None], w[keep]
    if len(d) > _SAMPLE:
        pick = np.random.default_rng(0).choice(len(d), _SAMPLE, replace=False)
        d, w = d[pick], w[pick]
    near = d @ d.T >= np.cos(COVER)  # (k, k): within a view's cover of each other
    seen = np.zeros(len(d), bool)
    span = float((box[1] - box[0]).max()) or 1.0
    views: list[View] = []
    while len(views) < n_views and not seen.all():
        gain = near[:, ~seen] @ w[~seen]
        i = int(np.argmax(np.where(seen, -1.0, gain)))
        group = near[i] & ~seen
        axis = (w[group, None] * d[group]).sum(axis=0)
        axis = axis / (np.linalg.norm(axis) or 1.0)
        seen |= d @ axis >= np.cos(COVER)
        seen[group] = True  # a group whose mean falls short of one of its own points
        views.append(view_from(centre, axis, span, box))
    return views


def _seen_from(pic: Picture, view: View) -> str:
    """The fingers and planes of ``pic`` whose pushes ``view`` looks at, for its title."""
    eye = np.subtract(view.position, view.focus)
    eye = eye / np.linalg.norm(eye)
    names = []
    for push in pic.forces.regions:
        d = np.asarray(push.point) - np.asarray(view.focus)
        n = float(np.linalg.norm(d))
        if n > 0 and d @ eye >= np.cos(COVER) * n:
            names.append(push.label)
    if names:
        return "toward " + ", ".join(names)
    return "seen from ({:.2f}, {:.2f}, {:.2f})".format(*(eye + 0.0))


def _colours():
    """:data:`_CMAP` in 255 levels above one grey level: no contact is grey, not pale."""
    from matplotlib import colormaps
    from matplotlib.colors import ListedColormap, to_rgba

    levels = colormaps[_CMAP](np.linspace(0.0, 1.0, 255))
    return ListedColormap(np.vstack([to_rgba(_NONE), levels]))


def shoot_pressure(
    window_size: tuple[int, int],
    pic: Picture,
    held: str,
    views: Sequence[View],
    bar: PressureScale,
) -> NDArray[np.uint8]:
    """Render a frame's pressure picture: the held body in each of ``views``, one bar."""
    import pyvista as pv

    body = next(b for b in pic.bodies if b.name == held)
    # panels about square, side by side, with room for the title and the bar
    width = window_size[0]
    size = [width, int(min(window_size[1], 1.3 * width / max(len(views), 1)))]
    plotter = pv.Plotter(
        off_screen=True, window_size=size, shape=(1, len(views)),
        border=True, border_color="#cccccc",
    )  # fmt: skip
    cmap = _colours()
    try:
        for k, view in enumerate(views):
            plotter.subplot(0, k)
            plotter.set_background("white")
            surface = body.surface.copy(deep=False)
            surface[bar.title] = np.asarray(body.surface["contact_pressure"]) * bar.scale
            plotter.add_mesh(
                surface, scalars=bar.title, cmap=cmap, smooth_shading=True,
                clim=(0.0, bar.top * bar.scale), show_scalar_bar=False,
            )  # fmt: skip
            title = _seen_from(pic, view)
            if k == 0:
                title = f"frame {pic.index}, t = {pic.time:g} s\n{title}"
                plotter.add_scalar_bar(
                    bar.title, mapper=plotter.mapper, color="black", fmt="%.3g",
                    title_font_size=11, label_font_size=10, n_labels=4, vertical=False,
                    position_x=0.05, position_y=0.03, width=0.9, height=0.12,
                )  # fmt: skip
            label = plotter.add_text(title, font_size=9, color="black").GetTextProperty()
            label.SetBackgroundColor(1.0, 1.0, 1.0)
            label.SetBackgroundOpacity(0.75)
            plotter.camera_position = view.camera
            plotter.reset_camera(bounds=view.box)
            plotter.camera.zoom(ZOOM)
        return plotter.screenshot(return_img=True)
    finally:
        plotter.close()
