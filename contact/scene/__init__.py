"""Scenes: the dataclasses of a grasp scene and the strict TOML reader."""

from __future__ import annotations

from ..errors import SceneError
from .model import (
    CONTACT_KEYS,
    LINEAR_SOLVERS,
    AutoFlex,
    Follow,
    HandScene,
    Material,
    OutputScene,
    PlaneScene,
    SolverScene,
)
from .read import load_scene
from .spec import Scene

__all__ = [
    "CONTACT_KEYS",
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
