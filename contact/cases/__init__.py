"""Verification cases, not the product: Hertz contact, rigid-plane contact, and friction.

Friction is checked against Cattaneo-Mindlin and Mindlin-Deresiewicz; a block and a long
cylinder between plates against uniaxial compression and the Hertz line contact.
"""

from __future__ import annotations

from .block import BLOCK_HOLDS, BLOCK_MESHES, BlockCheck, block_check, block_mesh
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
from .line_contact import (
    LineContactCheck,
    LineContactSolution,
    cylinder_between_plates,
    line_contact_check,
    quarter_cylinder_mesh,
)
from .mindlin_theory import MindlinSolution, dundurs_beta, mindlin_sphere_on_plane
from .rigid import solve_rigid_contact

__all__ = [
    "BLOCK_HOLDS",
    "BLOCK_MESHES",
    "HERTZ_MODELS",
    "SCENES",
    "BlockCheck",
    "CattaneoCheck",
    "ContactPatch",
    "Hemisphere",
    "HertzBodiesCheck",
    "HertzCheck",
    "HertzErrors",
    "HertzScene",
    "HertzSolution",
    "LineContactCheck",
    "LineContactSolution",
    "MindlinDeresiewiczCheck",
    "MindlinSolution",
    "StickZone",
    "block_check",
    "block_mesh",
    "cattaneo_check",
    "cylinder_between_plates",
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
    "line_contact_check",
    "measure_contact_patch",
    "measure_stick_zone",
    "mindlin_deresiewicz_check",
    "mindlin_sphere_on_plane",
    "moment_radius",
    "quarter_cylinder_mesh",
    "solve_rigid_contact",
    "squeezed_hemisphere",
]
