"""Pictures of a results folder: von Mises stress per frame, the GIF, the convergence plot.

A frame with friction also gets a picture of its stick and slip contacts
(:mod:`contact.output.status`). The frame pictures are rendered once every frame is known,
so that all frames share one camera and one colour range: the camera keeps the view
direction it is given and fits the box around every body of every frame; the colour range
runs from zero to the largest nodal von Mises stress of any frame. They need off-screen OpenGL
(:func:`contact.rendering.rendering_available`, read at use so that tests can replace it);
without it, or when VTK fails, they are skipped with a warning rather than failing a run.

Every file is written atomically (:func:`contact.output.staging.write_atomic`).
"""

from __future__ import annotations

import io
import logging
import os
import shutil
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

import fem
from fem.pvmesh import to_pyvista
from fem.stress import nodal_average

from .. import rendering
from .staging import write_atomic
from .status import StatusMarkers, draw_status

if TYPE_CHECKING:
    import pyvista

__all__ = [
    "Picture",
    "convergence_png",
    "deformed_surface",
    "render_pictures",
    "write_gif_atomically",
]

log = logging.getLogger(__name__)

#: Camera (position relative to the centre in spans, focal point, view up) when none is
#: given: looking down obliquely from ``(+x, -y, +z)`` with ``z`` up.
_DEFAULT_VIEW = ((1.0, -1.6, 1.0), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
_CMAP = "viridis"
#: Diameter of a stick or slip dot, as a fraction of the picture's smaller side (pixels).
_DOT = 1.0 / 60.0


@dataclass
class Picture:
    """What a frame's pictures need: deformed surfaces with their opacity, planes, contacts.

    Attributes
    ----------
    index : int
        Frame number (the ``NNNN`` of ``frame_NNNN.png``).
    time : float
        Frame time, in the title.
    surfaces : list of (pyvista.PolyData, float)
        Deformed outer surfaces with point data ``von_mises``, and their opacity.
    planes : list of (str, ndarray (3,), ndarray (3,))
        Name, a point and the unit normal of each plane at the frame.
    status : StatusMarkers or None
        The stick and slip contact nodes where the frame has friction (its
        ``status_NNNN.png``), else None (no status picture).
    """

    index: int
    time: float
    surfaces: list[tuple[pyvista.PolyData, float]]
    planes: list[tuple[str, NDArray[np.float64], NDArray[np.float64]]]
    status: StatusMarkers | None = None


def deformed_surface(
    mesh: fem.Mesh,
    displacement: NDArray[np.float64],
    von_mises: dict[str, NDArray[np.float64]],
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

    Returns
    -------
    pyvista.PolyData
        The surface at ``mesh.points + displacement``, point data ``von_mises``.
    """
    grid = to_pyvista(mesh, point_data={"von_mises": nodal_average(mesh, von_mises)})
    grid.points = mesh.points + displacement
    try:
        return grid.extract_surface(algorithm="dataset_surface")
    except TypeError:  # pyvista before the ``algorithm`` keyword
        return grid.extract_surface()


def render_pictures(
    pictures: Sequence[Picture],
    folder: Path,
    *,
    window_size: tuple[int, int],
    planes_extent: float | None = None,
    camera: tuple | None = None,
) -> str:
    """Render ``folder/frame_NNNN.png`` for every picture (and ``status_NNNN.png``); say how.

    Parameters
    ----------
    pictures : sequence of Picture
        The frames; those with ``status`` also get ``status_NNNN.png``.
    folder : Path
        Where the PNG files go (created; removed again when rendering fails).
    window_size : (int, int)
        Picture size in pixels.
    planes_extent : float, optional
        Side of the squares drawn for the planes (m); default 1.2 times the largest side
        of the box around every body of every frame.
    camera : tuple, optional
        pyvista camera position ``(position, focal point, view up)``; its view direction is
        kept and the distance fitted.

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
        _render_all(pictures, folder, window_size, planes_extent, camera)
    except OSError:
        raise  # a file that cannot be written: an error of the results folder
    except Exception as exc:  # pictures are not worth failing a run for
        shutil.rmtree(folder, ignore_errors=True)
        log.warning("pictures skipped: rendering failed: %s", exc, exc_info=True)
        return f"skipped: rendering failed: {type(exc).__name__}: {exc}"
    return "written"


def _render_all(
    pictures: Sequence[Picture],
    folder: Path,
    window_size: tuple[int, int],
    planes_extent: float | None,
    camera: tuple | None,
) -> None:
    folder.mkdir(exist_ok=True)
    bounds = np.array([s.bounds for p in pictures for s, _ in p.surfaces if s.n_points]).reshape(
        -1, 6
    )
    lo, hi = bounds[:, 0::2].min(axis=0), bounds[:, 1::2].max(axis=0)
    center, span = 0.5 * (lo + hi), float((hi - lo).max()) or 1.0
    extent = planes_extent or 1.2 * span
    top = max(
        (float(np.nanmax(s["von_mises"])) for p in pictures for s, _ in p.surfaces),
        default=0.0,
    )
    clim = (0.0, top if top > 0 else 1.0)
    box = [lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]]
    if camera is not None:
        view = [tuple(map(float, v)) for v in camera]
    else:
        pos, _, up = _DEFAULT_VIEW
        view = [tuple(center + np.asarray(pos) * span), tuple(center), up]
    shot = _Camera(window_size, extent, center, view, box)
    dot = _DOT * min(window_size)
    for pic in pictures:
        image = shot.shoot(pic, f"frame {pic.index}, t = {pic.time:g}", _stress(clim))
        write_atomic(folder / f"frame_{pic.index:04d}.png", rendering.png_bytes(image))
        if pic.status is not None:
            title = f"frame {pic.index}, t = {pic.time:g}: stick and slip"
            image = shot.shoot(
                pic, title, lambda plotter, p: draw_status(plotter, p.surfaces, p.status, dot)
            )
            write_atomic(folder / f"status_{pic.index:04d}.png", rendering.png_bytes(image))
    log.info("%d pictures rendered", len(pictures))


@dataclass(frozen=True)
class _Camera:
    """What every picture of a run shares: its size, the plane squares and the camera."""

    window_size: tuple[int, int]
    extent: float
    center: NDArray[np.float64]
    view: list
    box: list[float]

    def shoot(
        self, pic: Picture, title: str, draw: Callable[[pyvista.Plotter, Picture], None]
    ) -> NDArray[np.uint8]:
        """Render one picture: ``draw`` adds the bodies, then the planes, title and camera."""
        import pyvista as pv

        plotter = pv.Plotter(off_screen=True, window_size=list(self.window_size))
        try:
            plotter.set_background("white")
            draw(plotter, pic)
            for _, point, normal in pic.planes:
                c = self.center - np.dot(self.center - point, normal) * normal
                square = pv.Plane(
                    center=c, direction=normal, i_size=self.extent, j_size=self.extent
                )
                plotter.add_mesh(square, color="#8899aa", opacity=0.25, show_edges=False)
            plotter.add_text(title, font_size=12, color="black")
            plotter.camera_position = self.view
            plotter.reset_camera(bounds=self.box)
            plotter.camera.zoom(1.1)
            return plotter.screenshot(return_img=True)
        finally:
            plotter.close()


def _stress(clim: tuple[float, float]) -> Callable[[pyvista.Plotter, Picture], None]:
    """Draws the bodies coloured by von Mises stress, with its colour bar."""

    def draw(plotter: pyvista.Plotter, pic: Picture) -> None:
        for surface, opacity in pic.surfaces:
            plotter.add_mesh(
                surface,
                scalars="von_mises",
                cmap=_CMAP,
                clim=clim,
                opacity=opacity,
                smooth_shading=True,
                show_scalar_bar=False,
            )
        plotter.add_scalar_bar(
            "von Mises stress (Pa)",
            color="black",
            fmt="%.3g",
            title_font_size=16,
            label_font_size=14,
            vertical=True,
            position_x=0.86,
            position_y=0.08,
            height=0.76,
            width=0.06,
        )

    return draw


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


def convergence_png(curves: Sequence[tuple[float, Sequence[float]]]) -> bytes:
    """The convergence plot: largest change against iteration, one line per frame.

    Parameters
    ----------
    curves : sequence of (float, sequence of float)
        Frame time and the largest change of a nodal displacement at each iteration (m).
        More than ten frames are coloured by time with a colour bar, fewer get a legend.

    Returns
    -------
    bytes
        The PNG.
    """
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.0, 4.5), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    drawn = [(t, h) for t, h in curves if h]
    many = len(drawn) > 10
    times = [t for t, _ in drawn]
    norm = Normalize(min(times, default=0.0), max(times, default=1.0) or 1.0)
    cmap = colormaps["viridis"]
    for k, (t, h) in enumerate(drawn):
        y = np.asarray(h)
        y = np.where(y > 0, y, np.nan)  # a log scale cannot show a zero change
        it = np.arange(1, len(y) + 1)
        color = cmap(norm(t)) if many else f"C{k % 10}"
        ax.plot(it, y, "o-", ms=3, lw=1.2, color=color, label=f"t = {t:g}")
    ax.set_yscale("log")
    ax.set_xlabel("iteration")
    ax.set_ylabel("largest change of a nodal displacement (m)")
    ax.set_title("Contact iteration: convergence per frame")
    ax.grid(True, which="both", alpha=0.3)
    if not drawn:
        ax.text(0.5, 0.5, "no iterations", ha="center", va="center", transform=ax.transAxes)
    elif many:
        fig.colorbar(ScalarMappable(norm, cmap), ax=ax, label="frame time")
    else:
        ax.legend(fontsize=8)
    ax.xaxis.get_major_locator().set_params(integer=True)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()
