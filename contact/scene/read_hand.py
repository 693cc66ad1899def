"""Reading a scene's hand: ``[hand]``, its keyframes and automatic flexions, ``[ball.follow]``.

What refers to the rig (joint angles and their limits, bone names, joints to follow) is
checked against its skeleton (:func:`~contact.hand.skeleton.load_skeleton`), which is
read here; the hand meshes are not (the CLI reads them).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .._toml import MISSING, hint
from ..errors import RigError
from ..hand.autoflex import FINGERTIPS
from ..hand.keyframes import Key, Keyframes
from ..hand.shipped import RESOLUTIONS, hand_files
from ..hand.skeleton import Skeleton, load_skeleton
from ._reader import SceneReader
from .bounds import FRAME_TIME_TOL, frame_time
from .model import AutoFlex, Follow, HandScene

__all__ = ["HAND_KEYS", "read_auto_flexion", "read_follow", "read_hand", "read_keyframes"]

#: The keys of ``[hand]``.
HAND_KEYS = (
    "rig", "directory", "resolution", "flesh", "bone_force_limit", "bone_force_limits",
    "keyframe", "auto_flexion", "nodal_pressure", "friction",
)  # fmt: skip


def _rig(r: SceneReader, h: dict, base: Path, directory: Path) -> tuple[Path, Skeleton]:
    """The rig file and its skeleton; a rig given apart must match the meshes' own."""
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
    return rig, skeleton


def read_hand(r: SceneReader, data: dict, base: Path) -> tuple[HandScene, Skeleton] | None:
    """The ``[hand]`` table without its automatic flexions (they need the frames).

    Parameters
    ----------
    r : SceneReader
    data : dict
        The whole file.
    base : Path
        The scene file's folder, for relative paths.

    Returns
    -------
    (HandScene, Skeleton) or None
        None without a ``[hand]``.
    """
    if "hand" not in data:
        return None
    h = r.table(data["hand"], "hand", required=("keyframe",), optional=HAND_KEYS)
    directory = HandScene.directory
    if "directory" in h:
        given = Path(r.string(h["directory"], "hand.directory")).expanduser()
        try:
            directory = (base / given).resolve()
        except (RuntimeError, OSError):  # a symlink loop
            raise r.fail("hand.directory", h["directory"], "a symlink loop") from None
    if "directory" in h and not directory.is_dir():
        raise r.fail("hand.directory", h["directory"], f"no such folder ({directory})")
    resolution = r.string(h.get("resolution", HandScene.resolution), "hand.resolution", RESOLUTIONS)
    for kind, f in hand_files(resolution, directory).items():
        if kind != "rig" and not f.is_file():
            key = "hand.directory" if "directory" in h else "hand.resolution"
            raise r.fail(key, h.get(key.split(".")[1], resolution), f"no {f.name} in {directory}")
    rig, skeleton = _rig(r, h, base, directory)
    flesh = r.material(h.get("flesh", {}), "hand.flesh", HandScene.flesh)
    limit = None
    if "bone_force_limit" in h:
        limit = r.number(h["bone_force_limit"], "hand.bone_force_limit")
    per_bone = h.get("bone_force_limits", {})
    if not isinstance(per_bone, dict):
        raise r.fail("hand.bone_force_limits", per_bone, "must be a table {bone = N}")
    limits = {}
    for bone, v in per_bone.items():
        where = f"hand.bone_force_limits.{bone}"
        if bone not in skeleton.bones:
            close = hint(bone, skeleton.bone_names)
            raise r.fail(where, v, f"unknown bone{close} (bones: {', '.join(skeleton.bone_names)})")
        limits[bone] = r.number(v, where)
    keys = read_keyframes(r, h["keyframe"], skeleton)
    nodal = None
    if "nodal_pressure" in h:
        nodal = r.boolean(h["nodal_pressure"], "hand.nodal_pressure")
    friction = r.number(h["friction"], "hand.friction") if "friction" in h else None
    hand = r.build(
        "hand",
        HandScene,
        rig=rig,
        directory=directory,
        resolution=resolution,
        flesh=flesh,
        bone_force_limit=limit,
        bone_force_limits=limits,
        keyframes=keys,
        auto_flexion=(),
        nodal_pressure=nodal,
        friction=friction,
    )
    return hand, skeleton


def read_keyframes(r: SceneReader, value: Any, skeleton: Skeleton) -> tuple[dict, ...]:
    """The ``[[hand.keyframe]]`` tables, each angle within its limits in the rig."""
    if not isinstance(value, list) or not value:
        raise r.fail(
            "hand.keyframe", value, "must be a non-empty array of tables ([[hand.keyframe]])"
        )
    limits = skeleton.limits
    keys: list[dict] = []
    for i, k in enumerate(value):
        where = f"hand.keyframe[{i}]"
        r.table(k, where, required=("time", "angles"), optional=("tension", "continuity", "bias"))
        t = r.bounded(k["time"], f"{where}.time", "time")
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
                close = hint(name, list(limits))
                raise r.fail(path, v, f"unknown joint angle{close} (angles: {', '.join(limits)})")
            x = r.number(v, path)
            lo, hi = limits[name]
            if not lo <= x <= hi:
                raise r.fail(path, v, f"outside its limits [{lo:g}, {hi:g}]")
            out[name] = x
        key = {"time": t, "angles": out}
        for name in ("tension", "continuity", "bias"):
            x = r.number(k.get(name, getattr(Key, name)), f"{where}.{name}")
            if not -1.0 <= x <= 1.0:
                raise r.fail(f"{where}.{name}", k[name], "must lie in [-1, 1]")
            key[name] = x
        keys.append(key)
    try:
        Keyframes(skeleton, keys)
    except RigError as exc:  # pragma: no cover - the checks above come first
        raise r.fail("hand.keyframe", MISSING, str(exc)) from None
    return tuple(keys)


def read_auto_flexion(
    r: SceneReader, value: Any, skeleton: Skeleton, frames: tuple[float, ...]
) -> tuple[AutoFlex, ...]:
    """The ``[[hand.auto_flexion]]`` tables: rig angles, at frame times, one search a joint."""
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
            optional=(
                "epsilon", "press", "times", "first_contact", "force", "force_tolerance"
            ),
        )
        joint = r.string(a["joint"], f"{where}.joint")
        if joint not in skeleton.limits:
            close = hint(joint, list(skeleton.limits))
            raise r.fail(f"{where}.joint", joint, f"unknown joint angle{close}")
        p = a["point"]
        if isinstance(p, str):
            point: str | int = r.string(p, f"{where}.point")
        elif isinstance(p, int) and not isinstance(p, bool):
            point = r.integer(p, f"{where}.point")
        else:
            raise r.fail(
                f"{where}.point",
                p,
                f"must be a fingertip ({', '.join(FINGERTIPS)}) or a node index",
            )
        kw: dict[str, Any] = {}
        for key in ("epsilon", "press"):
            if key in a:
                kw[key] = r.bounded(a[key], f"{where}.{key}", "position")
        for key in ("force", "force_tolerance"):
            if key in a:
                kw[key] = r.number(a[key], f"{where}.{key}")
        times = None
        if "times" in a:
            given = r.times(a["times"], f"{where}.times")
            matched = []
            for j, t in enumerate(given):
                f = frame_time(t, frames)  # stored exactly: the run matches it exactly
                if f is None:
                    raise r.fail(
                        f"{where}.times[{j}]", a["times"][j],
                        f"not one of the frame times (within {FRAME_TIME_TOL:g} relative)",
                    )  # fmt: skip
                matched.append(f)
            times = tuple(matched)
        for prev in out:
            if prev.joint == joint and (
                prev.times is None or times is None or set(prev.times) & set(times)
            ):
                raise r.fail(
                    f"{where}.joint",
                    joint,
                    "already searched by an earlier auto_flexion at these times",
                )
        if "first_contact" in a:
            kw["first_contact"] = r.boolean(a["first_contact"], f"{where}.first_contact")
        out.append(r.build(where, AutoFlex, joint, point, times=times, **kw))
    return tuple(out)


def read_follow(
    r: SceneReader, value: Any, skeleton: Skeleton | None, where: str = "ball.follow"
) -> Follow | None:
    """``[ball.follow]`` (or an object's ``follow``): a joint of the rig, so only with a hand."""
    if value is None:
        return None
    f = r.table(value, where, required=("joint", "start", "stop"))
    joint = r.string(f["joint"], f"{where}.joint")
    if skeleton is None:
        raise r.fail(f"{where}.joint", joint, "an object can follow a joint only with a [hand]")
    if joint not in skeleton.joint_names:
        close = hint(joint, skeleton.joint_names)
        raise r.fail(f"{where}.joint", joint, f"unknown joint{close}")
    start = r.bounded(f["start"], f"{where}.start", "time")
    stop = r.bounded(f["stop"], f"{where}.stop", "time")
    return r.build(where, Follow, joint, start, stop)
