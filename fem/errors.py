"""Exceptions raised by the finite-element library."""

from __future__ import annotations

__all__ = [
    "FemError",
    "LoadError",
    "MaterialError",
    "MeshError",
    "NoVolumeCellsError",
    "SolverError",
]


class FemError(Exception):
    """Base class of every error raised by :mod:`fem`."""


class MeshError(FemError, ValueError):
    """A mesh is malformed: bad shapes, indices, coordinates or an inverted element."""


class NoVolumeCellsError(MeshError):
    """A mesh file holds no volume cells (a surface mesh, say).

    Attributes
    ----------
    cell_types : tuple of str
        The cell types the file holds.
    """

    def __init__(self, message: str, cell_types: tuple[str, ...] = ()) -> None:
        super().__init__(message)
        self.cell_types = cell_types

    @property
    def surface(self) -> bool:
        """Whether the file holds surface cells (triangles, quads or polygons)."""
        return any(t in ("triangle", "quad", "polygon") for t in self.cell_types)


class MaterialError(FemError, ValueError):
    """A material is invalid or missing for a region."""


class LoadError(FemError, ValueError):
    """A load is malformed, or not in balance on a free body."""


class SolverError(FemError, RuntimeError):
    """A linear solve failed: singular system, unknown backend or bad constraints."""
