"""Exceptions raised by the finite-element library."""

from __future__ import annotations

__all__ = ["FemError", "LoadError", "MaterialError", "MeshError", "SolverError"]


class FemError(Exception):
    """Base class of every error raised by :mod:`fem`."""


class MeshError(FemError, ValueError):
    """A mesh is malformed: bad shapes, indices, coordinates or an inverted element."""


class MaterialError(FemError, ValueError):
    """A material is invalid or missing for a region."""


class LoadError(FemError, ValueError):
    """A load is malformed, or not in balance on a free body."""


class SolverError(FemError, RuntimeError):
    """A linear solve failed: singular system, unknown backend or bad constraints."""
