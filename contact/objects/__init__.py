"""Solid objects from a user's mesh file (checked, filled with tetrahedra), placed per frame."""

from __future__ import annotations

from .meshing import mesh_object, read_surface
from .placed import SceneObject, from_ball, from_scene, object_pairs
from .surface import (
    DEGENERATE_AREA,
    HAND_LENGTH,
    MAX_EXTENT,
    MIN_EXTENT,
    check_object_surface,
)

__all__ = [
    "DEGENERATE_AREA",
    "HAND_LENGTH",
    "MAX_EXTENT",
    "MIN_EXTENT",
    "SceneObject",
    "check_object_surface",
    "from_ball",
    "from_scene",
    "mesh_object",
    "object_pairs",
    "read_surface",
]
