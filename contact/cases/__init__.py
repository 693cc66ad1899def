"""Verification cases, not the product: Hertz contact and rigid-plane contact."""

from __future__ import annotations

from .contact_patch import (
    ContactPatch,
    HertzErrors,
    interpolation_excess,
    measure_contact_patch,
    moment_radius,
)
from .hertz import HERTZ_MODELS, HertzCheck, hertz_check
from .hertz_bodies import (
    SCENES,
    HertzBodiesCheck,
    HertzScene,
    graded_box_mesh,
    hemisphere_mesh,
    hertz_bodies_check,
    hertz_scene,
    hertz_two_bodies,
)
from .hertz_theory import HertzSolution, effective_modulus, hertz_sphere_on_plane
from .rigid import solve_rigid_contact

__all__ = [
    "HERTZ_MODELS",
    "SCENES",
    "ContactPatch",
    "HertzBodiesCheck",
    "HertzCheck",
    "HertzErrors",
    "HertzScene",
    "HertzSolution",
    "effective_modulus",
    "graded_box_mesh",
    "hemisphere_mesh",
    "hertz_bodies_check",
    "hertz_check",
    "hertz_scene",
    "hertz_sphere_on_plane",
    "hertz_two_bodies",
    "interpolation_excess",
    "measure_contact_patch",
    "moment_radius",
    "solve_rigid_contact",
]
