"""contact: the grasp of a deformable ball by a hand (geometry, contact, rig, scenes, CLI).

Built on :mod:`fem`; the modules arrive with the issues that follow the FE core. The hand
(issue 4): :func:`load_skeleton` reads a rig (``meshes/hand/rig.toml``) into a
:class:`Skeleton` with forward kinematics, :func:`skin_surface` and :func:`bone_surfaces`
build its skin (metaballs) and bones, and :func:`load_hand` reads the shipped meshes.
"""

from __future__ import annotations

from .ball import Ball, BallError, BallSpec, make_ball
from .bones import bone_surfaces
from .errors import RigError
from .hand import Hand, load_hand
from .metaballs import skin_surface
from .skeleton import Skeleton, load_skeleton
from .surfacequery import Closest, SurfaceError, TriangleSurface, surface_of_mesh

__all__ = [
    "Ball",
    "BallError",
    "BallSpec",
    "Closest",
    "Hand",
    "RigError",
    "Skeleton",
    "SurfaceError",
    "TriangleSurface",
    "bone_surfaces",
    "load_hand",
    "load_skeleton",
    "make_ball",
    "skin_surface",
    "surface_of_mesh",
]
