"""Isotropic linear elastic materials and small pure functions of elasticity."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .errors import MaterialError
from .mesh import Mesh

__all__ = [
    "LinearElastic",
    "elasticity_matrix",
    "lame",
    "lame_fields",
    "materials_by_region",
]


def lame(E: float, nu: float) -> tuple[float, float]:
    """Lame parameters ``(lambda, mu)`` from Young's modulus and Poisson's ratio."""
    return E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), E / (2.0 * (1.0 + nu))


def elasticity_matrix(E: float, nu: float) -> NDArray[np.float64]:
    """The 6x6 isotropic elasticity matrix in Voigt order xx, yy, zz, yz, xz, xy.

    Shear strains are engineering strains (``gamma = 2 * eps``).
    """
    lam, mu = lame(E, nu)
    d = np.zeros((6, 6))
    d[:3, :3] = lam
    d[np.arange(3), np.arange(3)] += 2 * mu
    d[np.arange(3, 6), np.arange(3, 6)] = mu
    return d


@dataclass(frozen=True)
class LinearElastic:
    """An isotropic linear elastic material.

    Parameters
    ----------
    E : float
        Young's modulus (Pa), positive.
    nu : float
        Poisson's ratio, in (-1, 0.5).
    density : float
        Mass density (kg/m^3), non-negative; used by gravity loads.
    """

    E: float
    nu: float
    density: float = 0.0

    def __post_init__(self) -> None:
        for name in ("E", "nu", "density"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)):
                raise MaterialError(f"{name} = {value!r}: must be a number")
            if not math.isfinite(float(value)):
                raise MaterialError(f"{name} = {value!r}: must be finite")
        if self.E <= 0:
            raise MaterialError(f"E = {self.E!r}: must be positive")
        if not -1.0 < self.nu < 0.5:
            raise MaterialError(f"nu = {self.nu!r}: must be above -1 and below 0.5")
        if self.density < 0:
            raise MaterialError(f"density = {self.density!r}: must be non-negative")

    @property
    def lame(self) -> tuple[float, float]:
        """Lame parameters ``(lambda, mu)``."""
        return lame(self.E, self.nu)

    @property
    def bulk_modulus(self) -> float:
        """Bulk modulus ``K = E / (3 (1 - 2 nu))``."""
        return self.E / (3.0 * (1.0 - 2.0 * self.nu))


def materials_by_region(
    materials: LinearElastic | Mapping[int, LinearElastic | Mapping[str, float]],
    region_ids: NDArray[np.int64],
) -> dict[int, LinearElastic]:
    """Resolve one material or a region mapping against the regions a mesh uses.

    Mapping values are :class:`LinearElastic` or mappings of its fields
    (``{"E": 1e6, "nu": 0.45}``), validated with the region named in any error.

    Raises
    ------
    MaterialError
        If a region used by the mesh has no material, or an entry is not a material.
    """
    if isinstance(materials, LinearElastic):
        return {int(r): materials for r in region_ids}
    if not isinstance(materials, Mapping):
        raise MaterialError(
            f"materials must be a LinearElastic or a mapping region -> LinearElastic, "
            f"got {type(materials).__name__}"
        )
    out = {}
    for r in region_ids:
        r = int(r)
        if r not in materials:
            raise MaterialError(
                f"region {r} has no material (materials given for regions "
                f"{sorted(int(k) for k in materials)})"
            )
        m = materials[r]
        if isinstance(m, Mapping):
            try:
                m = LinearElastic(**m)
            except MaterialError as exc:
                raise MaterialError(f"region {r}: {exc}") from None
            except TypeError as exc:
                raise MaterialError(f"region {r}: {exc}") from None
        if not isinstance(m, LinearElastic):
            raise MaterialError(f"region {r}: expected a LinearElastic, got {type(m).__name__}")
        out[r] = m
    return out


def lame_fields(
    mesh: Mesh, materials: LinearElastic | Mapping[int, LinearElastic]
) -> dict[str, tuple[NDArray[np.float64], NDArray[np.float64]]]:
    """Per-cell Lame parameters ``(lam, mu)`` for every cell block."""
    mats = materials_by_region(materials, mesh.region_ids)
    ids = np.array(sorted(mats))
    lam_t = np.array([mats[int(r)].lame[0] for r in ids])
    mu_t = np.array([mats[int(r)].lame[1] for r in ids])
    out = {}
    for kind, reg in mesh.regions.items():
        pos = np.searchsorted(ids, reg)
        out[kind] = (lam_t[pos], mu_t[pos])
    return out
