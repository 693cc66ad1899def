"""Pictures of a results folder: the grasp, frame by frame, and their GIF.

A frame's picture has a main view of the grasp and, beside it, one view per body
(:mod:`contact.output.framing`; cameras shared by every frame so that frames compare):

- the bodies opaque, each coloured by its von Mises stress with its own colour map and
  colour bar in kPa or MPa, over the whole run: from the smallest to the largest value
  drawn (nodal averages on the surface; from zero where the smallest is near it); where
  the largest cell-average stress (``max_von_mises`` of ``summary.json``) lies above, the
  bar says "cell max"; where the surface's 99.9th percentile lies below :data:`_CLIP`
  of its largest value (one hot spot), the bar stops there, says "clipped" and the
  maximum, and draws what lies above in :data:`contact.output.drawing.ABOVE`; a body
  whose stress is round-off (below :data:`_NOISE` times its Young's modulus in every
  frame) is drawn grey with "no stress" instead of a bar;
- in the held (smallest) body's view, which shows it alone so that no body hides them
  (in the main view when the scene has one body),
  one arrow per finger (region) and per plane touching it (:mod:`contact.output.forces`),
  its tip where the force acts and its length the region's normal force over the largest
  grip force of the run times :data:`_ARROW` of the focus box: arrows compare between
  frames; each labelled with its force (N);
- the planes as small squares where they touch;
- the frame, its verdict (green when realistic, red when not) and the grip force per
  finger written on it, and a frame that did not converge marked "NOT CONVERGED" with its
  stop reason.

A frame with friction also gets a picture of its stick and slip contacts
(:mod:`contact.output.status`) in the main view, and a frame whose held body touches a
picture of its contact pressure (:mod:`contact.output.pressure`). The pictures need
off-screen OpenGL (:func:`contact.output.rendering.rendering_available`, read at use so
that tests can replace it); without it, or when VTK fails, they are skipped with a
warning rather than failing a run. They are rendered in a child process
(:func:`contact.output.rendering.run_in_child`): VTK can abort the process that renders,
which then costs the pictures, not the results.

Every file is written atomically (:func:`contact.output.staging.write_atomic`).
"""

from __future__ import annotations

import logging
import os
import shutil
import uuid
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

import fem
from fem.pvmesh import to_pyvista
from fem.stress import nodal_average

from . import rendering
from .drawing import Bar, draw_body, draw_planes, draw_pushes, write_verdict
from .framing import View, body_views, focus_box, grasp_axis, held_view, main_view
from .picturedata import BodyPicture, Picture, held_body
from .pressure import PressureScale, contact_pressure, pressure_views, shoot_pressure
from .staging import write_atomic
from .status import draw_status

if TYPE_CHECKING:
    import pyvista

__all__ = [
    "BodyPicture",
    "Picture",
    "body_picture",
    "deformed_surface",
    "render_pictures",
    "write_gif_atomically",
]

log = logging.getLogger(__name__)

#: Colour maps of the bodies, in order: distinct, so that each bar names its body.
_CMAPS = ("viridis", "plasma", "cividis", "magma")
#: A body's stress is round-off below this fraction of its Young's modulus.
_NOISE = 1e-9
#: Length of the arrow of the largest grip force, as a fraction of the focus box's side.
_ARROW = 0.45
#: A bar is clipped at the surface's 99.9th percentile when that is below this fraction
#: of the surface's largest stress (a hot spot would leave the rest one colour).
_CLIP = 0.25
#: Diameter of a stick or slip dot, as a fraction of the picture's smaller side (pixels).
_DOT = 1.0 / 60.0


def deformed_surface(
    mesh: fem.Mesh,
    displacement: NDArray[np.float64],
    von_mises: dict[str, NDArray[np.float64]],
    pressure: NDArray[np.float64] | None = None,
) -> pyvista.PolyData:
    """The outer surface of a deformed body with its nodal-average von Mises stress.

    Parameters
    ----------
    mesh : fem.Mesh
        The body's reference configuration.
    displacement : ndarray (N, 3)
        Nodal displacements.
    von_mises : dict of str to ndarray
        Cell-average von Mises stress per cell type.
    pressure : ndarray (N,), optional
        Nodal contact pressure (Pa, :func:`contact.output.pressure.contact_pressure`).

    Returns
    -------
    pyvista.PolyData
        The surface at ``mesh.points + displacement``, point data ``von_mises`` (and
        ``contact_pressure``).
    """
    data = {"von_mises": nodal_average(mesh, von_mises)}
    if pressure is not None:
        data["contact_pressure"] = np.asarray(pressure, dtype=np.float64)
    grid = to_pyvista(mesh, point_data=data)
    grid.points = mesh.points + displacement
    try:
        return grid.extract_surface(algorithm="dataset_surface")
    except TypeError:  # pyvista before the ``algorithm`` keyword
        return grid.extract_surface()


def body_picture(
    name: str,
    mesh: fem.Mesh,
    materials: fem.LinearElastic | Mapping[int, fem.LinearElastic],
    displacement: NDArray[np.float64],
    von_mises: dict[str, NDArray[np.float64]],
    fields: Mapping[str, NDArray],
    pressure: bool = False,
) -> BodyPicture:
    """What the pictures need of a body in a frame.

    Parameters
    ----------
    name : str
    mesh : fem.Mesh
        Its reference configuration.
    materials : fem.LinearElastic or mapping of int to fem.LinearElastic
        Its materials (the largest Young's modulus sets the round-off of its stress).
    displacement : ndarray (N, 3)
    von_mises : dict of str to ndarray
        Cell-average von Mises stress per cell type (Pa).
    fields : mapping of str to ndarray
        Its contact point data (``normal_force`` marks the contact nodes).
    pressure : bool
        Give its surface the nodal contact pressure (the held body's, which its pressure
        picture draws); others go without the tributary areas it takes.

    Returns
    -------
    BodyPicture
    """
    x = mesh.points + displacement
    mats = materials.values() if isinstance(materials, Mapping) else [materials]
    fn = np.asarray(fields["normal_force"])
    return BodyPicture(
        name,
        deformed_surface(
            mesh, displacement, von_mises, contact_pressure(mesh, x, fn) if pressure else None
        ),
        float(max(v.max() for v in von_mises.values())),
        _NOISE * max(float(m.E) for m in mats),
        x[fn > 0],
        x,
        fn[fn > 0],
    )


def render_pictures(
    pictures: Sequence[Picture],
    folder: Path,
    *,
    window_size: tuple[int, int],
    camera: tuple | None = None,
) -> str:
    """Render ``folder/frame_NNNN.png`` for every picture (``status_``, ``pressure_``); say how.

    Parameters
    ----------
    pictures : sequence of Picture
        The frames; those with ``status`` also get ``status_NNNN.png``, those with
        ``pressure`` ``pressure_NNNN.png``.
    folder : Path
        Where the PNG files go (created; removed again when rendering fails).
    window_size : (int, int)
        Picture size in pixels.
    camera : tuple, optional
        pyvista camera position ``(position, focal point, view up)`` of the main view;
        its view direction is kept and the distance fitted.

    Returns
    -------
    str
        ``"written"``, ``"none (no frames)"`` or ``"skipped: <reason>"``.

    Raises
    ------
    OSError
        When a file cannot be written (an error of the results folder, not of rendering).
    """
    if not pictures:
        return "none (no frames)"
    ok, reason = rendering.rendering_available()
    if not ok:
        log.warning("pictures skipped: %s", reason)
        return f"skipped: {reason}"
    try:
        # VTK can abort the process that renders: in a child, that costs the pictures only
        rendering.run_in_child(_render_all, (list(pictures), folder, window_size, camera))
    except OSError:
        raise  # a file that cannot be written: an error of the results folder
    except Exception as exc:  # pictures are not worth failing a run for
        shutil.rmtree(folder, ignore_errors=True)
        why = str(exc) if isinstance(exc, rendering.ChildDied) else f"{type(exc).__name__}: {exc}"
        log.warning("pictures not written: %s (the results are written)", why)
        return f"skipped: rendering failed: {why}"
    return "written"


def _bars(pictures: Sequence[Picture]) -> dict[str, Bar]:
    """Each body's colour scale over the whole run (see the module docstring)."""
    names = list(dict.fromkeys(b.name for p in pictures for b in p.bodies))
    out = {}
    for k, name in enumerate(names):
        mine = [b for p in pictures for b in p.bodies if b.name == name]
        cell = max(b.top for b in mine)
        noise = max(b.noise for b in mine)
        values = [np.asarray(b.surface["von_mises"]) for b in mine if b.surface.n_points]
        drawn = max((float(np.nanmax(v)) for v in values), default=0.0)
        low = min((float(np.nanmin(v)) for v in values), default=0.0)
        high = max((float(np.nanpercentile(v, 99.9)) for v in values), default=0.0)
        clipped = bool(drawn > noise and noise < high < _CLIP * drawn)
        shown = high if clipped else drawn
        unit, scale = ("MPa", 1e-6) if shown >= 1e6 else ("kPa", 1e-3)
        title = f"{name}: von Mises ({unit})"
        if clipped:
            title += f", clipped; max {cell * scale:.3g}"
        elif cell > 1.05 * drawn:
            title += f"; cell max {cell * scale:.3g}"
        blank = cell <= noise or not shown > 0
        bottom = low if 1e-3 * shown < low < shown else 0.0
        out[name] = Bar(_CMAPS[k % len(_CMAPS)], bottom, shown, scale, title, clipped, blank)
    return out


def _render_all(
    pictures: Sequence[Picture],
    folder: Path,
    window_size: tuple[int, int],
    camera: tuple | None,
) -> None:
    folder.mkdir(exist_ok=True)
    names = list(dict.fromkeys(b.name for p in pictures for b in p.bodies))
    per_body = [[b.points for p in pictures for b in p.bodies if b.name == n] for n in names]
    contacts = [b.contact for p in pictures for b in p.bodies]
    first = pictures[0]
    held = first.held or held_body({b.name: b.points for b in first.bodies})
    k = names.index(held)
    box = focus_box(per_body, contacts, k)
    sight = (
        [b.contact for p in pictures for b in p.bodies if b.name == held],
        [_triangles([b.surface for b in p.bodies if b.name != held], box) for p in pictures],
    )
    main = main_view(box, camera, grasp_axis(per_body, box, k), sight)
    views = dict(zip(names, body_views(per_body, box), strict=True)) if len(names) > 1 else {}
    if views:  # the held body's forces seen side on, as the main view sees them
        views[held] = held_view(main, per_body[k], 0.45)
    bars = _bars(pictures)
    grip = max((p.forces.grip for p in pictures), default=0.0)
    size = float((box[1] - box[0]).max())
    arrow = _ARROW * size / grip if grip > 0 else 0.0
    dot = _DOT * min(window_size)
    pressed = _pressure_views(pictures)
    for pic in pictures:
        image = _shoot(window_size, pic, main, views, bars, (held, arrow), size)
        write_atomic(folder / f"frame_{pic.index:04d}.png", rendering.png_bytes(image))
        if pic.status is not None:
            image = _shoot_status(window_size, pic, main, dot)
            write_atomic(folder / f"status_{pic.index:04d}.png", rendering.png_bytes(image))
        if pic.pressure is not None:
            sides, scale = pressed[pic.pressure]  # its own cameras: the frame's views stay
            image = shoot_pressure(window_size, pic, pic.pressure, sides, scale)
            write_atomic(folder / f"pressure_{pic.index:04d}.png", rendering.png_bytes(image))
    log.info("%d pictures rendered", len(pictures))


def _pressure_views(
    pictures: Sequence[Picture],
) -> dict[str, tuple[list[View], PressureScale]]:
    """The pressure pictures' cameras and colour scale per body drawn, over the run."""
    out = {}
    for name in dict.fromkeys(p.pressure for p in pictures if p.pressure is not None):
        mine = [b for p in pictures for b in p.bodies if b.name == name and p.pressure == name]
        views = pressure_views([(b.contact, b.pushes) for b in mine], [b.points for b in mine])
        top = max(float(np.max(b.surface["contact_pressure"], initial=0.0)) for b in mine)
        out[name] = (views, PressureScale.of(name, top))
    return out


def _triangles(surfaces: Sequence[pyvista.PolyData], box: NDArray[np.float64]) -> NDArray:
    """The surfaces' triangles ``(t, 3, 3)`` between the focus box and the main view's eye.

    Those with a corner within the eye's distance (three box sizes) of the box's centre:
    a finger outside the box may stand in front of it.
    """
    centre = box.mean(axis=0)
    reach = 3.0 * float((box[1] - box[0]).max())
    out = [np.zeros((0, 3, 3))]
    for surface in surfaces:
        tri = surface.triangulate()
        faces = np.asarray(tri.faces).reshape(-1, 4)[:, 1:]
        corners = np.asarray(tri.points)[faces]
        near = (np.linalg.norm(corners - centre, axis=2) <= reach).any(axis=1)
        out.append(corners[near])
    return np.concatenate(out)


def _plotter(window_size: tuple[int, int], n_views: int) -> pyvista.Plotter:
    import pyvista as pv

    if n_views < 2:
        return pv.Plotter(off_screen=True, window_size=list(window_size))
    return pv.Plotter(
        off_screen=True,
        window_size=list(window_size),
        shape=(n_views, 3),
        groups=[(np.s_[:], np.s_[:2])],
        border=True,
        border_color="#cccccc",
    )


def _place(plotter: pyvista.Plotter, view: View, zoom: float = 1.0) -> None:
    plotter.set_background("white")
    plotter.camera_position = view.camera
    plotter.reset_camera(bounds=view.box)
    plotter.camera.zoom(zoom)


def _shoot(
    window_size: tuple[int, int],
    pic: Picture,
    main: View,
    views: dict[str, View],
    bars: dict[str, Bar],
    arrows: tuple[str, float],
    size: float,
) -> NDArray[np.uint8]:
    """Render a frame's picture: the main view and one view per body.

    The force arrows go where no body hides them: into the view of the held (smallest)
    body, drawn alone, or into the main view when there is no other body.
    """
    held, arrow = arrows
    plotter = _plotter(window_size, len(views))
    try:
        plotter.subplot(0, 0)
        for k, body in enumerate(pic.bodies):
            draw_body(plotter, body, bars[body.name], bar_at=k, slots=len(pic.bodies))
        draw_planes(plotter, pic, size)
        wide = window_size[0] * (2 / 3 if views else 1)
        write_verdict(plotter, pic, (int(wide), window_size[1]))
        _place(plotter, main, 1.1)
        if not views:  # after the camera: the labels are kept inside the view as placed
            draw_pushes(plotter, pic.forces, arrow)
        for row, body in enumerate(b for b in pic.bodies if b.name in views):
            plotter.subplot(row, 2)
            draw_body(plotter, body, bars[body.name], bar_at=None)
            if body.name == held:
                title = f"{body.name} alone: the forces on it"
            else:
                title = f"{body.name}, seen from the {held}"
            label = plotter.add_text(title, font_size=9, color="black").GetTextProperty()
            label.SetBackgroundColor(1.0, 1.0, 1.0)  # readable over a dark body
            label.SetBackgroundOpacity(0.75)
            _place(plotter, views[body.name], 1.2 if body.name == held else 1.0)
            if body.name == held:
                draw_pushes(plotter, pic.forces, arrow)
        return plotter.screenshot(return_img=True)
    finally:
        plotter.close()


def _shoot_status(
    window_size: tuple[int, int], pic: Picture, main: View, dot: float
) -> NDArray[np.uint8]:
    """Render a frame's stick and slip picture in the main view."""
    assert pic.status is not None
    plotter = _plotter(window_size, 1)
    try:
        draw_status(plotter, [(b.surface, 1.0) for b in pic.bodies], pic.status, dot)
        plotter.add_text(
            f"frame {pic.index}, t = {pic.time:g} s: stick and slip", font_size=12, color="black"
        )
        _place(plotter, main, 1.15)
        return plotter.screenshot(return_img=True)
    finally:
        plotter.close()


def write_gif_atomically(pngs: Sequence[Path], path: Path, fps: float) -> None:
    """Assemble the PNG files into the GIF ``path`` through a temporary file beside it.

    Parameters
    ----------
    pngs : sequence of Path
        The frame pictures, in order.
    path : Path
        The GIF.
    fps : float
        Frame rate.
    """
    tmp = path.with_name(f".{path.stem}.{uuid.uuid4().hex[:12]}{path.suffix}")
    try:
        rendering.write_gif(pngs, tmp, fps=fps)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
