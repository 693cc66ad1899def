"""Scenes: the dataclasses of a grasp scene and the strict TOML reader."""

from __future__ import annotations

from .read import (
    LINEAR_SOLVERS,
    AutoFlex,
    Follow,
    HandScene,
    Material,
    OutputScene,
    PlaneScene,
    Scene,
    SceneError,
    SolverScene,
    load_scene,
)

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
