"""Reading a scene file (TOML) for ``python -m contact.grasp SCENE.toml``.

A scene is a ball, optionally a hand that grasps it (its rig, flesh, keyframes and
automatic flexions), rigid planes (a table, a moving plate), the frames to compute, the
solver's settings and what to write. ``docs/scene.md`` documents every key.

Reading is strict: an unknown key (the closest valid one is suggested), a wrong type (a
boolean is not a number), a missing required key or a value out of range raises
:class:`SceneError` with one line naming the file and the key path, e.g.
``grasp.toml: hand.keyframe[1].angles.index_pip = 200: outside its limits [0, 110]``.
List indices count from 0. This module reads; the defaults and range checks are the
dataclasses' (:mod:`contact.scene.model`, :mod:`contact.scene.spec`,
:class:`~contact.objects.ball.BallSpec`, :class:`~contact.solver.ContactSettings`), whose
failures it re-raises with the file and key path. What needs several sections is checked
here: the keyframes against the rig's skeleton (:mod:`contact.scene.read_hand`), frames
within the keyframes' span, planes that pass through each other or leave the ball's
centre behind them at a frame, a writable output folder, and the scene's estimated size
against the machine's memory (:mod:`contact.scene.sizing`), before anything is built.
Magnitudes are held within physical bounds (:mod:`contact.scene.bounds`). What needs the meshes (the
ball inside a bone, a ball held by nothing, an inverted element) is the CLI's to check.
"""

from __future__ import annotations

import math
import os
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._toml import MISSING, tomllib
from ..errors import ContactError, SceneError
from ..objects.ball import BallError, BallSpec
from ..solver import ContactSettings
from . import sizing
from ._reader import SceneReader
from .bounds import out_of_bounds
from .model import (
    CONTACT_KEYS,
    Follow,
    HandScene,
    Material,
    OutputScene,
    PlaneScene,
    SolverScene,
)
from .objects import read_objects
from .plausible import warn_coarse_gaps, warn_friction
from .read_hand import read_auto_flexion, read_follow, read_hand
from .spec import Scene

__all__ = ["load_scene"]

_TOP = ("scene", "ball", "object", "hand", "plane", "frames", "solver", "output")
_BALL = (
    "radius", "kind", "thickness", "pressure", "element", "mesh_size", "mesh", "center",
    "material", "follow", "nodal_pressure", "friction", "load",
)  # fmt: skip


def _read_scene(r: SceneReader, data: dict, path: Path) -> tuple[str, str, tuple | None]:
    sc = r.table(data.get("scene", {}), "scene", optional=("name", "description", "gravity"))
    name = r.string(sc["name"], "scene.name") if "name" in sc else path.stem
    desc = sc.get("description", Scene.description)
    if not isinstance(desc, str):
        raise r.fail("scene.description", desc, "must be a string")
    gravity = None
    if "gravity" in sc:
        gravity = r.bounded_vector(sc["gravity"], "scene.gravity", "acceleration")
        why = out_of_bounds("acceleration", math.hypot(*gravity))
        if why:
            raise r.fail("scene.gravity", sc["gravity"], why)
    return name, desc, gravity


def _read_ball(
    r: SceneReader, data: dict, base: Path
) -> tuple[BallSpec | None, dict | None, float | None]:
    """The ``[ball]`` table: a :class:`BallSpec` (which checks it), ``ball.follow``.

    And ``ball.friction``, None where not given (:class:`Scene` checks it).
    No ball (None) where the scene has ``[[object]]`` tables instead.
    """
    if "ball" not in data:
        if "object" in data:
            return None, None, None
        raise r.fail("ball", MISSING, "missing: a scene needs a [ball] table or [[object]] tables")
    b = r.table(data["ball"], "ball", required=("radius",), optional=_BALL)
    kw: dict[str, Any] = {}
    for key in ("radius", "thickness"):
        if key in b:
            kw[key] = r.bounded(b[key], f"ball.{key}", "length", positive=True)
    if "mesh_size" in b:  # bounded by the scene's size (contact.scene.sizing)
        kw["mesh_size"] = r.number(b["mesh_size"], "ball.mesh_size", positive=True)
    if "pressure" in b:
        kw["pressure"] = r.bounded(b["pressure"], "ball.pressure", "pressure")
    for key, choices in (("kind", ("solid", "hollow")), ("element", ("tet", "hex"))):
        if key in b:
            kw[key] = r.string(b[key], f"ball.{key}", choices)
    if "center" in b:
        kw["center"] = r.bounded_vector(b["center"], "ball.center", "position")
    if "nodal_pressure" in b:
        kw["nodal_pressure"] = r.boolean(b["nodal_pressure"], "ball.nodal_pressure")
    if "load" in b:  # [[t, fx, fy, fz, mx, my, mz], ...]: BallSpec checks the keys
        kw["load"] = b["load"]
    if "mesh" in b:
        if "mesh_size" in b:
            raise r.fail("ball.mesh", b["mesh"], "give mesh or mesh_size, not both")
        kw["mesh"] = r.file(b["mesh"], "ball.mesh", base)
    elif "mesh_size" not in b:
        raise r.fail("ball.mesh_size", MISSING, "missing: give mesh_size or a mesh file")
    if "material" in b:
        defaults = Material(BallSpec.E, BallSpec.nu, BallSpec.density)
        m = r.material(b["material"], "ball.material", defaults)
        kw.update(E=m.E, nu=m.nu, density=m.density, model=m.model)
    try:
        spec = BallSpec(**kw)
    except BallError as exc:
        raise SceneError(f"{r.source}: {exc}") from None
    friction = r.number(b["friction"], "ball.friction") if "friction" in b else None
    return spec, b.get("follow"), friction


def _check_size(
    r: SceneReader,
    ball: BallSpec | None,
    hand: HandScene | None,
    frames: int,
    frames_key: str,
    frames_value: Any,
) -> None:
    """Refuse a scene too big for the machine (:mod:`contact.scene.sizing`), warn of a big one."""
    size = sizing.estimate(ball, hand.resolution if hand else None, frames)
    avail = sizing.available_memory()
    frames_bytes = sizing.BYTES_PER_FRAME * frames
    too_many = frames > sizing.MAX_FRAMES
    if too_many or (avail is not None and size.memory > avail):
        has = "unknown" if avail is None else sizing.format_bytes(avail)
        why = f"too big: {size.describe()}, and the machine has {has} available"
        if too_many or frames_bytes > 0.5 * size.memory:
            why += f" (at most {sizing.MAX_FRAMES} frames)"
            raise r.fail(frames_key, frames_value, why)
        if ball is None:
            raise r.fail(frames_key, frames_value, why)
        if ball.mesh is not None:
            raise r.fail("ball.mesh", str(ball.mesh), why)
        raise r.fail("ball.mesh_size", ball.mesh_size, f"{why}: give a larger mesh_size")
    if (
        3 * size.ball_nodes > sizing.WARN_DOFS
        or frames > sizing.WARN_FRAMES
        or (avail is not None and size.memory > 0.5 * avail)
    ):
        sizing.log.warning("%s: a big scene: %s", r.source, size.describe())


def _read_frames(
    r: SceneReader, data: dict, hand: HandScene | None, ball: BallSpec | None
) -> tuple[float, ...]:
    """``[frames]``: the times, after the scene's size is checked against the machine."""
    if "frames" not in data:
        raise r.fail("frames", MISSING, "missing: give [frames] times = [...] or count = N")
    fr = r.table(data["frames"], "frames", optional=("times", "count"))
    if ("times" in fr) == ("count" in fr):
        raise r.fail("frames", fr, "give exactly one of times and count")
    if hand is not None:
        lo, hi = hand.keyframes[0]["time"], hand.keyframes[-1]["time"]
    else:
        lo, hi = 0.0, 1.0
    if "count" in fr:
        n = r.integer(fr["count"], "frames.count", 1)
        if n > 1 and not hi > lo:
            raise r.fail(
                "frames.count", n, f"the keyframes span no time (one keyframe at t = {lo:g}): "
                "the frames would repeat; give count = 1 or frames.times",
            )  # fmt: skip
        _check_size(r, ball, hand, n, "frames.count", fr["count"])
        return (lo,) if n == 1 else tuple(float(f"{t:.12g}") for t in np.linspace(lo, hi, n))
    times = r.times(fr["times"], "frames.times")
    for i, t in enumerate(times):
        why = out_of_bounds("time", t)
        if why:
            raise r.fail(f"frames.times[{i}]", fr["times"][i], why)
    _check_size(r, ball, hand, len(times), "frames.times", MISSING)
    if hand is not None:
        tol = 1e-9 * max(1.0, hi - lo)
        for i, t in enumerate(times):
            if not lo - tol <= t <= hi + tol:
                raise r.fail(
                    f"frames.times[{i}]", fr["times"][i],
                    f"outside the keyframes' span [{lo:g}, {hi:g}]",
                )  # fmt: skip
    return times


def _read_planes(r: SceneReader, data: dict) -> tuple[PlaneScene, ...]:
    value = data.get("plane", [])
    if not isinstance(value, list):
        raise r.fail("plane", value, "must be an array of tables ([[plane]])")
    planes: list[PlaneScene] = []
    for i, p in enumerate(value):
        where = f"plane[{i}]"
        r.table(
            p, where, required=("name", "point", "normal"),
            optional=("offsets", "friction", "force"),
        )  # fmt: skip
        name = r.string(p["name"], f"{where}.name")
        if any(q.name == name for q in planes):
            raise r.fail(f"{where}.name", name, "another plane has this name")
        point = r.bounded_vector(p["point"], f"{where}.point", "position")
        n = np.array(r.vector(p["normal"], f"{where}.normal"))
        big = np.abs(n).max()
        if not big > 0:
            raise r.fail(f"{where}.normal", p["normal"], "must be a non-zero vector")
        n = n / big  # scaled first: the norm of [1e200, 0, 1e200] does not overflow
        norm = np.linalg.norm(n)
        raw = p.get("offsets", [])
        if not isinstance(raw, list):
            raise r.fail(f"{where}.offsets", raw, "must be a list of [time, dx, dy, dz]")
        offsets = []
        for j, k in enumerate(raw):
            t, *d = r.vector(k, f"{where}.offsets[{j}]", 4)
            for x, kind in zip((t, *d), ("time", "position", "position", "position")):
                why = out_of_bounds(kind, x)
                if why:
                    raise r.fail(f"{where}.offsets[{j}]", k, why)
            offsets.append((t, tuple(d)))
        raw = p.get("force", [])
        if not isinstance(raw, list):
            raise r.fail(f"{where}.force", raw, "must be a list of [time, N]")
        force = [tuple(r.vector(k, f"{where}.force[{j}]", 2)) for j, k in enumerate(raw)]
        for j, (t, _) in enumerate(force):
            why = out_of_bounds("time", t)
            if why:
                raise r.fail(f"{where}.force[{j}]", raw[j], why)
        normal = tuple(float(x) for x in n / norm)
        mu = r.number(p["friction"], f"{where}.friction") if "friction" in p else None
        planes.append(
            r.build(where, PlaneScene, name, point, normal, tuple(offsets), mu, tuple(force))
        )
    return tuple(planes)


def _check_planes(
    r: SceneReader,
    planes: tuple[PlaneScene, ...],
    ball: BallSpec,
    frames: tuple[float, ...],
    follow: Follow | None,
) -> None:
    """Planes must keep the ball's centre in front and must not pass through each other."""
    c = np.array(ball.center)

    def blame(i: int) -> tuple[str, Any]:
        p = planes[i]
        if p.offsets:
            return f"plane[{i}].offsets", [[t, *d] for t, d in p.offsets]
        return f"plane[{i}].point", list(p.point)

    def place(t: float) -> tuple[list[NDArray], list[NDArray]]:
        return [np.array(p.point) + p.offset(t) for p in planes], [
            np.array(p.normal) for p in planes
        ]

    for k, t in enumerate(frames):  # first planes through planes, at any frame
        pts, nrm = place(t)
        for i in range(len(planes)):
            for j in range(i + 1, len(planes)):
                if not nrm[i] @ nrm[j] < 0:
                    continue  # not facing each other
                d = nrm[i] - nrm[j]
                d /= np.linalg.norm(d)
                # along the line c + s d the ball side of i is s > s_i, that of j is s < s_j
                s_i = float((pts[i] - c) @ nrm[i] / (d @ nrm[i]))
                s_j = float((pts[j] - c) @ nrm[j] / (d @ nrm[j]))
                if s_j - s_i < 0:
                    worst = j if planes[j].offsets or not planes[i].offsets else i
                    other = planes[i + j - worst].name
                    raise r.fail(
                        *blame(worst),
                        f"at frame {k} (t = {t:g}) the planes {planes[worst].name!r} and "
                        f"{other!r} have passed through each other (distance {s_j - s_i:.6g} m "
                        "between them along their normals): no room for the ball",
                    )
    for k, t in enumerate(frames):  # then the ball's centre behind a plane
        if follow is not None and t > follow.start:
            break  # the ball has moved with the hand
        pts, nrm = place(t)
        for i, p in enumerate(planes):
            dist = float((c - pts[i]) @ nrm[i])
            if dist < 0:
                start = float((c - np.array(p.point) - p.offset(frames[0])) @ nrm[i])
                why = (
                    "the plane has moved past it"
                    if start >= 0
                    else "the plane's normal must point toward the ball"
                )
                raise r.fail(
                    *blame(i),
                    f"at frame {k} (t = {t:g}) the ball's centre {list(ball.center)} lies "
                    f"behind the plane {p.name!r} (signed distance {dist:.6g} m): {why}",
                )


def _read_solver(r: SceneReader, data: dict) -> SolverScene:
    """``[solver]``: the contact settings (:class:`ContactSettings` checks them) and more."""
    s = r.table(
        data.get("solver", {}), "solver", optional=(*CONTACT_KEYS, "linear_solver", "substeps")
    )
    kw: dict[str, Any] = {}
    for key in ("algorithm", "relaxation", "gaps"):
        if key in s:
            kw[key] = r.string(s[key], f"solver.{key}")
    if "max_iterations" in s:
        kw["max_iterations"] = r.integer(s["max_iterations"], "solver.max_iterations")
    for key in ("tolerance", "gap_tolerance", "force_tolerance", "relaxation_factor"):
        if key in s:
            kw[key] = r.number(s[key], f"solver.{key}")
    try:
        contact = ContactSettings(**kw)
    except ContactError as exc:  # "solver.<key> <why>, got <value>": the key path is given
        text = str(exc)
        for key in kw:
            if text.startswith(f"solver.{key} "):
                why = text.removeprefix(f"solver.{key} ").rsplit(", got ", 1)[0]
                raise r.fail(f"solver.{key}", s[key], why) from None
        raise SceneError(f"{r.source}: {text}") from None
    more = {}
    if "linear_solver" in s:
        more["linear_solver"] = r.string(s["linear_solver"], "solver.linear_solver")
    if "substeps" in s:
        more["substeps"] = r.integer(s["substeps"], "solver.substeps", minimum=1)
    return r.build("solver", SolverScene, contact, **more)


def _writable(directory: Path) -> str | None:
    """Why ``directory`` cannot be created or written, or None."""
    full = Path(os.path.abspath(directory))
    if full.exists():
        if not full.is_dir():
            return f"{full} exists and is not a folder"
        return None if os.access(full, os.W_OK | os.X_OK) else f"{full} is not writable"
    parent = full.parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        return f"cannot create it: {parent} is not a folder"
    if not os.access(parent, os.W_OK | os.X_OK):
        return f"cannot create it: {parent} is not writable"
    return None


def _read_output(r: SceneReader, data: dict) -> OutputScene:
    o = r.table(data.get("output", {}), "output", optional=OutputScene.__dataclass_fields__)
    kw: dict[str, Any] = {}
    if "directory" in o:
        kw["directory"] = Path(r.string(o["directory"], "output.directory"))
    directory = kw.get("directory", OutputScene.directory)
    why = _writable(directory.expanduser())
    if why:
        raise r.fail("output.directory", str(directory), why)
    if "window_size" in o:
        size = o["window_size"]
        if not isinstance(size, list) or len(size) != 2:
            raise r.fail("output.window_size", size, "must be [width, height] in pixels")
        kw["window_size"] = tuple(
            r.integer(v, f"output.window_size[{i}]") for i, v in enumerate(size)
        )
    for key in ("pictures", "gif"):
        if key in o:
            kw[key] = r.boolean(o[key], f"output.{key}")
    return r.build("output", OutputScene, **kw)


def load_scene(path: str | os.PathLike) -> Scene:
    """Read and validate a scene file.

    Parameters
    ----------
    path : str or path-like
        A TOML scene file (``docs/scene.md``). Relative paths inside it (``ball.mesh``,
        ``hand.rig``, ``hand.directory``) are taken from its folder; ``output.directory``
        from the current working directory.

    Returns
    -------
    Scene

    Raises
    ------
    SceneError
        One line naming the file and the key path of the first problem found.
    """
    source = str(path)
    r = SceneReader(source)
    p = Path(path)
    try:
        text = p.read_bytes()
    except FileNotFoundError:
        raise SceneError(f"{source}: no such scene file") from None
    except OSError as exc:
        raise SceneError(f"{source}: cannot read the scene file ({exc.strerror or exc})") from None
    try:
        data = tomllib.loads(text.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise SceneError(f"{source}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{source}: not valid TOML: {exc}") from None
    r.table(data, "", optional=_TOP)
    base = p.resolve().parent
    name, description, gravity = _read_scene(r, data, p)
    ball, follow_data, ball_friction = _read_ball(r, data, base)
    read = read_hand(r, data, base)
    hand, skeleton = read if read is not None else (None, None)
    follow = read_follow(r, follow_data, skeleton)
    frames = _read_frames(r, data, hand, ball)
    if hand is not None and "auto_flexion" in data["hand"]:
        auto = read_auto_flexion(r, data["hand"]["auto_flexion"], skeleton, frames)
        hand = replace(hand, auto_flexion=auto)
    planes = _read_planes(r, data)
    if ball is not None:
        _check_planes(r, planes, ball, frames, follow)
    objects = read_objects(r, data, base, skeleton, tuple(p.name for p in planes))
    solver = _read_solver(r, data)
    output = _read_output(r, data)
    scene = r.build(
        "",
        Scene,
        path=p.resolve(),
        name=name,
        ball=ball,
        hand=hand,
        planes=planes,
        follow=follow,
        frames=frames,
        gravity=gravity,
        solver=solver,
        output=output,
        description=description,
        objects=objects,
        ball_friction=ball_friction,
    )
    warn_friction(scene, source)
    warn_coarse_gaps(scene, source)
    return scene
