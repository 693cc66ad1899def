"""Drawing a frame's picture: a body by its own colour scale, force arrows, planes, verdict.

The pieces that :mod:`contact.output.pictures` puts into its views; what each shows and
why is in that module's docstring.
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from .forces import FrameForces

if TYPE_CHECKING:
    import pyvista

    from .picturedata import BodyPicture, Picture

__all__ = ["Bar", "draw_body", "draw_planes", "draw_pushes", "label_anchors", "write_verdict"]

#: Colour of stresses above a clipped bar's top.
ABOVE = "#ff00ff"
_GREEN, _RED = "#1a7f37", "#cf222e"
_PLANE = "#8899aa"
#: Font size of the force labels.
_LABEL_FONT = 11
#: Side of a plane's square, as a fraction of the focus box's side.
_SQUARE = 0.35


@dataclass(frozen=True)
class Bar:
    """A body's colour scale: map, range (Pa), unit factor, what its bar says.

    ``clipped``: the range stops below the body's largest stress (drawn in :data:`ABOVE`
    above it); ``blank``: the body's stress is round-off, drawn grey without a bar.
    """

    cmap: str
    bottom: float
    top: float
    scale: float
    title: str
    clipped: bool
    blank: bool


def draw_body(
    plotter: pyvista.Plotter, body: BodyPicture, bar: Bar, bar_at: int | None, slots: int = 2
) -> None:
    """A body opaque, coloured by its own scale; its colour bar when ``bar_at`` is given.

    The bars share the bottom of the view in ``slots`` equal places (at least two).
    """
    step = 0.96 / max(2, slots)
    if bar.blank:
        plotter.add_mesh(body.surface, color="#bbbbbb", smooth_shading=True)
        if bar_at is not None:
            plotter.add_text(
                f"{body.name}: no stress",
                position=(0.03 + step * bar_at, 0.02),
                viewport=True,
                font_size=10,
                color="black",
            )
        return
    surface = body.surface.copy(deep=False)
    surface[bar.title] = np.asarray(body.surface["von_mises"]) * bar.scale
    plotter.add_mesh(
        surface,
        scalars=bar.title,
        cmap=bar.cmap,
        clim=(bar.bottom * bar.scale, bar.top * bar.scale),
        above_color=ABOVE if bar.clipped else None,
        smooth_shading=True,
        show_scalar_bar=False,
    )
    if bar_at is not None:
        plotter.add_scalar_bar(
            bar.title,
            mapper=plotter.mapper,
            color="black",
            fmt="%.3g",
            title_font_size=13 if slots <= 2 else 10,
            label_font_size=11,
            n_labels=4,
            vertical=False,
            position_x=0.03 + step * bar_at,
            position_y=0.03,
            width=step - 0.04,
            height=0.08,
            above_label="above" if bar.clipped else None,
        )


def draw_pushes(plotter: pyvista.Plotter, forces: FrameForces, arrow: float) -> None:
    """One arrow per finger and plane, its tip where it acts, labelled with its force.

    Draw it after the view's camera is placed: a label that would run past its view's
    edge is moved back inside (:func:`label_anchors`).
    """
    import pyvista as pv

    if not arrow:
        return
    tails, labels = [], []
    for push in forces.regions:
        f = np.asarray(push.force, dtype=np.float64)
        n = float(np.linalg.norm(f))
        length = push.normal * arrow
        if not (n > 0 and length > 0):
            continue
        d = f / n
        tail = push.point - d * length
        colour = "#444444" if push.label.startswith("plane ") else "black"
        plotter.add_mesh(
            pv.Arrow(
                start=tail,
                direction=d,
                scale=length,
                tip_length=0.3,
                tip_radius=0.12,
                shaft_radius=0.04,
            ),
            color=colour,
        )
        tails.append(tail)
        labels.append(f"{push.label} {push.normal:.3g} N")
    if not tails:
        return
    plotter.add_point_labels(
        label_anchors(plotter, np.array(tails), labels, _LABEL_FONT),
        labels,
        font_size=_LABEL_FONT,
        text_color="black",
        fill_shape=True,
        shape_color="white",
        shape_opacity=0.6,
        show_points=False,
        always_visible=True,
    )


def label_anchors(
    plotter: pyvista.Plotter, points: NDArray[np.float64], labels: list[str], font_size: int
) -> NDArray[np.float64]:
    """Where to anchor each label (its lower left corner) so that it stays in its view.

    A label at ``points`` that would run past the current view's edge (as its camera
    stands; the text about ``0.65 font_size`` pixels a character) is moved back inside,
    in the screen's plane at its point's depth.
    """
    renderer = plotter.renderer
    x0, y0, x1, y1 = renderer.GetViewport()
    width, height = plotter.window_size
    left, right, bottom, top = x0 * width, x1 * width, y0 * height, y1 * height
    out = np.array(points, dtype=np.float64).reshape(-1, 3)
    for k, (p, text) in enumerate(zip(out.copy(), labels, strict=True)):
        renderer.SetWorldPoint(*(float(v) for v in p), 1.0)
        renderer.WorldToDisplay()
        dx, dy, dz = renderer.GetDisplayPoint()
        wide, high = 0.65 * font_size * len(text) + 8, 1.6 * font_size + 4
        x = min(max(dx, left + 2), max(right - 2 - wide, left + 2))
        y = min(max(dy, bottom + 2), max(top - 2 - high, bottom + 2))
        if (x, y) != (dx, dy):
            renderer.SetDisplayPoint(x, y, dz)
            renderer.DisplayToWorld()
            wx, wy, wz, ww = renderer.GetWorldPoint()
            out[k] = np.array([wx, wy, wz]) / (ww if ww else 1.0)
    return out


def draw_planes(plotter: pyvista.Plotter, pic: Picture, size: float) -> None:
    """Each plane that touches a body, as a small square under its contact."""
    import pyvista as pv

    at = {
        p.label[len("plane ") :]: p.point
        for p in pic.forces.regions
        if p.label.startswith("plane ")
    }
    for name, point, normal in pic.planes:
        if name not in at:
            continue
        c = at[name] - np.dot(at[name] - point, normal) * normal
        square = pv.Plane(
            center=c,
            direction=normal,
            i_size=_SQUARE * size,
            j_size=_SQUARE * size,
            i_resolution=1,
            j_resolution=1,
        )
        plotter.add_mesh(square, color=_PLANE, opacity=0.6)


def write_verdict(plotter: pyvista.Plotter, pic: Picture, view: tuple[int, int]) -> None:
    """The frame, its verdict, the grip force per finger; a failed solve in red.

    The lines are wrapped to the current view's width and stacked from its top left;
    ``view`` is its size in pixels.
    """
    realistic = bool(pic.verdict.get("realistic"))
    word = "REALISTIC" if realistic else "NOT REALISTIC"
    f = pic.forces
    parts = [f"{n} {v:.3g}" for n, v in f.fingers.items() if v > 0]
    grip = f"grip {f.grip:.3g} N" + (f": {', '.join(parts)}" if parts else "")
    blocks = [(f"frame {pic.index}, t = {pic.time:g} s", "black", 13)]
    if not pic.converged:
        blocks.append((f"NOT CONVERGED: {pic.stop_reason}", _RED, 12))
    blocks += [
        (f"{word}: {pic.verdict.get('reason', '')}", _GREEN if realistic else _RED, 10),
        (grip, "black", 10),
    ]
    y = 1.0 - 0.01
    for text, colour, size in blocks:
        lines = _wrap(text, int(view[0] / (1.05 * size)))
        y -= (lines.count("\n") + 1) * 2.1 * size / view[1]
        actor = plotter.add_text(
            lines, position=(0.01, y), viewport=True, font_size=size, color=colour
        )
        prop = actor.GetTextProperty()
        prop.SetBackgroundColor(1.0, 1.0, 1.0)
        prop.SetBackgroundOpacity(0.75)


def _wrap(text: str, width: int) -> str:
    return "\n".join(textwrap.wrap(text, width)) or text
