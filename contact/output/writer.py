"""The results folder of a grasp run: summary, VTU/PVD series, pictures, GIF, convergence.

:class:`ResultsWriter` stages everything in a hidden sibling folder of the results
folder (same filesystem) and swaps it into place in :meth:`ResultsWriter.finish`: an
existing results folder is renamed aside, the staging folder renamed into its place, and
only then the old one deleted, so the folder is never half-overwritten (a crash between
the two renames leaves both complete, the old one under a hidden name). Every file is
also written atomically inside the staging folder (temporary file, then rename).

Layout of a results folder::

    summary.json               per frame: time, verdict, forces, history, timings; the scene
    <body>_<index:04d>.vtu     reference configuration of the frame, with the arrays below
    <body>.pvd                 ParaView series of a body (timestep = frame time)
    frames/frame_<index:04d>.png   von Mises stress on the deformed bodies
    grasp.gif                  the frames as an animation
    convergence.png            largest change against iteration, one line per frame

VTU arrays: point data ``displacement`` and ``contact_force`` ``(N, 3)``; cell data
``von_mises`` (cell-average stress, Pa), ``stress`` ``(M, 6)`` in the component order
:data:`STRESS_COMPONENTS` (``xx yy zz xy yz xz``, the order ParaView names the components
of a symmetric tensor) and ``region``. The points are the body's reference configuration
of the frame (posed hand, placed ball): ParaView's *Warp By Vector* with ``displacement``
shows the deformed bodies.

Pictures are rendered in :meth:`ResultsWriter.finish`, once every frame is known, so that
all frames share one camera and one colour range. They need off-screen OpenGL
(:func:`rendering_available` checks it once, in a child process, since a failing VTK can
abort the process); without it they are skipped with a warning and ``summary.json`` says
``"pictures": "skipped: <reason>"``.

Timings (seconds) are kept under ``"timings"`` keys only: everything else in
``summary.json`` is a function of the input.
"""

from __future__ import annotations

import functools
import io
import json
import logging
import math
import os
import re
import shutil
import subprocess
import sys
import time
import uuid
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

import fem
from fem.pvmesh import to_pyvista
from fem.stress import cell_stress, nodal_average, von_mises

from ..errors import OutputError
from ..solver.results import FrameResult

if TYPE_CHECKING:
    import pyvista

__all__ = [
    "STRESS_COMPONENTS",
    "BodyFrame",
    "OutputError",
    "ResultsWriter",
    "rendering_available",
    "verdict",
    "versions",
]

log = logging.getLogger(__name__)

#: Order of the six components of the ``stress`` cell array (ParaView's for 6-component
#: symmetric tensors).
STRESS_COMPONENTS = ("xx", "yy", "zz", "xy", "yz", "xz")
_VOIGT = (np.array([0, 1, 2, 0, 1, 0]), np.array([0, 1, 2, 1, 2, 2]))

#: Distributions whose versions :func:`versions` reports (key -> distribution name).
_DISTRIBUTIONS = {
    "numpy": "numpy",
    "scipy": "scipy",
    "meshio": "meshio",
    "pyvista": "pyvista",
    "vtk": "vtk",
    "matplotlib": "matplotlib",
    "pillow": "pillow",
    "pytetwild": "pytetwild",
    "libigl": "libigl",
    "pypardiso": "pypardiso",
    "grasp-contact": "grasp-contact",
}
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.+-]*$")
_DEFAULT_VIEW = ((1.0, -1.6, 1.0), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
_CMAP = "viridis"


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
        Opacity of the body in the pictures (1 opaque; e.g. 0.5 for a hand around a ball).
    bbar : bool
        Its bricks and wedges with their mean dilatation, as its stiffness was assembled
        (:class:`contact.solver.body.ElasticBody`): the stress follows the same strain.
    nodal_pressure : bool
        Its tetrahedra with averaged nodal pressures, likewise.
    """

    mesh: fem.Mesh
    materials: fem.LinearElastic | Mapping[int, fem.LinearElastic]
    opacity: float = 1.0
    bbar: bool = True
    nodal_pressure: bool = False


def verdict(result: FrameResult) -> dict[str, Any]:
    """The verdict of a frame: realistic when converged and no bone is over its limit.

    Parameters
    ----------
    result : FrameResult

    Returns
    -------
    dict
        ``{"realistic": bool, "reason": str}``; the reason names every bone over its
        limit with its force and limit, else the stop reason of a solve that did not
        converge, else ``"converged; every bone under its limit"``.
    """
    if result.over_limit:
        parts = [
            f"bone {name} carries {float(f):.4g} N > its limit {float(lim):.4g} N"
            for name, (f, lim) in sorted(result.over_limit.items())
        ]
        return {"realistic": False, "reason": "; ".join(parts)}
    if not result.converged:
        return {"realistic": False, "reason": f"not converged: {result.stop_reason}"}
    return {"realistic": True, "reason": "converged; every bone under its limit"}


def versions() -> dict[str, str]:
    """Versions of Python and of the packages the results depend on.

    Returns
    -------
    dict of str to str
        ``python`` and each distribution (``"not installed"`` when missing).
    """
    out = {"python": sys.version.split()[0]}
    for key, dist in _DISTRIBUTIONS.items():
        try:
            out[key] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[key] = "not installed"
    return out


_versions = versions  # finish() has a parameter of this name


_PROBE = """
import numpy as np, pyvista as pv
p = pv.Plotter(off_screen=True, window_size=[64, 48])
p.add_mesh(pv.Sphere(), color="red")
img = p.screenshot(return_img=True)
p.close()
assert img.shape[:2] == (48, 64) and np.ptp(img) > 0, "blank image"
"""


#: The environment variable by which VTK (9.4 on) is told which OpenGL window to make.
_WINDOW_VARIABLE = "VTK_DEFAULT_OPENGL_WINDOW"
#: Asked for first on Linux without a display: left to choose, VTK tries X first, logs
#: "bad X server connection" on every run, and only then falls back to EGL.
_HEADLESS_WINDOW = "vtkEGLRenderWindow"


def _probe(env: Mapping[str, str]) -> tuple[bool, str]:
    """Render a small picture in a child process with ``env`` added to the environment."""
    try:
        proc = subprocess.run(
            [sys.executable, "-c", _PROBE],
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
            env={**os.environ, **env},
        )
    except (OSError, subprocess.SubprocessError) as exc:
        return False, f"off-screen rendering check failed: {exc}"
    if proc.returncode == 0:
        return True, "ok"
    lines = [ln.strip() for ln in proc.stderr.splitlines() if ln.strip()]
    last = lines[-1] if lines else f"exit status {proc.returncode}"
    return False, f"off-screen rendering unavailable: {last[:300]}"


@functools.cache
def rendering_available() -> tuple[bool, str]:
    """Can pyvista render off-screen here? Checked once per process, in a child process.

    On Linux without a display (``DISPLAY`` and ``WAYLAND_DISPLAY`` unset), and unless the
    user chose a window (``VTK_DEFAULT_OPENGL_WINDOW``), EGL is tried first; where it
    renders, this process asks VTK for it too, so that VTK does not try X and log a
    warning on every run. Otherwise VTK chooses, as it would.

    Returns
    -------
    ok : bool
    reason : str
        ``"ok"``, or why not (the child's last error line).
    """
    headless = not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    if sys.platform.startswith("linux") and headless and _WINDOW_VARIABLE not in os.environ:
        ok, _ = _probe({_WINDOW_VARIABLE: _HEADLESS_WINDOW})
        if ok:
            os.environ[_WINDOW_VARIABLE] = _HEADLESS_WINDOW
            return True, "ok"
    return _probe({})


def _jsonable(value: Any) -> Any:
    """``value`` as plain JSON types (arrays to lists, non-finite floats to None)."""
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, (list, tuple, set, frozenset)):
        items = sorted(value, key=repr) if isinstance(value, (set, frozenset)) else value
        return [_jsonable(v) for v in items]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        v = float(value) + 0.0  # no -0.0
        return v if math.isfinite(v) else None
    if value is None or isinstance(value, str):
        return value
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if hasattr(value, "__dataclass_fields__"):
        return _jsonable({k: getattr(value, k) for k in value.__dataclass_fields__})
    return str(value)


def _vector(v: ArrayLike) -> dict[str, Any]:
    a = np.asarray(v, dtype=np.float64).reshape(3)
    return {"force": _jsonable(a), "magnitude": float(np.linalg.norm(a))}


def _write_atomic(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder."""
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex[:12]}.tmp")
    try:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def _png_bytes(image: NDArray[np.uint8]) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(image)).save(buf, format="PNG")
    return buf.getvalue()


def _history(result: FrameResult) -> list[dict[str, Any]]:
    return [
        {
            "iteration": int(r.iteration),
            "n_contacts": int(r.n_contacts),
            "added": int(r.added),
            "released": int(r.released),
            "max_change": float(r.max_change),
            "max_penetration": float(r.max_penetration),
            "total_force": _jsonable(np.asarray(r.total_force, dtype=np.float64)),
            "normal_force": float(r.normal_force),
            "relaxation": float(r.relaxation),
            "max_support_force": float(r.max_support_force),
        }
        for r in result.history
    ]


def _bone_forces(result: FrameResult) -> dict[str, dict[str, Any]]:
    """Support forces keyed by group name (``body/group`` where a name repeats)."""
    counts: dict[str, int] = {}
    for groups in result.support_forces.values():
        for g in groups:
            counts[g] = counts.get(g, 0) + 1
    out = {}
    for body in sorted(result.support_forces):
        for g in sorted(result.support_forces[body]):
            key = g if counts[g] == 1 else f"{body}/{g}"
            out[key] = {"body": body, **_vector(result.support_forces[body][g])}
    return out


@dataclass
class _Picture:
    """What a frame's picture needs: deformed surfaces, planes, title."""

    index: int
    time: float
    surfaces: list[tuple[pyvista.PolyData, float]]
    planes: list[tuple[str, NDArray[np.float64], NDArray[np.float64]]]


@dataclass
class _Frame:
    index: int
    time: float
    entry: dict[str, Any]
    vtu: dict[str, str]
    history: list[float]


class ResultsWriter:
    """Writes a results folder frame by frame; nothing in it changes until :meth:`finish`.

    Parameters
    ----------
    directory : str or path-like
        The results folder. Its parent is created if needed. An existing folder is
        replaced by :meth:`finish` when it is empty or a results folder (holds a
        ``summary.json``); any other existing folder or file is refused.
    pictures : bool
        Render ``frames/frame_NNNN.png``.
    gif : bool
        Assemble ``grasp.gif`` from the pictures (only with ``pictures``).
    window_size : (int, int)
        Picture size in pixels.
    planes_extent : float, optional
        Side of the squares drawn for the planes (m); default 1.2 times the largest
        side of the box around every body of every frame.
    camera : tuple, optional
        pyvista camera position ``(position, focal point, view up)``: its view direction
        is kept and the distance fitted to every body of every frame. Default: looking
        down obliquely from ``(+x, -y, +z)`` with ``z`` up.
    fps : float
        GIF frame rate.

    Raises
    ------
    OutputError
        When the folder cannot be created or written, or is an existing folder that is
        not a results folder.

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
        self._check_target()
        parent = self.directory.parent
        try:
            parent.mkdir(parents=True, exist_ok=True)
            # not mkdtemp: its mode 0700 would become the results folder's
            self.staging = parent / f".{self.directory.name}.staging-{uuid.uuid4().hex[:12]}"
            self.staging.mkdir()
        except OSError as exc:
            raise OutputError(
                f"cannot write the results folder {self.directory}: {exc.strerror or exc}"
            ) from None
        self._frames: list[_Frame] = []
        self._pictures: list[_Picture] = []
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
            On a repeated index, an unknown body or a shape mismatch.
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
        vtu: dict[str, str] = {}
        max_vm: dict[str, float] = {}
        surfaces = []
        for name, body in bodies.items():
            u = np.asarray(result.displacement[name], dtype=np.float64)
            f = result.contact_force.get(name)
            f = np.zeros_like(u) if f is None else np.asarray(f, dtype=np.float64)
            sigma = cell_stress(
                body.mesh,
                body.materials,
                u.ravel(),
                bbar=body.bbar,
                nodal_pressure=body.nodal_pressure,
            )
            vm = {k: von_mises(s) for k, s in sigma.items()}
            six = {k: s[:, _VOIGT[0], _VOIGT[1]] for k, s in sigma.items()}
            max_vm[name] = float(max(v.max() for v in vm.values()))
            fname = f"{name}_{index:04d}.vtu"
            try:
                fem.write_mesh(
                    self.staging / fname,
                    body.mesh,
                    point_data={"displacement": u, "contact_force": f},
                    cell_data={"von_mises": vm, "stress": six},
                )
            except fem.MeshError as exc:
                raise OutputError(
                    f"cannot write the results folder {self.directory}: {exc}"
                ) from None
            vtu[name] = fname
            if self.pictures:
                grid = to_pyvista(body.mesh, point_data={"von_mises": nodal_average(body.mesh, vm)})
                grid.points = body.mesh.points + u
                surfaces.append((_surface(grid), float(body.opacity)))
        if self.pictures:
            self._pictures.append(_Picture(index, time, surfaces, plane_list))
        entry = self._entry(index, time, result, vtu, max_vm, extra)
        entry["timings"]["write"] = _clock() - t0
        history = [float(r.max_change) for r in result.history]
        self._frames.append(_Frame(index, time, entry, vtu, history))
        log.info("frame %d (t = %g): %s written", index, time, ", ".join(vtu.values()))
        return entry

    def _entry(
        self,
        index: int,
        time: float,
        result: FrameResult,
        vtu: dict[str, str],
        max_vm: dict[str, float],
        extra: Mapping[str, Any] | None,
    ) -> dict[str, Any]:
        pairs = result.contacts.get("pair") if result.contacts else None
        per_pair: dict[str, int] = {}
        if pairs is not None:
            names, counts = np.unique(np.asarray(pairs).astype(str), return_counts=True)
            per_pair = {str(n): int(c) for n, c in zip(names, counts, strict=True)}
        entry: dict[str, Any] = {
            "index": index,
            "time": time,
            "converged": bool(result.converged),
            "stop_reason": str(result.stop_reason),
            "algorithm": str(result.algorithm),
            "iterations": int(result.iterations),
            "verdict": verdict(result),
            "max_penetration": float(result.max_penetration),
            "penetration_ratio": float(result.penetration_ratio),
            "separation_ratio": float(result.separation_ratio),
            "contact_force": {
                b: _vector(np.asarray(result.contact_force[b]).sum(axis=0))
                for b in sorted(result.contact_force)
            },
            "obstacle_forces": {
                p: _vector(result.obstacle_forces[p]) for p in sorted(result.obstacle_forces)
            },
            "bone_forces": _bone_forces(result),
            "over_limit": {
                b: {"force": float(f), "limit": float(lim)}
                for b, (f, lim) in sorted(result.over_limit.items())
            },
            "contacts": {"total": int(sum(per_pair.values())), "per_pair": per_pair},
            "max_von_mises": max_vm,
            "history": _history(result),
            "files": {
                "vtu": dict(vtu),
                "picture": f"frames/frame_{index:04d}.png" if self.pictures else None,
            },
            "timings": {k: float(v) for k, v in sorted(result.timings.items())},
        }
        if extra:
            clash = sorted(set(extra) & set(entry))
            if clash:
                raise ValueError(f"extra repeats keys of the frame entry: {clash}")
            entry.update(_jsonable(dict(extra)))
        return _jsonable(entry)

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
            self._write_convergence(frames)
            files["convergence"] = "convergence.png"
            t1 = _clock()
            pictures = self._render_pictures()
            if pictures == "written" and self.gif and self._pictures:
                self._write_gif()
                files["gif"] = "grasp.gif"
            t_render = _clock() - t1
            summary = {
                "scene": _jsonable(scene),
                "versions": _jsonable(versions if versions is not None else _versions()),
                "frames": [f.entry for f in frames],
                "all_converged": all(f.entry["converged"] for f in frames),
                "all_realistic": all(f.entry["verdict"]["realistic"] for f in frames),
                "pictures": pictures,
                "stress_components": list(STRESS_COMPONENTS),
                "files": files,
                "timings": {"pictures": t_render, "finish": _clock() - t0},
            }
            text = json.dumps(summary, indent=2, allow_nan=False) + "\n"
            _write_atomic(self.staging / "summary.json", text.encode())
            self._swap()
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
        """Remove the staging folder; the results folder stays as it was. Idempotent."""
        if self._state == "open":
            shutil.rmtree(self.staging, ignore_errors=True)
            self._state = "aborted"
            self._pictures.clear()
            log.debug("results for %s discarded", self.directory)

    # --- internals ---------------------------------------------------------------------

    def _require_open(self) -> None:
        if self._state != "open":
            raise RuntimeError(f"the results writer for {self.directory} is {self._state}")

    def _check_target(self) -> None:
        d = self.directory
        if d.exists() or d.is_symlink():
            if d.is_symlink() or not d.is_dir():
                raise OutputError(f"results folder {d} exists and is not a folder")
            if any(d.iterdir()) and not (d / "summary.json").is_file():
                raise OutputError(
                    f"results folder {d} exists and is not a results folder (no summary.json):"
                    " refusing to replace it"
                )

    def _swap(self) -> None:
        """Rename the old folder aside, the staging folder into place, delete the old."""
        self._check_target()
        d = self.directory
        old = None
        if d.exists():
            old = d.with_name(f".{d.name}.old-{uuid.uuid4().hex[:12]}")
            os.rename(d, old)
        try:
            os.rename(self.staging, d)
        except BaseException:
            if old is not None:
                try:
                    os.rename(old, d)
                except OSError:
                    log.error("the previous results of %s are left in %s", d, old)
            raise
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)

    def _write_pvd(self, frames: list[_Frame]) -> dict[str, str]:
        names = sorted({b for f in frames for b in f.vtu})
        out = {}
        for body in names:
            root = ET.Element(
                "VTKFile", type="Collection", version="0.1", byte_order="LittleEndian"
            )
            coll = ET.SubElement(root, "Collection")
            for f in frames:
                if body in f.vtu:
                    ET.SubElement(
                        coll, "DataSet", timestep=repr(f.time), group="", part="0", file=f.vtu[body]
                    )
            ET.indent(root)
            data = b'<?xml version="1.0"?>\n' + ET.tostring(root) + b"\n"
            _write_atomic(self.staging / f"{body}.pvd", data)
            out[body] = f"{body}.pvd"
        return out

    def _write_convergence(self, frames: list[_Frame]) -> None:
        from matplotlib import colormaps
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.cm import ScalarMappable
        from matplotlib.colors import Normalize
        from matplotlib.figure import Figure

        fig = Figure(figsize=(7.0, 4.5), dpi=100)
        FigureCanvasAgg(fig)
        ax = fig.add_subplot()
        drawn = [f for f in frames if f.history]
        many = len(drawn) > 10
        times = [f.time for f in drawn]
        norm = Normalize(min(times, default=0.0), max(times, default=1.0) or 1.0)
        cmap = colormaps["viridis"]
        for k, f in enumerate(drawn):
            y = np.asarray(f.history)
            y = np.where(y > 0, y, np.nan)  # a log scale cannot show a zero change
            it = np.arange(1, len(y) + 1)
            color = cmap(norm(f.time)) if many else f"C{k % 10}"
            ax.plot(it, y, "o-", ms=3, lw=1.2, color=color, label=f"t = {f.time:g}")
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
        _write_atomic(self.staging / "convergence.png", buf.getvalue())

    def _render_pictures(self) -> str:
        if not self.pictures:
            return "off"
        if not self._pictures:
            return "none (no frames)"
        ok, reason = rendering_available()
        if not ok:
            log.warning("pictures skipped: %s", reason)
            return f"skipped: {reason}"
        try:
            self._render_all()
        except OSError:
            raise  # a file that cannot be written: an error of the results folder
        except Exception as exc:  # pictures are not worth failing a run for
            shutil.rmtree(self.staging / "frames", ignore_errors=True)
            log.warning("pictures skipped: rendering failed: %s", exc, exc_info=True)
            return f"skipped: rendering failed: {type(exc).__name__}: {exc}"
        return "written"

    def _render_all(self) -> None:
        import pyvista as pv

        folder = self.staging / "frames"
        folder.mkdir(exist_ok=True)
        bounds = np.array(
            [s.bounds for p in self._pictures for s, _ in p.surfaces if s.n_points]
        ).reshape(-1, 6)
        lo, hi = bounds[:, 0::2].min(axis=0), bounds[:, 1::2].max(axis=0)
        center, span = 0.5 * (lo + hi), float((hi - lo).max()) or 1.0
        extent = self.planes_extent or 1.2 * span
        top = max(
            (float(np.nanmax(s["von_mises"])) for p in self._pictures for s, _ in p.surfaces),
            default=0.0,
        )
        clim = (0.0, top if top > 0 else 1.0)
        box = [lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]]
        if self.camera is not None:
            view = [tuple(map(float, v)) for v in self.camera]
        else:
            pos, _, up = _DEFAULT_VIEW
            view = [tuple(center + np.asarray(pos) * span), tuple(center), up]
        for pic in self._pictures:
            plotter = pv.Plotter(off_screen=True, window_size=list(self.window_size))
            try:
                plotter.set_background("white")
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
                for _, point, normal in pic.planes:
                    c = center - np.dot(center - point, normal) * normal
                    square = pv.Plane(center=c, direction=normal, i_size=extent, j_size=extent)
                    plotter.add_mesh(square, color="#8899aa", opacity=0.25, show_edges=False)
                plotter.add_text(
                    f"frame {pic.index}, t = {pic.time:g}", font_size=12, color="black"
                )
                plotter.camera_position = view
                plotter.reset_camera(bounds=box)
                plotter.camera.zoom(1.1)
                image = plotter.screenshot(return_img=True)
            finally:
                plotter.close()
            _write_atomic(folder / f"frame_{pic.index:04d}.png", _png_bytes(image))
        log.info("%d pictures rendered", len(self._pictures))

    def _write_gif(self) -> None:
        from ..hand.animation import write_gif

        pngs = [
            self.staging / "frames" / f"frame_{p.index:04d}.png"
            for p in sorted(self._pictures, key=lambda p: p.index)
        ]
        tmp = self.staging / f".grasp.{uuid.uuid4().hex[:12]}.gif"
        try:
            write_gif(pngs, tmp, fps=self.fps)
            os.replace(tmp, self.staging / "grasp.gif")
        finally:
            tmp.unlink(missing_ok=True)


def _surface(grid: pyvista.UnstructuredGrid) -> pyvista.PolyData:
    """The outer surface of a grid, with its point data."""
    try:
        return grid.extract_surface(algorithm="dataset_surface")
    except TypeError:  # pyvista before the ``algorithm`` keyword
        return grid.extract_surface()


def _unit(v: ArrayLike) -> NDArray[np.float64]:
    a = np.asarray(v, dtype=np.float64).reshape(3)
    n = float(np.linalg.norm(a))
    if not n > 0:
        raise ValueError(f"plane normal must be non-zero, got {a.tolist()}")
    return a / n


def _clock() -> float:
    return time.perf_counter()
