"""The scene's ``[[object]]`` tables: any solid object from a mesh file, placed in the hand frame.

An object is a closed triangle surface (filled with tetrahedra at ``mesh_size``) or a
volume mesh, placed by ``rotation`` (degrees about x, then y, then z, about the mesh's own
origin) and ``center`` (where that origin goes). It is free (held by its contacts alone),
follows a joint (``follow``, as ``[ball.follow]``), or is ``fixed`` (a rigid handle held
by the world: every node prescribed). ``[ball]`` is one object among them, named
``"ball"``. The mesh itself is read and checked when the run is built
(:func:`contact.objects.mesh_object`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

import fem

from ..hand.skeleton import Skeleton
from ._checks import check_friction, invalid
from ._reader import SceneReader
from .model import RESERVED, Follow, Material
from .read_hand import read_follow

__all__ = ["OBJECT_KEYS", "ObjectScene", "read_objects", "rotation_matrix"]

#: The keys of an ``[[object]]`` table.
OBJECT_KEYS = (
    "name", "mesh", "mesh_size", "center", "rotation", "material", "kind", "friction",
    "follow", "fixed", "nodal_pressure",
)  # fmt: skip
#: An object's material where its table gives none: a soft rubber.
DEFAULT_MATERIAL = Material(1.0e6, 0.45, 1100.0)


def rotation_matrix(degrees: tuple[float, float, float]) -> NDArray[np.float64]:
    """The rotation by ``degrees`` about x, then y, then z (fixed axes): ``Rz @ Ry @ Rx``."""
    cx, cy, cz = (math.cos(math.radians(a)) for a in degrees)
    sx, sy, sz = (math.sin(math.radians(a)) for a in degrees)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]])
    ry = np.array([[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]])
    rz = np.array([[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]])
    return rz @ ry @ rx


@dataclass(frozen=True)
class ObjectScene:
    """One ``[[object]]`` table.

    Attributes
    ----------
    name : str
        The body's name in results; not ``hand``, ``ball`` or a plane's.
    mesh : Path
        A closed triangle surface or a volume mesh (absolute path).
    mesh_size : float or None
        Target tetrahedron edge (m) for a surface; None: the surface's mean edge length.
        Ignored for a volume mesh.
    center : tuple of 3 floats
        Where the mesh's origin is placed (m, hand frame).
    rotation : tuple of 3 floats
        Degrees about x, then y, then z (fixed axes), applied before ``center``.
    material : Material
    friction : float or None
        Coulomb's coefficient against a body whose table gives none; None: 0.
    fixed : bool
        A rigid object held by the world (every node prescribed); it cannot follow.
    follow : Follow or None
    nodal_pressure : bool or None
        As ``ball.nodal_pressure``.
    """

    name: str
    mesh: Path
    mesh_size: float | None = None
    center: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation: tuple[float, float, float] = (0.0, 0.0, 0.0)
    material: Material = DEFAULT_MATERIAL
    friction: float | None = None
    fixed: bool = False
    follow: Follow | None = None
    nodal_pressure: bool | None = None

    def __post_init__(self) -> None:
        check_friction("friction", self.friction)
        if self.name in RESERVED:
            raise invalid("name", self.name, f"reserved for a body ({', '.join(RESERVED)})")
        if self.fixed and self.follow is not None:
            raise invalid("fixed", True, "a fixed object cannot also follow a joint")

    @property
    def placement(self) -> NDArray[np.float64]:
        """The 4x4 rigid placement of the mesh's own coordinates in the hand frame."""
        tf = np.eye(4)
        tf[:3, :3] = rotation_matrix(self.rotation)
        tf[:3, 3] = self.center
        return tf

    @property
    def elastic(self) -> fem.LinearElastic:
        """The object's material."""
        return self.material.elastic()


def _name(r: SceneReader, o: dict, where: str, mesh: Path, taken: set[str]) -> str:
    if "name" in o:
        name = r.string(o["name"], f"{where}.name")
    else:
        name = mesh.stem
        if name in taken or name in RESERVED:
            raise r.fail(
                f"{where}.name", "missing", f"the default name {name!r} is taken: give a name"
            )
    if name in taken:
        raise r.fail(f"{where}.name", name, "already names another body")
    return name


def read_objects(
    r: SceneReader, data: dict, base: Path, skeleton: Skeleton | None, planes: tuple[str, ...]
) -> tuple[ObjectScene, ...]:
    """The ``[[object]]`` tables, in file order.

    Parameters
    ----------
    r : SceneReader
    data : dict
        The whole scene's TOML.
    base : Path
        The scene file's folder (relative mesh paths).
    skeleton : Skeleton or None
        The hand's, for ``follow``.
    planes : tuple of str
        The planes' names, which an object's may not repeat.

    Returns
    -------
    tuple of ObjectScene
    """
    value = data.get("object", [])
    if not isinstance(value, list) or not all(isinstance(o, dict) for o in value):
        raise r.fail("object", value, "must be an array of tables: [[object]]")
    taken = set(planes)
    out = []
    for i, raw in enumerate(value):
        where = f"object[{i}]"
        o = r.table(raw, where, required=("mesh",), optional=OBJECT_KEYS)
        mesh = r.file(o["mesh"], f"{where}.mesh", base)
        kw: dict[str, Any] = {}
        name = _name(r, o, where, mesh, taken)
        taken.add(name)
        if "mesh_size" in o:
            size = o["mesh_size"]
            kw["mesh_size"] = r.bounded(size, f"{where}.mesh_size", "length", positive=True)
        if "center" in o:
            kw["center"] = r.bounded_vector(o["center"], f"{where}.center", "position")
        if "rotation" in o:
            rot = r.vector(o["rotation"], f"{where}.rotation", 3)
            for k, a in enumerate(rot):
                if abs(a) > 360.0:
                    raise r.fail(f"{where}.rotation[{k}]", a, "must lie in [-360, 360] degrees")
            kw["rotation"] = rot
        if "material" in o:
            kw["material"] = r.material(o["material"], f"{where}.material", DEFAULT_MATERIAL)
        if "kind" in o:
            r.string(o["kind"], f"{where}.kind", ("solid",))
        if "friction" in o:
            kw["friction"] = r.number(o["friction"], f"{where}.friction")
        for key in ("fixed", "nodal_pressure"):
            if key in o:
                kw[key] = r.boolean(o[key], f"{where}.{key}")
        if "follow" in o:
            kw["follow"] = read_follow(r, o["follow"], skeleton, where=f"{where}.follow")
        out.append(r.build(where, ObjectScene, name, mesh, **kw))
    return tuple(out)
