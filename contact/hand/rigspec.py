"""Reading a hand rig file (TOML) into validated, immutable data.

The file format is documented at the top of ``meshes/hand/rig.toml``. Reading is strict:
an unknown key, a wrong type, a non-positive radius or weight, bad limits, an axis along
its bone, or a reference to an unknown joint or group raises :class:`RigError` with one
line naming the file and the key path, e.g. ``rig.toml: joints.index_pip.flexion = [90.0,
0.0]: the lower limit must not exceed the upper``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._toml import MISSING, TomlReader, short, tomllib
from ..errors import RigError

__all__ = [
    "JLD_DEFAULTS",
    "ROOT",
    "BoneSpec",
    "JLDParams",
    "JointSpec",
    "Primitive",
    "RigSpec",
    "read_rig",
]

#: Name of the fixed frame (the forearm) that the first joint and root bones hang on.
ROOT = "root"
_MAX_COS = 0.8  # an axis must be at least ~37 degrees away from its bone


@dataclass(frozen=True)
class JointSpec:
    """A joint at rest: where it is, its axes in the rest frame and its limits (degrees)."""

    name: str
    parent: str
    position: NDArray[np.float64]
    flexion_axis: NDArray[np.float64]
    flexion_limits: tuple[float, float]
    pivot_axis: NDArray[np.float64] | None
    pivot_limits: tuple[float, float] | None
    frame: NDArray[np.float64]
    """Rest frame, columns x, y, z: y along the joint's bone, z dorsal (``y x flexion``)."""


@dataclass(frozen=True)
class BoneSpec:
    """A bone: the joint that carries it, its axis at rest and its shape (metres)."""

    name: str
    joint: str
    part: str
    start: NDArray[np.float64]
    end: NDArray[np.float64]
    frame: NDArray[np.float64]
    """Columns x, y, z; y from ``start`` to ``end``, z dorsal."""
    base: NDArray[np.float64]
    shaft: NDArray[np.float64]
    head: NDArray[np.float64]

    @property
    def length(self) -> float:
        """Distance from ``start`` to ``end`` (m)."""
        return float(np.linalg.norm(self.end - self.start))


@dataclass(frozen=True)
class Primitive:
    """An ellipsoidal metaball in its joint's frame: centre, radii, axes and weight."""

    joint: str
    group: str
    center: NDArray[np.float64]
    radii: NDArray[np.float64]
    rotation: NDArray[np.float64]
    """3x3 rotation from the ellipsoid's axes to the joint frame."""
    weight: float


@dataclass(frozen=True)
class JLDParams:
    """The animator's parameters of the JLD skin mapping at one joint.

    Magnenat-Thalmann, Laperriere and Thalmann 1988, section 3. Proximities are fractions
    of a segment's length; amplitudes are relative to the flesh thickness beyond the bone.
    See ``meshes/hand/rig.toml`` (section ``[jld]``).
    """

    proximal: float = 0.35
    """Proximal area of the joint's child segment (fraction of its length, Fig. 6)."""
    distal: float = 0.35
    """Distal area of the joint's parent segment (fraction of its length)."""
    rounding: float = 0.12
    """Joint inflation: dorsal rounding amplitude at full flexion (section 6.1)."""
    muscle: float = 0.10
    """Palmar muscle inflation amplitude at full flexion (section 6.2)."""
    muscle_peak: float = 0.5
    """Join point of the two exponential functions: ratio of the largest inflation."""
    muscle_power: float = 2.0
    """Exponent ``b`` of the exponential functions (sharper peak when larger)."""

    def replace(self, **kw: float) -> JLDParams:
        """A copy with some fields changed."""
        return replace(self, **kw)


#: Defaults of every JLD parameter; a rig file without a ``[jld]`` section gets these.
JLD_DEFAULTS = JLDParams()


@dataclass(frozen=True)
class RigSpec:
    """Everything a rig file says, validated."""

    name: str
    source: str
    joints: dict[str, JointSpec]
    bones: dict[str, BoneSpec]
    primitives: tuple[Primitive, ...]
    groups: tuple[str, ...]
    base_group: str
    reach: float
    gap: float
    min_flesh: float
    jld: dict[str, JLDParams] | None = None
    """JLD parameters by joint name (every joint; defaults where the file is silent)."""
    palm_proximity: float = 0.25
    """Two-segment palm covering: area along each metacarpal, fraction of the virtual
    segment (section 5.2)."""
    palm_bulge: float = 0.5
    """Palm thickness grows as ``F ** palm_bulge`` midway between two metacarpals whose
    virtual segment shrank by the scale factor ``F`` (section 4)."""

    def jld_params(self, joint: str) -> JLDParams:
        """The JLD parameters of one joint (the defaults if the rig gives none)."""
        return (self.jld or {}).get(joint, JLD_DEFAULTS)


class _Reader(TomlReader):
    """The rig's reader: :class:`RigError`, no key hints, full ``repr`` of a scalar."""

    error = RigError
    hints = False
    missing = "missing"

    def show(self, value: Any) -> str:
        """A scalar in full, a table or list cut short."""
        return repr(value) if not isinstance(value, (dict, list)) else short(value)

    def array(self, value: Any, path: str, n: int = 3, positive: bool = False) -> NDArray:
        """A list of ``n`` numbers as an array."""
        return np.array(self.vector(value, path, n, positive=positive))

    def limits(self, value: Any, path: str) -> tuple[float, float]:
        """Joint limits (degrees): ordered, within [-180, 180], around the rest angle 0."""
        lo, hi = self.vector(value, path, 2)
        if lo > hi:
            raise self.fail(path, value, "the lower limit must not exceed the upper")
        if lo < -180.0 or hi > 180.0:
            raise self.fail(path, value, "limits must lie within [-180, 180] degrees")
        if lo > 0.0 or hi < 0.0:
            raise self.fail(path, value, "the rest angle 0 must lie within the limits")
        return float(lo), float(hi)

    def axis(self, value: Any, path: str) -> NDArray:
        """A non-zero vector, normalised."""
        v = self.array(value, path)
        norm = np.linalg.norm(v)
        if norm < 1e-9:
            raise self.fail(path, value, "must be a non-zero vector")
        return v / norm


def _frame(axis_y: NDArray, toward_z: NDArray) -> NDArray:
    """Orthonormal columns x, y, z with y along ``axis_y`` and z nearest ``toward_z``."""
    y = axis_y / np.linalg.norm(axis_y)
    z = toward_z - (toward_z @ y) * y
    z /= np.linalg.norm(z)
    return np.column_stack([np.cross(y, z), y, z])


def _rotation(degrees: NDArray) -> NDArray:
    """Rotation matrix of intrinsic x, then y, then z rotations (degrees)."""
    ax, ay, az = np.radians(degrees)
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rx @ ry @ rz


def read_rig(path: str | os.PathLike) -> RigSpec:
    """Read and validate a rig file.

    Parameters
    ----------
    path : str or path-like
        A TOML rig file (see ``meshes/hand/rig.toml`` for the format).

    Returns
    -------
    RigSpec

    Raises
    ------
    RigError
        One line naming the file and the key path of the first problem found.
    """
    path = Path(path)
    src = path.name
    if not path.is_file():
        raise RigError(f"rig file {path} does not exist")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise RigError(f"{src}: not valid TOML: {exc}") from None
    r = _Reader(src)
    r.table(data, "", {"rig", "flesh", "skin", "joints", "bones"}, {"jld"})
    r.table(data["rig"], "rig", {"name", "length_unit", "angle_unit"}, set())
    name = r.string(data["rig"]["name"], "rig.name")
    r.string(data["rig"]["length_unit"], "rig.length_unit", ("m",))
    r.string(data["rig"]["angle_unit"], "rig.angle_unit", ("deg",))
    r.table(data["flesh"], "flesh", {"gap", "min_thickness"}, set())
    gap = r.number(data["flesh"]["gap"], "flesh.gap", positive=True)
    min_flesh = r.number(data["flesh"]["min_thickness"], "flesh.min_thickness", positive=True)
    skin = data["skin"]
    r.table(skin, "skin", {"reach", "groups", "base_group", "primitives"}, set())
    reach = r.number(skin["reach"], "skin.reach")
    if not reach > 1.0:
        raise r.fail("skin.reach", skin["reach"], "must exceed 1 (field reach over radius)")
    groups = skin["groups"]
    if not isinstance(groups, list) or not groups or len(set(map(str, groups))) != len(groups):
        raise r.fail("skin.groups", groups, "must be a non-empty list of distinct names")
    groups = tuple(r.string(g, f"skin.groups[{i}]") for i, g in enumerate(groups))
    base_group = r.string(skin["base_group"], "skin.base_group", groups)

    joints, bones = _read_skeleton(r, data["joints"], data["bones"], groups)
    prims = skin["primitives"]
    if not isinstance(prims, list) or not prims:
        raise r.fail("skin.primitives", prims, "must be a non-empty list of tables")
    primitives = tuple(
        _read_primitive(r, p, f"skin.primitives[{i}]", joints, groups) for i, p in enumerate(prims)
    )
    jld, palm_proximity, palm_bulge = _read_jld(r, data.get("jld", {}), joints)
    return RigSpec(
        name,
        src,
        joints,
        bones,
        primitives,
        groups,
        base_group,
        reach,
        gap,
        min_flesh,
        jld,
        palm_proximity,
        palm_bulge,
    )


_JLD_KEYS = {
    "proximal": (0.05, 0.5),
    "distal": (0.05, 0.5),
    "rounding": (0.0, 0.5),
    "muscle": (0.0, 0.5),
    "muscle_peak": (0.05, 0.95),
    "muscle_power": (0.5, 8.0),
}


def _jld_values(r: _Reader, table: Any, path: str, base: JLDParams) -> JLDParams:
    r.table(table, path, set(), set(_JLD_KEYS))
    values = {}
    for key, (lo, hi) in _JLD_KEYS.items():
        if key in table:
            v = r.number(table[key], f"{path}.{key}")
            if not lo <= v <= hi:
                raise r.fail(f"{path}.{key}", table[key], f"must lie in [{lo:g}, {hi:g}]")
            values[key] = v
    return base.replace(**values)


def _read_jld(
    r: _Reader, data: Any, joints: dict[str, JointSpec]
) -> tuple[dict[str, JLDParams], float, float]:
    """The optional ``[jld]`` section: defaults, per-joint overrides and the palm keys."""
    top = set(_JLD_KEYS) | {"palm_proximity", "palm_bulge", "joints"}
    r.table(data, "jld", set(), top)
    defaults = _jld_values(r, {k: v for k, v in data.items() if k in _JLD_KEYS}, "jld", JLDParams())
    palm_proximity = 0.25
    if "palm_proximity" in data:
        palm_proximity = r.number(data["palm_proximity"], "jld.palm_proximity")
        if not 0.0 <= palm_proximity < 0.5:
            raise r.fail("jld.palm_proximity", data["palm_proximity"], "must lie in [0, 0.5)")
    palm_bulge = 0.5
    if "palm_bulge" in data:
        palm_bulge = r.number(data["palm_bulge"], "jld.palm_bulge")
        if not 0.0 <= palm_bulge <= 2.0:
            raise r.fail("jld.palm_bulge", data["palm_bulge"], "must lie in [0, 2]")
    per_joint = data.get("joints", {})
    if not isinstance(per_joint, dict):
        raise r.fail("jld.joints", per_joint, "must be a table of joints")
    out = {}
    for name in per_joint:
        if name not in joints:
            raise r.fail(f"jld.joints.{name}", name, "unknown joint")
    for name in joints:
        out[name] = _jld_values(r, per_joint.get(name, {}), f"jld.joints.{name}", defaults)
    return out, palm_proximity, palm_bulge


def _read_primitive(r: _Reader, p: Any, path: str, joints: dict, groups: tuple) -> Primitive:
    r.table(p, path, {"joint", "group", "center", "radii", "weight"}, {"rotation"})
    joint = r.string(p["joint"], f"{path}.joint")
    if joint != ROOT and joint not in joints:
        raise r.fail(f"{path}.joint", joint, "unknown joint")
    group = r.string(p["group"], f"{path}.group", groups)
    rot = _rotation(r.array(p.get("rotation", [0, 0, 0]), f"{path}.rotation"))
    return Primitive(
        joint=joint,
        group=group,
        center=r.array(p["center"], f"{path}.center"),
        radii=r.array(p["radii"], f"{path}.radii", positive=True),
        rotation=rot,
        weight=r.number(p["weight"], f"{path}.weight", positive=True),
    )


def _read_skeleton(
    r: _Reader, jdata: Any, bdata: Any, groups: tuple[str, ...]
) -> tuple[dict[str, JointSpec], dict[str, BoneSpec]]:
    if not isinstance(jdata, dict) or not jdata:
        raise r.fail("joints", jdata, "must be a non-empty table of joints")
    if not isinstance(bdata, dict) or not bdata:
        raise r.fail("bones", bdata, "must be a non-empty table of bones")
    raw: dict[str, dict] = {}
    for jn, j in jdata.items():
        p = f"joints.{jn}"
        r.table(j, p, {"parent", "position", "flexion_axis", "flexion"}, {"pivot_axis", "pivot"})
        if ("pivot_axis" in j) != ("pivot" in j):
            raise r.fail(p, MISSING, "give both pivot_axis and pivot, or neither")
        parent = r.string(j["parent"], f"{p}.parent")
        if parent != ROOT and parent not in jdata:
            raise r.fail(f"{p}.parent", parent, "unknown joint")
        raw[jn] = {
            "parent": parent,
            "position": r.array(j["position"], f"{p}.position"),
            "flexion_axis": r.axis(j["flexion_axis"], f"{p}.flexion_axis"),
            "flexion": r.limits(j["flexion"], f"{p}.flexion"),
            "pivot_axis": r.axis(j["pivot_axis"], f"{p}.pivot_axis") if "pivot" in j else None,
            "pivot": r.limits(j["pivot"], f"{p}.pivot") if "pivot" in j else None,
        }
    for jn in raw:  # no cycles
        seen, k = {jn}, raw[jn]["parent"]
        while k != ROOT:
            if k in seen:
                raise r.fail(f"joints.{jn}.parent", raw[jn]["parent"], "joints form a cycle")
            seen.add(k)
            k = raw[k]["parent"]

    braw: dict[str, dict] = {}
    for bn, b in bdata.items():
        p = f"bones.{bn}"
        r.table(b, p, {"joint", "part", "end", "base", "shaft", "head"}, {"start"})
        joint = r.string(b["joint"], f"{p}.joint")
        if joint != ROOT and joint not in raw:
            raise r.fail(f"{p}.joint", joint, "unknown joint")
        if joint == ROOT and "start" not in b:
            raise r.fail(f"{p}.start", MISSING, "missing (a bone on the root needs a start)")
        start = r.array(b["start"], f"{p}.start") if "start" in b else raw[joint]["position"]
        end = b["end"]
        if isinstance(end, str):
            if end not in raw:
                raise r.fail(f"{p}.end", end, "unknown joint")
            if raw[end]["parent"] != joint:
                raise r.fail(f"{p}.end", end, f"that joint's parent is not {joint!r}")
            end = raw[end]["position"]
        else:
            end = r.array(end, f"{p}.end")
        if np.linalg.norm(end - start) < 1e-3:
            raise r.fail(f"{p}.end", b["end"], "the bone is shorter than 1 mm")
        braw[bn] = {
            "joint": joint,
            "part": r.string(b["part"], f"{p}.part", groups),
            "start": start,
            "end": end,
            "base": r.array(b["base"], f"{p}.base", 3, positive=True),
            "shaft": r.array(b["shaft"], f"{p}.shaft", 2, positive=True),
            "head": r.array(b["head"], f"{p}.head", 3, positive=True),
        }
    joints: dict[str, JointSpec] = {}
    for jn, j in raw.items():
        carried = [bn for bn, b in braw.items() if b["joint"] == jn]
        if len(carried) != 1:
            raise RigError(
                f"{r.source}: joints.{jn}: must carry exactly one bone (bones with joint = "
                f"{jn!r}: {', '.join(carried) or 'none'})"
            )
        axis_y = braw[carried[0]]["end"] - j["position"]
        if np.linalg.norm(axis_y) < 1e-3:
            raise r.fail(
                f"bones.{carried[0]}.end",
                bdata[carried[0]]["end"],
                "must lie at least 1 mm from its joint",
            )
        axis_y = axis_y / np.linalg.norm(axis_y)
        for key in ("flexion_axis", "pivot_axis"):
            if j[key] is not None and abs(j[key] @ axis_y) > _MAX_COS:
                raise r.fail(
                    f"joints.{jn}.{key}",
                    jdata[jn][key],
                    f"lies too close to the bone axis of {carried[0]}",
                )
        if j["pivot_axis"] is not None and abs(j["pivot_axis"] @ j["flexion_axis"]) > _MAX_COS:
            raise r.fail(
                f"joints.{jn}.pivot_axis",
                jdata[jn]["pivot_axis"],
                "lies too close to the flexion axis",
            )
        frame = _frame(axis_y, np.cross(axis_y, j["flexion_axis"]))
        joints[jn] = JointSpec(
            jn,
            j["parent"],
            j["position"],
            j["flexion_axis"],
            j["flexion"],
            j["pivot_axis"],
            j["pivot"],
            frame,
        )
    bones: dict[str, BoneSpec] = {}
    for bn, b in braw.items():
        z_hint = joints[b["joint"]].frame[:, 2] if b["joint"] != ROOT else np.array([0, 0, 1.0])
        axis = b["end"] - b["start"]
        if abs(z_hint @ axis) > _MAX_COS * np.linalg.norm(axis):
            raise r.fail(f"bones.{bn}.end", bdata[bn]["end"], "the bone runs along z")
        bones[bn] = BoneSpec(
            bn,
            b["joint"],
            b["part"],
            b["start"],
            b["end"],
            _frame(axis, z_hint),
            b["base"],
            b["shaft"],
            b["head"],
        )
    return joints, bones
