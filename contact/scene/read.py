"""Reading a scene file (TOML) for ``python -m contact.grasp SCENE.toml``.

A scene is a ball, optionally a hand that grasps it (its rig, flesh, keyframes and
automatic flexions), rigid planes (a table, a moving plate), the frames to compute, the
solver's settings and what to write. ``docs/scene.md`` documents every key.

Reading is strict: an unknown key (the closest valid one is suggested), a wrong type (a
boolean is not a number), a missing required key or a value out of range raises
:class:`SceneError` with one line naming the file and the key path, e.g.
``grasp.toml: hand.keyframe[1].angles.index_pip = 200: outside its limits [0, 110]``.
List indices count from 0. The loader checks what it can without the hand meshes: the
ball's own validation (:class:`~contact.ball.BallSpec`), the mesh file's presence, the
keyframes against the rig's skeleton (:func:`~contact.hand.skeleton.load_skeleton`), frames
within the keyframes' span, planes that pass through each other or leave the ball's
centre behind them at a frame, and a writable output folder. What needs the meshes (the
ball inside a bone, a ball held by nothing, an inverted element) is the CLI's to check.
"""

from __future__ import annotations

import difflib
import math
import os
import sys
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

import fem
from fem.linsolve import BACKENDS

from ..ball import BallError, BallSpec
from ..errors import RigError, SceneError
from ..hand.autoflex import FINGERTIPS
from ..hand.keyframes import Keyframes
from ..hand.shipped import HAND_DIR, RESOLUTIONS, hand_files
from ..hand.skeleton import Skeleton, load_skeleton
from ..solver.iteration import ALGORITHMS, RELAXATIONS, ContactSettings

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = [
    "LINEAR_SOLVERS",
    "AutoFlex",
    "Follow",
    "HandScene",
    "Material",
    "OutputScene",
    "PlaneScene",
    "Scene",
    "SceneError",
    "SolverScene",
    "load_scene",
]

#: Names ``solver.linear_solver`` accepts.
LINEAR_SOLVERS = ("auto", *BACKENDS)
_RESERVED = ("ball", "hand")  # body names a plane may not take
_MISSING = object()


# --------------------------------------------------------------------------- data


@dataclass(frozen=True)
class Material:
    """A linear elastic material: Young's modulus (Pa), Poisson's ratio, density (kg/m^3)."""

    E: float
    nu: float
    density: float = 1000.0

    def elastic(self) -> fem.LinearElastic:
        """The material as :class:`fem.LinearElastic`."""
        return fem.LinearElastic(self.E, self.nu, self.density)


@dataclass(frozen=True)
class AutoFlex:
    """An automatic flexion (:func:`contact.auto_flex`): bend ``joint`` until ``point`` touches.

    Attributes
    ----------
    joint : str
        The angle searched (``"index_pip"``, ``"thumb_cmc_pivot"``...).
    point : str or int
        A fingertip name (:data:`contact.hand.autoflex.FINGERTIPS`) or a flesh node index.
    epsilon : float
        Tolerance on the distance (m).
    press : float
        Depth (m) to press past first contact.
    times : tuple of float or None
        Frame times at which it applies; None: every frame.
    first_contact : bool
        Stop at the first skin node the joint brings to the ball (``point`` or another,
        a finger's pad before its tip); False: ``point`` alone, as the seed.
    """

    joint: str
    point: str | int
    epsilon: float = 1e-4
    press: float = 0.0
    times: tuple[float, ...] | None = None
    first_contact: bool = True


@dataclass(frozen=True)
class HandScene:
    """The ``[hand]`` table.

    Attributes
    ----------
    rig : Path
        The rig file (absolute).
    directory : Path or None
        Folder of the hand meshes (absolute; the shipped ``meshes/hand`` by default).
    resolution : {"coarse", "fine"}
    flesh : Material
    bone_force_limit : float or None
        Largest force (N) on any one bone; None: no limit.
    bone_force_limits : dict of str to float
        Per-bone limits (N) overriding ``bone_force_limit``.
    keyframes : tuple of dict
        ``{time, angles, tension, continuity, bias}`` per key, validated against the rig;
        as :class:`contact.Keyframes` takes them.
    auto_flexion : tuple of AutoFlex
    nodal_pressure : bool or None
        The flesh's tetrahedra with averaged nodal pressures (no volumetric locking);
        None: where ``flesh.nu`` is above :data:`contact.ball.LOCKING_NU`, as for a tet
        ball.
    """

    rig: Path
    directory: Path | None
    resolution: str
    flesh: Material
    bone_force_limit: float | None
    bone_force_limits: dict[str, float]
    keyframes: tuple[dict, ...]
    auto_flexion: tuple[AutoFlex, ...] = ()
    nodal_pressure: bool | None = None

    def limits(self, bone_names: Iterable[str]) -> dict[str, float]:
        """The force limit (N) of each bone: its override, else the global one, else none.

        Parameters
        ----------
        bone_names : iterable of str

        Returns
        -------
        dict of str to float
            Only the bones that have a limit.
        """
        out = {}
        for name in bone_names:
            if name in self.bone_force_limits:
                out[name] = self.bone_force_limits[name]
            elif self.bone_force_limit is not None:
                out[name] = self.bone_force_limit
        return out


@dataclass(frozen=True)
class PlaneScene:
    """A rigid plane: the ball side is where ``normal`` points.

    Attributes
    ----------
    name : str
    point : tuple of 3 floats
        A point of the plane at rest (m).
    normal : tuple of 3 floats
        Unit normal (the file's normal, normalised).
    offsets : tuple of (float, (float, float, float))
        ``(time, translation)`` keys, times increasing: the plane's rigid translation (m),
        piecewise linear between keys and constant outside; empty: the plane is fixed.
    """

    name: str
    point: tuple[float, float, float]
    normal: tuple[float, float, float]
    offsets: tuple[tuple[float, tuple[float, float, float]], ...] = ()

    def offset(self, time: float) -> NDArray[np.float64]:
        """The plane's translation (m) at ``time``, shape (3,)."""
        if not self.offsets:
            return np.zeros(3)
        t = np.array([k[0] for k in self.offsets])
        d = np.array([k[1] for k in self.offsets])
        return np.array([np.interp(time, t, d[:, i]) for i in range(3)])


@dataclass(frozen=True)
class Follow:
    """The ball follows a hand joint from ``start`` to ``stop`` (:class:`ObjectAssociation`)."""

    joint: str
    start: float
    stop: float


@dataclass(frozen=True)
class SolverScene:
    """The ``[solver]`` table; see :class:`contact.solver.iteration.ContactSettings`."""

    algorithm: str = "contact-space"
    max_iterations: int = 50
    tolerance: float = 1e-4
    gap_tolerance: float = 1e-3
    force_tolerance: float = 1e-9
    relaxation: str = "none"
    relaxation_factor: float = 0.5
    linear_solver: str = "auto"

    def settings(self, support_limits: Mapping[str, float]) -> ContactSettings:
        """The contact settings, with the force limit of each support group (bone)."""
        return ContactSettings(
            algorithm=self.algorithm,
            max_iterations=self.max_iterations,
            tolerance=self.tolerance,
            gap_tolerance=self.gap_tolerance,
            force_tolerance=self.force_tolerance,
            relaxation=self.relaxation,
            relaxation_factor=self.relaxation_factor,
            support_limits=dict(support_limits),
        )


@dataclass(frozen=True)
class OutputScene:
    """The ``[output]`` table.

    Attributes
    ----------
    directory : Path
        Results folder, as written (relative to the current working directory).
    pictures : bool
        Write PNG pictures of the stress.
    gif : bool
        Write an animated GIF of the frames.
    window_size : (int, int)
        Picture size in pixels.
    """

    directory: Path = Path("results")
    pictures: bool = True
    gif: bool = True
    window_size: tuple[int, int] = (1024, 768)


@dataclass(frozen=True)
class Scene:
    """A validated scene (see :func:`load_scene`).

    Attributes
    ----------
    path : Path
        The scene file (absolute).
    name : str
        ``scene.name``, default the file's stem.
    ball : BallSpec
    hand : HandScene or None
    planes : tuple of PlaneScene
    follow : Follow or None
    frames : tuple of float
        Times to compute, increasing.
    gravity : (float, float, float) or None
        m/s^2; None: no gravity.
    solver : SolverScene
    output : OutputScene
    description : str
        ``scene.description``.
    """

    path: Path
    name: str
    ball: BallSpec
    hand: HandScene | None
    planes: tuple[PlaneScene, ...]
    follow: Follow | None
    frames: tuple[float, ...]
    gravity: tuple[float, float, float] | None
    solver: SolverScene
    output: OutputScene
    description: str = ""

    def echo(self) -> dict:
        """The whole scene with its defaults filled in, JSON-serialisable, in the file's layout.

        Paths are strings; ``None`` stands for an absent optional value.
        """
        b = self.ball
        ball = {
            "radius": b.radius,
            "kind": b.kind,
            "thickness": b.thickness,
            "pressure": b.pressure,
            "element": b.element,
            "mesh_size": b.mesh_size,
            "mesh": None if b.mesh is None else str(b.mesh),
            "center": list(b.center),
            "material": {"E": b.E, "nu": b.nu, "density": b.density},
            "nodal_pressure": b.nodal_pressure,
            "follow": None if self.follow is None else _fields(self.follow),
        }
        hand = None
        if self.hand is not None:
            h = self.hand
            hand = {
                "rig": str(h.rig),
                "directory": None if h.directory is None else str(h.directory),
                "resolution": h.resolution,
                "flesh": _fields(h.flesh),
                "bone_force_limit": h.bone_force_limit,
                "bone_force_limits": dict(h.bone_force_limits),
                "keyframe": [{**k, "angles": dict(k["angles"])} for k in h.keyframes],
                "auto_flexion": [
                    {**_fields(a), "times": None if a.times is None else list(a.times)}
                    for a in h.auto_flexion
                ],
                "nodal_pressure": h.nodal_pressure,
            }
        return {
            "path": str(self.path),
            "scene": {
                "name": self.name,
                "description": self.description,
                "gravity": None if self.gravity is None else list(self.gravity),
            },
            "ball": ball,
            "hand": hand,
            "plane": [
                {
                    "name": p.name,
                    "point": list(p.point),
                    "normal": list(p.normal),
                    "offsets": [[t, *d] for t, d in p.offsets],
                }
                for p in self.planes
            ],
            "frames": {"times": list(self.frames)},
            "solver": _fields(self.solver),
            "output": {
                "directory": str(self.output.directory),
                "pictures": self.output.pictures,
                "gif": self.output.gif,
                "window_size": list(self.output.window_size),
            },
        }


def _fields(obj: Any) -> dict:
    return {k: getattr(obj, k) for k in obj.__dataclass_fields__}


# --------------------------------------------------------------------------- reading


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _hint(key: str, options: Iterable[str]) -> str:
    """``"; did you mean 'x'?"`` for the closest option (difflib, else a unique prefix)."""
    options = list(options)
    close = difflib.get_close_matches(key, options, n=1)
    if not close:
        close = [o for o in options if o.startswith(key) or key.startswith(o)][:1]
    return f"; did you mean {close[0]!r}?" if close else ""


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


class _Reader:
    """Typed access to TOML values; every failure is a one-line :class:`SceneError`."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, path: str, value: Any, why: str) -> SceneError:
        if value is _MISSING:
            return SceneError(f"{self.source}: {path}: {why}")
        return SceneError(f"{self.source}: {path} = {_short(value)}: {why}")

    def table(
        self, data: Any, path: str, required: Iterable[str] = (), optional: Iterable[str] = ()
    ) -> dict:
        """Check that ``data`` is a table with only allowed keys and the required ones."""
        required, optional = set(required), set(optional)
        allowed = required | optional
        if not isinstance(data, dict):
            raise self.fail(path, data, "must be a table")
        for key in data:
            if key not in allowed:
                hint = _hint(key, sorted(allowed))
                raise SceneError(
                    f"{self.source}: {_join(path, key)}: unknown key{hint} "
                    f"(allowed: {', '.join(sorted(allowed))})"
                )
        for key in sorted(required):
            if key not in data:
                raise self.fail(_join(path, key), _MISSING, "missing (required)")
        return data

    def number(
        self,
        value: Any,
        path: str,
        *,
        positive: bool = False,
        nonnegative: bool = False,
    ) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(path, value, "must be a number")
        if not math.isfinite(value):
            raise self.fail(path, value, "must be finite")
        if positive and not value > 0:
            raise self.fail(path, value, "must be positive")
        if nonnegative and value < 0:
            raise self.fail(path, value, "must not be negative")
        return float(value)

    def integer(self, value: Any, path: str, minimum: int) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(path, value, "must be an integer")
        if value < minimum:
            raise self.fail(path, value, f"must be at least {minimum}")
        return value

    def boolean(self, value: Any, path: str) -> bool:
        if not isinstance(value, bool):
            raise self.fail(path, value, "must be true or false")
        return value

    def string(self, value: Any, path: str, choices: Iterable[str] | None = None) -> str:
        if not isinstance(value, str) or not value:
            raise self.fail(path, value, "must be a non-empty string")
        if choices is not None:
            choices = tuple(choices)
            if value not in choices:
                raise self.fail(path, value, f"unknown; expected one of {', '.join(choices)}")
        return value

    def vector(self, value: Any, path: str, n: int = 3) -> tuple[float, ...]:
        if not isinstance(value, list) or len(value) != n:
            raise self.fail(path, value, f"must be a list of {n} numbers")
        return tuple(self.number(v, f"{path}[{i}]") for i, v in enumerate(value))

    def times(self, value: Any, path: str) -> tuple[float, ...]:
        """A non-empty list of strictly increasing times."""
        if not isinstance(value, list) or not value:
            raise self.fail(path, value, "must be a non-empty list of numbers")
        out = tuple(self.number(v, f"{path}[{i}]") for i, v in enumerate(value))
        for i in range(1, len(out)):
            if not out[i] > out[i - 1]:
                raise self.fail(
                    f"{path}[{i}]", value[i], f"times must increase (previous {out[i - 1]:g})"
                )
        return out

    def material(self, value: Any, path: str, defaults: Material) -> Material:
        self.table(value, path, optional=("E", "nu", "density"))
        e = self.number(value.get("E", defaults.E), f"{path}.E")
        nu = self.number(value.get("nu", defaults.nu), f"{path}.nu")
        rho = self.number(value.get("density", defaults.density), f"{path}.density")
        if e <= 0:
            raise self.fail(f"{path}.E", value.get("E"), "must be positive")
        if not -1.0 < nu < 0.5:
            raise self.fail(f"{path}.nu", value.get("nu"), "must be above -1 and below 0.5")
        if rho < 0:
            raise self.fail(f"{path}.density", value.get("density"), "must not be negative")
        return Material(e, nu, rho)

    def file(self, value: Any, path: str, base: Path) -> Path:
        """An existing readable file, relative paths against ``base``."""
        name = self.string(value, path)
        full = (base / Path(name).expanduser()).resolve()
        if not full.exists():
            raise self.fail(path, value, f"no such file ({full})")
        if not full.is_file():
            raise self.fail(path, value, f"not a file ({full})")
        try:
            with open(full, "rb") as f:
                f.read(1)
        except OSError as exc:
            raise self.fail(path, value, f"cannot be read ({exc.strerror or exc})") from None
        return full


# --------------------------------------------------------------------------- sections

_TOP = ("scene", "ball", "hand", "plane", "frames", "solver", "output")
_BALL = (
    "radius", "kind", "thickness", "pressure", "element", "mesh_size", "mesh", "center",
    "material", "follow", "nodal_pressure",
)  # fmt: skip
_HAND = (
    "rig", "directory", "resolution", "flesh", "bone_force_limit", "bone_force_limits",
    "keyframe", "auto_flexion", "nodal_pressure",
)  # fmt: skip
_FLESH = Material(5.0e4, 0.45, 1000.0)


def _read_scene(r: _Reader, data: dict, path: Path) -> tuple[str, str, tuple | None]:
    sc = r.table(data.get("scene", {}), "scene", optional=("name", "description", "gravity"))
    name = r.string(sc["name"], "scene.name") if "name" in sc else path.stem
    desc = sc.get("description", "")
    if not isinstance(desc, str):
        raise r.fail("scene.description", desc, "must be a string")
    gravity = r.vector(sc["gravity"], "scene.gravity") if "gravity" in sc else None
    return name, desc, gravity


def _read_ball(r: _Reader, data: dict, base: Path) -> tuple[BallSpec, dict | None]:
    if "ball" not in data:
        raise r.fail("ball", _MISSING, "missing: a scene needs a [ball] table")
    b = r.table(data["ball"], "ball", required=("radius",), optional=_BALL)
    kw: dict[str, Any] = {}
    for key in ("radius", "thickness", "mesh_size"):
        if key in b:
            kw[key] = r.number(b[key], f"ball.{key}", positive=True)
    if "pressure" in b:
        kw["pressure"] = r.number(b["pressure"], "ball.pressure")
    for key, choices in (("kind", ("solid", "hollow")), ("element", ("tet", "hex"))):
        if key in b:
            kw[key] = r.string(b[key], f"ball.{key}", choices)
    if "center" in b:
        kw["center"] = r.vector(b["center"], "ball.center")
    if "nodal_pressure" in b:
        kw["nodal_pressure"] = r.boolean(b["nodal_pressure"], "ball.nodal_pressure")
    if "mesh" in b:
        if "mesh_size" in b:
            raise r.fail("ball.mesh", b["mesh"], "give mesh or mesh_size, not both")
        kw["mesh"] = r.file(b["mesh"], "ball.mesh", base)
    elif "mesh_size" not in b:
        raise r.fail("ball.mesh_size", _MISSING, "missing: give mesh_size or a mesh file")
    if "material" in b:
        defaults = Material(BallSpec.E, BallSpec.nu, BallSpec.density)
        m = r.material(b["material"], "ball.material", defaults)
        kw.update(E=m.E, nu=m.nu, density=m.density)
    try:
        spec = BallSpec(**kw)
    except BallError as exc:
        raise SceneError(f"{r.source}: {exc}") from None
    return spec, b.get("follow")


def _read_hand(r: _Reader, data: dict, base: Path) -> tuple[HandScene, Skeleton] | None:
    if "hand" not in data:
        return None
    h = r.table(data["hand"], "hand", required=("keyframe",), optional=_HAND)
    directory = (
        (base / Path(r.string(h["directory"], "hand.directory")).expanduser()).resolve()
        if "directory" in h
        else HAND_DIR
    )
    if "directory" in h and not directory.is_dir():
        raise r.fail("hand.directory", h["directory"], f"no such folder ({directory})")
    resolution = r.string(h.get("resolution", "coarse"), "hand.resolution", RESOLUTIONS)
    for kind, f in hand_files(resolution, directory).items():
        if kind != "rig" and not f.is_file():
            key = "hand.directory" if "directory" in h else "hand.resolution"
            raise r.fail(key, h.get(key.split(".")[1], resolution), f"no {f.name} in {directory}")
    rig = r.file(h["rig"], "hand.rig", base) if "rig" in h else directory / "rig.toml"
    try:
        skeleton = load_skeleton(rig)
    except (RigError, OSError) as exc:
        raise r.fail("hand.rig", h.get("rig", str(rig)), f"bad rig: {exc}") from None
    own = directory / "rig.toml"  # the rig the meshes were built from (load_hand reads it)
    if "rig" in h and own.is_file() and own.resolve() != rig.resolve():
        try:
            theirs = load_skeleton(own)
        except (RigError, OSError):
            theirs = None
        if theirs is None or (theirs.bone_names, theirs.joint_names) != (
            skeleton.bone_names,
            skeleton.joint_names,
        ):
            raise r.fail(
                "hand.rig", h["rig"], f"its joints and bones differ from those of the meshes' {own}"
            )
    flesh = r.material(h.get("flesh", {}), "hand.flesh", _FLESH)
    limit = None
    if "bone_force_limit" in h:
        limit = r.number(h["bone_force_limit"], "hand.bone_force_limit", positive=True)
    per_bone = h.get("bone_force_limits", {})
    if not isinstance(per_bone, dict):
        raise r.fail("hand.bone_force_limits", per_bone, "must be a table {bone = N}")
    limits = {}
    for bone, v in per_bone.items():
        where = f"hand.bone_force_limits.{bone}"
        if bone not in skeleton.bones:
            hint = _hint(bone, skeleton.bone_names)
            raise r.fail(where, v, f"unknown bone{hint} (bones: {', '.join(skeleton.bone_names)})")
        limits[bone] = r.number(v, where, positive=True)
    keys = _read_keyframes(r, h["keyframe"], skeleton)
    nodal = None
    if "nodal_pressure" in h:
        nodal = r.boolean(h["nodal_pressure"], "hand.nodal_pressure")
    hand = HandScene(
        rig=rig,
        directory=directory,
        resolution=resolution,
        flesh=flesh,
        bone_force_limit=limit,
        bone_force_limits=limits,
        keyframes=keys,
        auto_flexion=(),
        nodal_pressure=nodal,
    )
    return hand, skeleton


def _read_keyframes(r: _Reader, value: Any, skeleton: Skeleton) -> tuple[dict, ...]:
    if not isinstance(value, list) or not value:
        raise r.fail(
            "hand.keyframe", value, "must be a non-empty array of tables ([[hand.keyframe]])"
        )
    limits = skeleton.limits
    keys: list[dict] = []
    for i, k in enumerate(value):
        where = f"hand.keyframe[{i}]"
        r.table(k, where, required=("time", "angles"), optional=("tension", "continuity", "bias"))
        t = r.number(k["time"], f"{where}.time")
        if keys and not t > keys[-1]["time"]:
            raise r.fail(
                f"{where}.time",
                k["time"],
                f"key times must increase (previous key at t = {keys[-1]['time']:g})",
            )
        angles = k["angles"]
        if not isinstance(angles, dict):
            raise r.fail(f"{where}.angles", angles, "must be a table of angles (degrees)")
        out = {}
        for name, v in angles.items():
            path = f"{where}.angles.{name}"
            if name not in limits:
                hint = _hint(name, list(limits))
                raise r.fail(path, v, f"unknown joint angle{hint} (angles: {', '.join(limits)})")
            x = r.number(v, path)
            lo, hi = limits[name]
            if not lo <= x <= hi:
                raise r.fail(path, v, f"outside its limits [{lo:g}, {hi:g}]")
            out[name] = x
        key = {"time": t, "angles": out}
        for name in ("tension", "continuity", "bias"):
            x = r.number(k.get(name, 0.0), f"{where}.{name}")
            if not -1.0 <= x <= 1.0:
                raise r.fail(f"{where}.{name}", k[name], "must lie in [-1, 1]")
            key[name] = x
        keys.append(key)
    try:
        Keyframes(skeleton, keys)
    except RigError as exc:  # pragma: no cover - the checks above come first
        raise r.fail("hand.keyframe", _MISSING, str(exc)) from None
    return tuple(keys)


def _read_auto_flexion(
    r: _Reader, value: Any, skeleton: Skeleton, frames: tuple[float, ...]
) -> tuple[AutoFlex, ...]:
    if not isinstance(value, list):
        raise r.fail(
            "hand.auto_flexion", value, "must be an array of tables ([[hand.auto_flexion]])"
        )
    out: list[AutoFlex] = []
    for i, a in enumerate(value):
        where = f"hand.auto_flexion[{i}]"
        r.table(
            a,
            where,
            required=("joint", "point"),
            optional=("epsilon", "press", "times", "first_contact"),
        )
        joint = r.string(a["joint"], f"{where}.joint")
        if joint not in skeleton.limits:
            hint = _hint(joint, list(skeleton.limits))
            raise r.fail(f"{where}.joint", joint, f"unknown joint angle{hint}")
        p = a["point"]
        if isinstance(p, str):
            point: str | int = r.string(p, f"{where}.point", FINGERTIPS)
        elif isinstance(p, int) and not isinstance(p, bool):
            point = r.integer(p, f"{where}.point", 0)
        else:
            raise r.fail(
                f"{where}.point",
                p,
                f"must be a fingertip ({', '.join(FINGERTIPS)}) or a node index",
            )
        eps = r.number(a.get("epsilon", AutoFlex.epsilon), f"{where}.epsilon", positive=True)
        press = r.number(a.get("press", 0.0), f"{where}.press", nonnegative=True)
        times = None
        if "times" in a:
            times = r.times(a["times"], f"{where}.times")
            for j, t in enumerate(times):
                if not any(math.isclose(t, f, rel_tol=1e-9, abs_tol=1e-12) for f in frames):
                    raise r.fail(f"{where}.times[{j}]", a["times"][j], "not one of the frame times")
        for prev in out:
            if prev.joint == joint and (
                prev.times is None or times is None or set(prev.times) & set(times)
            ):
                raise r.fail(
                    f"{where}.joint",
                    joint,
                    "already searched by an earlier auto_flexion at these times",
                )
        first = r.boolean(a.get("first_contact", True), f"{where}.first_contact")
        out.append(AutoFlex(joint, point, eps, press, times, first))
    return tuple(out)


def _read_follow(r: _Reader, value: Any, skeleton: Skeleton | None) -> Follow | None:
    if value is None:
        return None
    f = r.table(value, "ball.follow", required=("joint", "start", "stop"))
    joint = r.string(f["joint"], "ball.follow.joint")
    if skeleton is None:
        raise r.fail("ball.follow.joint", joint, "the ball can follow a joint only with a [hand]")
    if joint not in skeleton.joint_names:
        hint = _hint(joint, skeleton.joint_names)
        raise r.fail("ball.follow.joint", joint, f"unknown joint{hint}")
    start = r.number(f["start"], "ball.follow.start")
    stop = r.number(f["stop"], "ball.follow.stop")
    if stop < start:
        raise r.fail("ball.follow.stop", f["stop"], f"must not be before start = {start:g}")
    return Follow(joint, start, stop)


def _read_frames(r: _Reader, data: dict, hand: HandScene | None) -> tuple[float, ...]:
    if "frames" not in data:
        raise r.fail("frames", _MISSING, "missing: give [frames] times = [...] or count = N")
    fr = r.table(data["frames"], "frames", optional=("times", "count"))
    if ("times" in fr) == ("count" in fr):
        raise r.fail("frames", fr, "give exactly one of times and count")
    if hand is not None:
        lo, hi = hand.keyframes[0]["time"], hand.keyframes[-1]["time"]
    else:
        lo, hi = 0.0, 1.0
    if "count" in fr:
        n = r.integer(fr["count"], "frames.count", 1)
        return (lo,) if n == 1 else tuple(float(f"{t:.12g}") for t in np.linspace(lo, hi, n))
    times = r.times(fr["times"], "frames.times")
    if hand is not None:
        tol = 1e-9 * max(1.0, hi - lo)
        for i, t in enumerate(times):
            if not lo - tol <= t <= hi + tol:
                raise r.fail(
                    f"frames.times[{i}]", fr["times"][i],
                    f"outside the keyframes' span [{lo:g}, {hi:g}]",
                )  # fmt: skip
    return times


def _read_planes(r: _Reader, data: dict) -> tuple[PlaneScene, ...]:
    value = data.get("plane", [])
    if not isinstance(value, list):
        raise r.fail("plane", value, "must be an array of tables ([[plane]])")
    planes: list[PlaneScene] = []
    for i, p in enumerate(value):
        where = f"plane[{i}]"
        r.table(p, where, required=("name", "point", "normal"), optional=("offsets",))
        name = r.string(p["name"], f"{where}.name")
        if name in _RESERVED:
            raise r.fail(f"{where}.name", name, f"reserved for a body ({', '.join(_RESERVED)})")
        if any(q.name == name for q in planes):
            raise r.fail(f"{where}.name", name, "another plane has this name")
        point = r.vector(p["point"], f"{where}.point")
        n = np.array(r.vector(p["normal"], f"{where}.normal"))
        norm = np.linalg.norm(n)
        if not norm > 1e-12:
            raise r.fail(f"{where}.normal", p["normal"], "must be a non-zero vector")
        offsets = []
        raw = p.get("offsets", [])
        if not isinstance(raw, list):
            raise r.fail(f"{where}.offsets", raw, "must be a list of [time, dx, dy, dz]")
        for j, k in enumerate(raw):
            t, *d = r.vector(k, f"{where}.offsets[{j}]", 4)
            if offsets and not t > offsets[-1][0]:
                raise r.fail(
                    f"{where}.offsets[{j}]", k, f"times must increase (previous {offsets[-1][0]:g})"
                )
            offsets.append((t, tuple(d)))
        planes.append(PlaneScene(name, point, tuple(float(x) for x in n / norm), tuple(offsets)))
    return tuple(planes)


def _check_planes(
    r: _Reader,
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


def _read_solver(r: _Reader, data: dict) -> SolverScene:
    s = r.table(data.get("solver", {}), "solver", optional=SolverScene.__dataclass_fields__)
    d = SolverScene()
    kw: dict[str, Any] = {}
    kw["algorithm"] = r.string(s.get("algorithm", d.algorithm), "solver.algorithm", ALGORITHMS)
    kw["max_iterations"] = r.integer(
        s.get("max_iterations", d.max_iterations), "solver.max_iterations", 1
    )
    for key in ("tolerance", "gap_tolerance"):
        kw[key] = r.number(s.get(key, getattr(d, key)), f"solver.{key}", positive=True)
    kw["force_tolerance"] = r.number(
        s.get("force_tolerance", d.force_tolerance), "solver.force_tolerance", nonnegative=True
    )
    kw["relaxation"] = r.string(s.get("relaxation", d.relaxation), "solver.relaxation", RELAXATIONS)
    f = r.number(s.get("relaxation_factor", d.relaxation_factor), "solver.relaxation_factor")
    if not 0 < f <= 1:
        raise r.fail("solver.relaxation_factor", s.get("relaxation_factor"), "must lie in (0, 1]")
    kw["relaxation_factor"] = f
    kw["linear_solver"] = r.string(
        s.get("linear_solver", d.linear_solver), "solver.linear_solver", LINEAR_SOLVERS
    )
    return SolverScene(**kw)


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


def _read_output(r: _Reader, data: dict) -> OutputScene:
    o = r.table(data.get("output", {}), "output", optional=OutputScene.__dataclass_fields__)
    d = OutputScene()
    directory = (
        Path(r.string(o["directory"], "output.directory")) if "directory" in o else d.directory
    )
    why = _writable(directory.expanduser())
    if why:
        raise r.fail("output.directory", str(directory), why)
    size = o.get("window_size", list(d.window_size))
    if not isinstance(size, list) or len(size) != 2:
        raise r.fail("output.window_size", size, "must be [width, height] in pixels")
    w, h = (r.integer(v, f"output.window_size[{i}]", 1) for i, v in enumerate(size))
    return OutputScene(
        directory=directory,
        pictures=r.boolean(o.get("pictures", d.pictures), "output.pictures"),
        gif=r.boolean(o.get("gif", d.gif), "output.gif"),
        window_size=(w, h),
    )


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
    r = _Reader(source)
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
    ball, follow_data = _read_ball(r, data, base)
    read = _read_hand(r, data, base)
    hand, skeleton = read if read is not None else (None, None)
    follow = _read_follow(r, follow_data, skeleton)
    frames = _read_frames(r, data, hand)
    if hand is not None and "auto_flexion" in data["hand"]:
        auto = _read_auto_flexion(r, data["hand"]["auto_flexion"], skeleton, frames)
        hand = HandScene(**{**_fields(hand), "auto_flexion": auto})
    planes = _read_planes(r, data)
    _check_planes(r, planes, ball, frames, follow)
    solver = _read_solver(r, data)
    output = _read_output(r, data)
    return Scene(
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
    )
