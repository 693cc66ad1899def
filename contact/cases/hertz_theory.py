"""Hertz contact of an elastic sphere on a rigid frictionless plane: the analytic solution.

The classical solution for a sphere of radius ``R`` pressed with force ``F``, with the
contact modulus ``E* = E / (1 - nu^2)`` (:func:`effective_modulus`)::

    a  = (3 F R / (4 E*))^(1/3)                  contact radius
    p0 = 3 F / (2 pi a^2) = (6 F E*^2 / (pi^3 R^2))^(1/3)   peak pressure
    p(r) = p0 sqrt(1 - r^2 / a^2)                pressure profile
    delta = a^2 / R                              approach of distant points

It is small-strain, half-space theory: an FE model reproduces it up to terms of order
``(a / R)^2`` (the sphere's true gap against the parabola ``r^2 / 2R``, its finite size).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ContactError

__all__ = ["HertzSolution", "effective_modulus", "hertz_sphere_on_plane"]


def effective_modulus(E: float, nu: float, E2: float = math.inf, nu2: float = 0.0) -> float:
    """Hertz contact modulus ``E*`` of two bodies: ``1/E* = (1-nu^2)/E + (1-nu2^2)/E2``.

    The default second body is rigid, so ``E* = E / (1 - nu^2)``.
    """
    if not E > 0 or not E2 > 0 or not -1.0 < nu < 0.5 or not -1.0 < nu2 < 0.5:
        raise ContactError(f"need E, E2 > 0 and nu, nu2 in (-1, 0.5); got {E}, {nu}, {E2}, {nu2}")
    inv = (1.0 - nu**2) / E + (0.0 if math.isinf(E2) else (1.0 - nu2**2) / E2)
    return 1.0 / inv


@dataclass(frozen=True)
class HertzSolution:
    """Hertz contact of a sphere on a plane (SI units).

    Attributes
    ----------
    force : float
        Normal force ``F`` (N).
    radius : float
        Sphere radius ``R`` (m).
    modulus : float
        Contact modulus ``E*`` (Pa).
    contact_radius : float
        ``a = (3 F R / 4 E*)^(1/3)`` (m).
    peak_pressure : float
        ``p0 = 3 F / (2 pi a^2)`` (Pa).
    mean_pressure : float
        ``F / (pi a^2) = 2 p0 / 3`` (Pa).
    approach : float
        ``delta = a^2 / R`` (m): how far distant points of sphere and plane close in.
    """

    force: float
    radius: float
    modulus: float
    contact_radius: float
    peak_pressure: float
    mean_pressure: float
    approach: float

    def pressure(self, r: ArrayLike) -> NDArray[np.float64]:
        """The pressure ``p0 sqrt(1 - r^2 / a^2)`` at distances ``r`` from the centre (0 out)."""
        x = np.asarray(r, dtype=np.float64) / self.contact_radius
        return self.peak_pressure * np.sqrt(np.clip(1.0 - x**2, 0.0, None))


def hertz_sphere_on_plane(force: float, radius: float, E: float, nu: float) -> HertzSolution:
    """Hertz solution of an elastic sphere pressed on a rigid frictionless plane.

    Parameters
    ----------
    force : float
        Normal force (N), positive.
    radius : float
        Sphere radius (m).
    E, nu : float
        The sphere's Young's modulus (Pa) and Poisson's ratio.

    Returns
    -------
    HertzSolution
    """
    if not force > 0 or not radius > 0:
        raise ContactError(f"need a positive force and radius, got {force}, {radius}")
    es = effective_modulus(E, nu)
    a = (3.0 * force * radius / (4.0 * es)) ** (1.0 / 3.0)
    p0 = 3.0 * force / (2.0 * math.pi * a**2)
    return HertzSolution(force, radius, es, a, p0, force / (math.pi * a**2), a**2 / radius)
