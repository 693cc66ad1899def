"""Scenes: the dataclasses of a grasp scene and the strict TOML reader."""

from __future__ import annotations

from ..errors import SceneError
from .bounds import BOUNDS, FRAME_TIME_TOL
from .model import (
    CONTACT_KEYS,
    LINEAR_SOLVERS,
    WINDOW_SIZE,
    AutoFlex,
    Follow,
    HandScene,
    Material,
    OutputScene,
    PlaneScene,
    SolverScene,
)
from .objects import ObjectScene
from .read import load_scene
from .sizing import SceneSize
from .spec import Scene

__all__ = [
    "BOUNDS",
    "CONTACT_KEYS",
    "FRAME_TIME_TOL",
    "LINEAR_SOLVERS",
    "WINDOW_SIZE",
    "AutoFlex",
    "Follow",
    "HandScene",
    "Material",
    "ObjectScene",
    "OutputScene",
    "PlaneScene",
    "Scene",
    "SceneError",
    "SceneSize",
    "SolverScene",
    "load_scene",
]
