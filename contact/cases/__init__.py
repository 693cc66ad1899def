"""Verification cases, not the product: Hertz contact, rigid-plane contact, and friction.

Friction is checked against Cattaneo-Mindlin and Mindlin-Deresiewicz.
"""

from __future__ import annotations

from .cattaneo import (
    CattaneoCheck,
    Hemisphere,
    MindlinDeresiewiczCheck,
    StickZone,
    cattaneo_check,
    measure_stick_zone,
    mindlin_deresiewicz_check,
    squeezed_hemisphere,
)
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
from .mindlin_theory import MindlinSolution, dundurs_beta, mindlin_sphere_on_plane
from .rigid import solve_rigid_contact

__all__ = [
    "HERTZ_MODELS",
    "SCENES",
    "CattaneoCheck",
    "ContactPatch",
    "Hemisphere",
    "HertzBodiesCheck",
    "HertzCheck",
    "HertzErrors",
    "HertzScene",
    "HertzSolution",
    "MindlinDeresiewiczCheck",
    "MindlinSolution",
    "StickZone",
    "cattaneo_check",
    "dundurs_beta",
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
    "measure_stick_zone",
    "mindlin_deresiewicz_check",
    "mindlin_sphere_on_plane",
    "moment_radius",
    "solve_rigid_contact",
    "squeezed_hemisphere",
]
