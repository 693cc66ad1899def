"""Cattaneo-Mindlin and Mindlin-Deresiewicz: a Hertz contact loaded tangentially, analytically.

A sphere pressed on a flat by ``P`` (Hertz radius ``a``, peak pressure ``p0``), then loaded
tangentially by ``Q < mu P`` along x with Coulomb friction ``mu`` (Cattaneo 1938, Mindlin
1949; Johnson, Contact Mechanics, 1985, section 7.2)::

    c = a (1 - Q / (mu P))^(1/3)                        stick radius
    q(r) = mu p0 sqrt(1 - r^2/a^2) - (c/a) mu p0 sqrt(1 - r^2/c^2)   traction (2nd term r < c)
    delta(Q) = K (1 - (1 - Q/(mu P))^(2/3)),  K = 3 mu P (2 - nu) / (16 G a)

``delta`` is the tangential shift of the sphere's distant points against the flat (a rigid
flat: only the sphere's ``(2 - nu) / G`` counts; ``G`` its shear modulus). Unloading from
``Q*`` (Mindlin and Deresiewicz 1953) a counter-slip annulus grows from the edge and::

    delta(Q) = delta(Q*) - 2 delta((Q* - Q) / 2)

so that at ``Q = 0`` a residual shift ``K (2 (1 - Q*/(2 mu P))^(2/3) - (1 - Q*/(mu P))^(2/3)
- 1)`` is left. The solution is exact only where the normal and tangential problems
uncouple (Dundurs' ``beta = 0``); for an elastic sphere on a rigid flat ``beta =
(1 - 2 nu) / (2 (1 - nu))``, small near ``nu = 0.5``. Mindlin's traction also leaves a small
slip across x inside the stick zone for ``nu > 0``: the stick zone is circular only
approximately.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ContactError
from .hertz_theory import HertzSolution, hertz_sphere_on_plane

__all__ = ["MindlinSolution", "dundurs_beta", "mindlin_sphere_on_plane"]


def dundurs_beta(nu: float) -> float:
    """Dundurs' coupling ``beta = (1 - 2 nu) / (2 (1 - nu))`` of an elastic body on a rigid one."""
    return (1.0 - 2.0 * nu) / (2.0 * (1.0 - nu))


@dataclass(frozen=True)
class MindlinSolution:
    """A Hertz contact of a sphere on a rigid flat under a tangential load (SI units).

    Attributes
    ----------
    hertz : HertzSolution
        The normal contact (force ``P``, radius ``a``, peak pressure ``p0``).
    friction : float
        Coulomb's ``mu``.
    shear_modulus : float
        The sphere's ``G`` (Pa).
    nu : float
        The sphere's Poisson's ratio.
    compliance : float
        ``K = 3 mu P (2 - nu) / (16 G a)`` (m): the shift at full slip.
    """

    hertz: HertzSolution
    friction: float
    shear_modulus: float
    nu: float
    compliance: float

    @property
    def limit(self) -> float:
        """``mu P`` (N): the load at which the whole patch slides."""
        return self.friction * self.hertz.force

    def _ratio(self, load: float) -> float:
        x = float(load) / self.limit
        if not 0.0 <= x <= 1.0:
            raise ContactError(f"need 0 <= Q <= mu P = {self.limit:.6g}, got Q = {load!r}")
        return x

    def stick_radius(self, load: float) -> float:
        """Cattaneo-Mindlin's ``c = a (1 - Q / (mu P))^(1/3)`` (m)."""
        return self.hertz.contact_radius * (1.0 - self._ratio(load)) ** (1.0 / 3.0)

    def traction(self, r: ArrayLike, load: float) -> NDArray[np.float64]:
        """The tangential traction ``q(r)`` under the load ``Q`` on loading (Pa)."""
        a, c = self.hertz.contact_radius, self.stick_radius(load)
        x = np.asarray(r, dtype=np.float64)
        q = np.sqrt(np.clip(1.0 - (x / a) ** 2, 0.0, None))
        if c > 0:
            q = q - (c / a) * np.sqrt(np.clip(1.0 - (x / c) ** 2, 0.0, None))
        return self.friction * self.hertz.peak_pressure * q

    def traction_radius(self, load: float) -> float:
        """Second-moment radius ``sqrt(5/2 int q r^2 dA / int q dA)`` of ``q`` (m).

        ``sqrt((a^5 - c^5) / (a^3 - c^3))``: ``a`` at full slip (the pressure's own moment
        radius), rising to ``sqrt(5/3) a`` as ``Q -> 0`` (the traction moves to the edge).
        """
        a, c = self.hertz.contact_radius, self.stick_radius(load)
        k = c / a
        if k > 1.0 - 1e-9:
            return math.sqrt(5.0 / 3.0) * a
        return a * math.sqrt((1.0 - k**5) / (1.0 - k**3))

    def shift(self, load: float) -> float:
        """The shift ``delta(Q) = K (1 - (1 - Q/(mu P))^(2/3))`` on loading (m)."""
        return self.compliance * (1.0 - (1.0 - self._ratio(load)) ** (2.0 / 3.0))

    def unloading_shift(self, load: float, peak: float) -> float:
        """Mindlin-Deresiewicz: ``delta(Q*) - 2 delta((Q* - Q) / 2)`` unloading from ``Q*`` (m)."""
        if not 0.0 <= load <= peak:
            raise ContactError(f"unloading needs 0 <= Q <= Q* = {peak!r}, got {load!r}")
        return self.shift(peak) - 2.0 * self.shift(0.5 * (peak - load))

    def unloading_stick_radius(self, load: float, peak: float) -> float:
        """Radius ``a (1 - (Q* - Q) / (2 mu P))^(1/3)`` of what has stuck since the peak (m)."""
        if not 0.0 <= load <= peak:
            raise ContactError(f"unloading needs 0 <= Q <= Q* = {peak!r}, got {load!r}")
        return self.stick_radius(0.5 * (peak - load))

    def residual_shift(self, peak: float) -> float:
        """The shift left at ``Q = 0`` after loading to ``Q*`` and unloading (m)."""
        return self.unloading_shift(0.0, peak)


def mindlin_sphere_on_plane(
    force: float, friction: float, radius: float, E: float, nu: float
) -> MindlinSolution:
    """Cattaneo-Mindlin's solution for a sphere pressed by ``force`` on a rigid flat.

    Parameters
    ----------
    force : float
        Normal force ``P`` (N), positive.
    friction : float
        Coulomb's ``mu``, positive.
    radius, E, nu : float
        The sphere (m, Pa).

    Returns
    -------
    MindlinSolution
    """
    if not friction > 0:
        raise ContactError(f"need a positive friction coefficient, got {friction!r}")
    hz = hertz_sphere_on_plane(force, radius, E, nu)
    g = E / (2.0 * (1.0 + nu))
    k = 3.0 * friction * force * (2.0 - nu) / (16.0 * g * hz.contact_radius)
    return MindlinSolution(hz, float(friction), g, float(nu), k)
