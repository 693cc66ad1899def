"""The results folder of a grasp run, written frame by frame: VTU/PVD series and summary.

:class:`ResultsWriter` writes into a staging folder and swaps it into place when finished
(:mod:`contact.output.staging`), so that a results folder is never half-overwritten.

Layout of a results folder::

    summary.json               per frame: time, verdict, forces, history, timings; the scene
    <body>_<index:04d>.vtu     the body in the frame, with the arrays below
    <body>.pvd                 ParaView series of a body (timestep = frame time)
    frames/frame_<index:04d>.png   the grasp: stress, finger forces, verdict
    frames/status_<index:04d>.png  stick and slip contacts (frames with friction)
    grasp.gif                  the frames as an animation
    forces.png                 force per finger and per bone against time
    convergence.png            largest change against iteration, one line per frame

**One configuration.** Every body's points are its reference placement of the frame,
before contact: the hand posed by the frame's joint angles, the ball at its scene position
(moved by ``[ball.follow]``). The bodies line up as posed (a finger pressed into the ball
overlaps it by the press depth); ``points + displacement`` is every body's deformed
configuration (ParaView's *Warp By Vector* on ``displacement``, scale 1).

VTU arrays (units in the field data, :mod:`contact.output.vtufields`): point data
``displacement`` (m) and ``contact_force`` ``(N, 3)`` (N), and the contact fields
``normal_force``, ``tangential_force``, ``contact_status`` and ``cone_use``
(:mod:`contact.output.status`, zeros where a body has no contact); cell data
``von_mises`` (cell-average stress, Pa), ``stress`` ``(M, 6)`` (Pa) in the component order
:data:`STRESS_COMPONENTS` (``xx yy zz xy yz xz``, the order ParaView names the components
of a symmetric tensor), ``region`` and, for a body given its cells' bones, ``bone``. Field
data: ``time (s)``, the units, ``region <name>`` (the region id of each named region),
``bone <name>`` (the bone id of each bone) and ``bone_force <name> (N)``: the force the
bone (support) exerts on the body, as in ``summary.json``.

The frame records and ``summary.json`` come from :mod:`contact.output.summary`; the
pictures and GIF from :mod:`contact.output.pictures`, rendered in
:meth:`ResultsWriter.finish` once every frame is known (without off-screen OpenGL they are
skipped with a warning and ``summary.json`` says ``"pictures": "skipped: <reason>"``);
the plots from :mod:`contact.output.plots`.
"""

from __future__ import annotations

import logging
import os
import re
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

import fem

from ..errors import OutputError
from ..solver.results import FrameResult
from .forces import FrameForces, frame_forces
from .picturedata import held_body
from .pictures import (
    Picture,
    body_picture,
    render_pictures,
    write_gif_atomically,
)
from .plainjson import versions as _versions  # finish() has a parameter of this name
from .plots import convergence_png, forces_png
from .staging import make_staging, write_atomic
from .status import contact_point_data, status_markers
from .summary import frame_entry, summary_text
from .vtufields import STRESS_COMPONENTS, write_body_vtu, write_pvd

__all__ = ["STRESS_COMPONENTS", "BodyFrame", "ResultsWriter"]


log = logging.getLogger(__name__)

#: A body name that can name a file.
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.+-]*$")


@dataclass(frozen=True)
class BodyFrame:
    """A body as it is written for one frame.

    Attributes
    ----------
    mesh : fem.Mesh
        The body's reference configuration of the frame (posed hand, placed ball): the
        points of its ``.vtu`` file, which the frame's displacement deforms.
    materials : fem.LinearElastic or mapping of int to fem.LinearElastic
        Its material, or one per region (for the stress).
    opacity : float
        Not used: the pictures draw every body opaque, so that the skin's stress can be
        read (kept so that existing callers run).
    bbar : bool
        Its bricks and wedges with their mean dilatation, as its stiffness was assembled
        (:class:`contact.solver.body.ElasticBody`): the stress follows the same strain.
    nodal_pressure : bool
        Its tetrahedra with averaged nodal pressures, likewise.
    region_names : sequence of str
        Name of each region id (the hand: palm, thumb, index, middle, ring, little): the
        VTU's field data, and the contact forces summed per region in the pictures and
        ``forces.png``. Empty: regions unnamed, no forces per region.
    cell_bone : ndarray of int, optional
        The bone of each cell, in the mesh's cell order (``-1`` none): the VTU's cell data
        ``bone``.
    bone_names : sequence of str
        Name of each bone id of ``cell_bone``.
    finite : bool
        A neo-Hookean body: Cauchy stress on its deformed placement and its log strain
        (:func:`contact.output.vtufields.write_body_vtu`).
    """

    mesh: fem.Mesh
    materials: fem.LinearElastic | Mapping[int, fem.LinearElastic]
    opacity: float = 1.0
    bbar: bool = True
    nodal_pressure: bool = False
    region_names: Sequence[str] = ()
    cell_bone: NDArray[np.int64] | None = None
    bone_names: Sequence[str] = ()
    finite: bool = False


@dataclass
class _Frame:
    """A written frame: its summary record, its VTU files and its convergence history."""

    index: int
    time: float
    entry: dict[str, Any]
    vtu: dict[str, str]
    history: list[float]
    forces: FrameForces


class ResultsWriter:
    """Writes a results folder frame by frame; nothing in it changes until :meth:`finish`.

    Parameters
    ----------
    directory : str or path-like
        The results folder. Its parent is created if needed (and removed again by
        :meth:`abort`). An existing folder is replaced by :meth:`finish` when it is empty
        or its marker lists every file in it (:mod:`contact.output.staging`); any other
        existing folder or file is refused. What dead runs left beside it is cleaned.
    pictures : bool
        Render ``frames/frame_NNNN.png`` (and ``frames/status_NNNN.png`` for a frame with
        friction, ``frames/pressure_NNNN.png`` for one whose held body touches).
    gif : bool
        Assemble ``grasp.gif`` from the pictures (only with ``pictures``).
    window_size : (int, int)
        Picture size in pixels.
    planes_extent : float, optional
        Not used: each plane is drawn as a small square where it touches a body (kept so
        that existing callers run).
    camera : tuple, optional
        pyvista camera position ``(position, focal point, view up)`` of the pictures' main
        view: its view direction is kept and the distance fitted to the grasp
        (:mod:`contact.output.framing`). Default: looking down obliquely from
        ``(+x, -y, +z)`` with ``z`` up.
    fps : float
        GIF frame rate.

    Raises
    ------
    TargetError
        When ``directory`` is an existing folder this program may not replace.
    OutputError
        When the folder cannot be created or written.

    Examples
    --------
    >>> with ResultsWriter("results") as w:  # doctest: +SKIP
    ...     for i, t in enumerate(times):
    ...         w.add_frame(i, t, solve(t), {"ball": BodyFrame(mesh, material)})
    ...     w.finish(scene)
    """

    def __init__(
        self,
        directory: str | os.PathLike,
        *,
        pictures: bool = True,
        gif: bool = True,
        window_size: tuple[int, int] = (1024, 768),
        planes_extent: float | None = None,
        camera: tuple | None = None,
        fps: float = 5.0,
    ) -> None:
        self.directory = Path(os.path.abspath(os.fspath(directory)))
        self.pictures = bool(pictures)
        self.gif = bool(gif) and self.pictures
        self.window_size = (int(window_size[0]), int(window_size[1]))
        if min(self.window_size) <= 0:
            raise ValueError(f"window_size must be positive, got {window_size}")
        if planes_extent is not None and not planes_extent > 0:
            raise ValueError(f"planes_extent must be positive, got {planes_extent}")
        self.planes_extent = planes_extent
        self.camera = camera
        self.fps = float(fps)
        self._stage = make_staging(self.directory)
        self.staging = self._stage.path
        self._frames: list[_Frame] = []
        self._pictures: list[Picture] = []
        self._state = "open"
        log.debug("staging results for %s in %s", self.directory, self.staging)

    # --- context manager ---------------------------------------------------------------

    def __enter__(self) -> ResultsWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if self._state == "open":
            if exc_type is None:
                log.warning(
                    "results writer closed without finish(): %s not written", self.directory
                )
            self.abort()

    # --- frames ------------------------------------------------------------------------

    def add_frame(
        self,
        index: int,
        time: float,
        result: FrameResult,
        bodies: Mapping[str, BodyFrame],
        planes: Sequence[tuple[str, ArrayLike, ArrayLike]] = (),
        extra: Mapping[str, Any] | None = None,
    ) -> dict[str, Any]:
        """Write one frame's ``.vtu`` files and keep its summary entry and picture.

        Parameters
        ----------
        index : int
            Frame number (>= 0, unique): the ``NNNN`` of the file names.
        time : float
            Frame time (the ``.pvd`` timestep).
        result : FrameResult
            The frame's solve.
        bodies : mapping of str to BodyFrame
            Body name (as in ``result.displacement``) -> its mesh and materials.
        planes : sequence of (name, point, normal)
            Rigid planes at their position of the frame, drawn in the picture.
        extra : mapping, optional
            More JSON-able items for the summary entry (a key of the entry may not be
            repeated).

        Returns
        -------
        dict
            The frame's ``summary.json`` entry (see the module docstring).

        Raises
        ------
        ValueError
            On a repeated index, an unknown body or a shape mismatch (of a displacement
            or a contact field).
        OutputError
            When a file cannot be written.
        """
        self._require_open()
        t0 = _clock()
        index = int(index)
        time = float(time)
        if index < 0:
            raise ValueError(f"frame index must be >= 0, got {index}")
        if any(f.index == index for f in self._frames):
            raise ValueError(f"frame {index} was already added")
        if not bodies:
            raise ValueError("add_frame needs at least one body")
        for name, body in bodies.items():
            if not _NAME.match(name):
                raise ValueError(f"body name {name!r} cannot name a file")
            if name not in result.displacement:
                raise ValueError(
                    f"body {name!r} has no displacement in the result "
                    f"(bodies there: {sorted(result.displacement)})"
                )
            u = np.asarray(result.displacement[name])
            if u.shape != (body.mesh.n_points, 3):
                raise ValueError(
                    f"displacement of body {name!r} has shape {u.shape}, its mesh has "
                    f"{body.mesh.n_points} points"
                )
        plane_list = [
            (str(n), np.asarray(p, dtype=np.float64).reshape(3), _unit(q)) for n, p, q in planes
        ]
        fields = {
            name: contact_point_data(result.contact_fields.get(name), body.mesh.n_points, name)
            for name, body in bodies.items()
        }
        deformed = {n: b.mesh.points + result.displacement[n] for n, b in bodies.items()}
        vtu: dict[str, str] = {}
        max_vm: dict[str, float] = {}
        drawn = []
        # the held body: its contact pressure gets its own picture where it touches
        held = held_body({n: b.mesh.points for n, b in bodies.items()})
        for name, body in bodies.items():
            vtu[name] = f"{name}_{index:04d}.vtu"
            u = np.asarray(result.displacement[name], dtype=np.float64)
            f = result.contact_force.get(name)
            try:
                vm = write_body_vtu(
                    self.staging / vtu[name],
                    body.mesh,
                    body.materials,
                    u,
                    np.zeros_like(u) if f is None else f,
                    fields[name],
                    time=time,
                    bbar=body.bbar,
                    nodal_pressure=body.nodal_pressure,
                    support=result.support_forces.get(name, {}),
                    region_names=body.region_names,
                    cell_bone=body.cell_bone,
                    bone_names=body.bone_names,
                    finite=body.finite,
                )
            except (fem.MeshError, OSError) as exc:
                raise OutputError(
                    f"cannot write the results folder {self.directory}: {exc}"
                ) from None
            max_vm[name] = float(max(v.max() for v in vm.values()))
            if self.pictures:
                drawn.append(
                    body_picture(
                        name, body.mesh, body.materials, u, vm, fields[name], name == held
                    )
                )
        pressed = held if self.pictures and fields[held]["normal_force"].max() > 0 else None
        status = None
        if self.pictures and result.friction is not None:
            status = status_markers(deformed, {n: fields[n]["contact_status"] for n in bodies})
        entry = frame_entry(
            index,
            time,
            result,
            vtu=vtu,
            max_von_mises=max_vm,
            picture=f"frames/frame_{index:04d}.png" if self.pictures else None,
            status_picture=f"frames/status_{index:04d}.png" if status is not None else None,
            pressure_picture=f"frames/pressure_{index:04d}.png" if pressed else None,
            extra=extra,
        )
        named = {n: (b.mesh, tuple(b.region_names)) for n, b in bodies.items() if b.region_names}
        span = float(np.ptp(np.concatenate(list(deformed.values())), axis=0).max())
        grip = entry.get("grip_force")
        grip = float(grip) if isinstance(grip, (int, float)) else None
        forces = frame_forces(time, result, deformed, named, plane_list, span, grip)
        if self.pictures:
            self._pictures.append(
                Picture(
                    index,
                    time,
                    drawn,
                    plane_list,
                    forces,
                    verdict=dict(entry["verdict"]),
                    converged=bool(result.converged),
                    stop_reason=str(result.stop_reason),
                    status=status,
                    pressure=pressed,
                    held=held,
                )
            )
        entry["timings"]["write"] = _clock() - t0
        history = [float(r.max_change) for r in result.history]
        self._frames.append(_Frame(index, time, entry, vtu, history, forces))
        log.info("frame %d (t = %g): %s written", index, time, ", ".join(vtu.values()))
        return entry

    # --- the end -----------------------------------------------------------------------

    def finish(
        self, scene: Mapping[str, Any], *, versions: Mapping[str, str] | None = None
    ) -> Path:
        """Write the series, pictures, convergence plot and summary; swap the folder in.

        Parameters
        ----------
        scene : mapping
            The scene with its defaults filled, echoed in ``summary.json``.
        versions : mapping, optional
            Versions to record; default :func:`versions`.

        Returns
        -------
        Path
            The results folder.

        Raises
        ------
        OutputError
            When a file cannot be written or the folder cannot be swapped in; the
            staging folder is then removed and an existing results folder left as it was.
        """
        self._require_open()
        t0 = _clock()
        try:
            frames = sorted(self._frames, key=lambda f: f.index)
            files: dict[str, Any] = {"pvd": self._write_pvd(frames)}
            curves = [(f.time, f.history) for f in frames]
            write_atomic(self.staging / "convergence.png", convergence_png(curves))
            files["convergence"] = "convergence.png"
            write_atomic(self.staging / "forces.png", forces_png([f.forces for f in frames]))
            files["forces"] = "forces.png"
            t1 = _clock()
            pictures = "off"
            if self.pictures:
                pictures = render_pictures(
                    self._pictures,
                    self.staging / "frames",
                    window_size=self.window_size,
                    camera=self.camera,
                )
            if pictures == "written" and self.gif and self._pictures:
                pngs = [
                    self.staging / "frames" / f"frame_{p.index:04d}.png"
                    for p in sorted(self._pictures, key=lambda p: p.index)
                ]
                write_gif_atomically(pngs, self.staging / "grasp.gif", self.fps)
                files["gif"] = "grasp.gif"
            t_render = _clock() - t1
            text = summary_text(
                scene=scene,
                versions=versions if versions is not None else _versions(),
                entries=[f.entry for f in frames],
                pictures=pictures,
                stress_components=STRESS_COMPONENTS,
                files=files,
                timings={"pictures": t_render, "finish": _clock() - t0},
            )
            write_atomic(self.staging / "summary.json", text.encode())
            self._stage.swap()
        except OSError as exc:
            self.abort()
            if isinstance(exc, OutputError):
                raise
            raise OutputError(f"cannot write the results folder {self.directory}: {exc}") from None
        except BaseException:
            self.abort()
            raise
        self._state = "finished"
        log.info("results written to %s (%.2f s)", self.directory, _clock() - t0)
        return self.directory

    def abort(self) -> None:
        """Remove the staging folder (and the parents it created); the results stay. Idempotent."""
        if self._state == "open":
            self._stage.discard()
            self._state = "aborted"
            self._pictures.clear()
            log.debug("results for %s discarded", self.directory)

    # --- internals ---------------------------------------------------------------------

    def _require_open(self) -> None:
        if self._state != "open":
            raise RuntimeError(f"the results writer for {self.directory} is {self._state}")

    def _write_pvd(self, frames: list[_Frame]) -> dict[str, str]:
        out = {}
        for body in sorted({b for f in frames for b in f.vtu}):
            series = [(f.time, f.vtu[body]) for f in frames if body in f.vtu]
            write_pvd(self.staging / f"{body}.pvd", series)
            out[body] = f"{body}.pvd"
        return out


def _unit(v: ArrayLike) -> NDArray[np.float64]:
    a = np.asarray(v, dtype=np.float64).reshape(3)
    n = float(np.linalg.norm(a))
    if not n > 0:
        raise ValueError(f"plane normal must be non-zero, got {a.tolist()}")
    return a / n


def _clock() -> float:
    return time.perf_counter()
