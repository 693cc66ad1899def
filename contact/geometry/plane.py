"""Stateless contact geometry: rigid planes, batched over points.

Geometry objects know shapes and distances only; the active set and the iteration state
live in the result objects of the algorithm (see :mod:`contact.cases.rigid`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ContactError

__all__ = ["Plane", "tributary_areas"]


def _vec3(value: ArrayLike, what: str) -> NDArray[np.float64]:
    v = np.asarray(value, dtype=np.float64)
    if v.shape != (3,) or not np.isfinite(v).all():
        raise ContactError(f"{what} must be 3 finite numbers, got {np.asarray(value).tolist()}")
    return v


@dataclass(frozen=True, eq=False)
class Plane:
    """A rigid plane; bodies must stay on the side its normal points to.

    Parameters
    ----------
    point : array_like, shape (3,)
        A point of the plane (m).
    normal : array_like, shape (3,)
        Its normal, towards the free side; normalised here.
    motion : array_like, shape (3,)
        A rigid translation applied to the plane for the current frame (m): a plate that
        presses moves, a table does not.
    name : str
        For messages and results.
    force : float, optional
        A force-driven plane: it moves along its normal, from ``motion``, until the
        bodies push it back with this force (N, > 0). None: it stays at ``motion``.
    """

    point: NDArray[np.float64]
    normal: NDArray[np.float64]
    motion: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    name: str = "plane"
    force: float | None = None

    def __post_init__(self) -> None:
        n = _vec3(self.normal, f"{self.name}: normal")
        length = float(np.linalg.norm(n))
        if length == 0.0:
            raise ContactError(f"{self.name}: normal must not be zero")
        object.__setattr__(self, "normal", n / length)
        object.__setattr__(self, "point", _vec3(self.point, f"{self.name}: point"))
        object.__setattr__(self, "motion", _vec3(self.motion, f"{self.name}: motion"))
        f = self.force
        if f is not None and not (isinstance(f, (int, float)) and np.isfinite(f) and f > 0):
            raise ContactError(f"{self.name}: force must be a finite number > 0, got {f!r}")

    def moved(self, motion: ArrayLike) -> Plane:
        """The same plane with another rigid translation."""
        return Plane(self.point, self.normal, np.asarray(motion, float), self.name, self.force)

    def signed_distance(self, x: ArrayLike) -> NDArray[np.float64]:
        """Distance of points ``(n, 3)`` from the moved plane, negative behind it."""
        return (np.asarray(x, dtype=np.float64) - self.point - self.motion) @ self.normal

    def project(self, x: ArrayLike) -> NDArray[np.float64]:
        """Closest points on the moved plane, ``(n, 3)``."""
        x = np.asarray(x, dtype=np.float64)
        return x - self.signed_distance(x)[:, None] * self.normal


def tributary_areas(points: NDArray[np.float64], faces: dict[str, NDArray]) -> NDArray:
    """Area lumped to each node from the faces around it (1/3 of a triangle, 1/4 of a quad).

    Returns an ``(n_points,)`` array, zero for nodes on no face.
    """
    out = np.zeros(len(points))
    for f in faces.values():
        if len(f) == 0:
            continue
        x = points[f]
        if f.shape[1] == 3:
            area = 0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), axis=1)
        else:
            area = 0.5 * np.linalg.norm(np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 1]), axis=1)
        k = f.shape[1]
        out += np.bincount(f.ravel(), np.repeat(area / k, k), minlength=len(points))
    return out
