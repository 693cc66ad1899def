"""contact: the grasp of a deformable ball by a hand (geometry, contact, rig, scenes, CLI).

Built on :mod:`fem`; the modules arrive with the issues that follow the FE core. The hand
(issue 4): :func:`load_skeleton` reads a rig (``meshes/hand/rig.toml``) into a
:class:`Skeleton` with forward kinematics, :func:`skin_surface` and :func:`bone_surfaces`
build its skin (metaballs) and bones, and :func:`load_hand` reads the shipped meshes.
Posing (issue 5): :class:`Keyframes` interpolate joint angles (Kochanek-Bartels),
:func:`pose_hand` (or :class:`HandPoser`) maps the flesh by the JLD operators
(:class:`JLDMap`) and gives the bone transforms, :func:`auto_flex` bends a joint until a
point touches an object, :class:`ObjectAssociation` makes an object follow a joint and
:func:`render_sequence` draws a sequence to PNG frames and a GIF.
Outputs (issue 8): :class:`ResultsWriter` writes a results folder (summary, VTU/PVD
series, pictures) of :class:`BodyFrame` bodies with each frame's :func:`verdict`.
"""

from __future__ import annotations

from .ball import Ball, BallError, BallSpec, make_ball
from .errors import PoseError, RigError
from .geometry.plane import Plane
from .geometry.surfacequery import Closest, SurfaceError, TriangleSurface, surface_of_mesh
from .hand.animation import render_sequence
from .hand.autoflex import AutoFlexResult, auto_flex
from .hand.bones import bone_surfaces
from .hand.jld import JLDMap
from .hand.keyframes import Clamp, Key, Keyframes
from .hand.metaballs import skin_surface
from .hand.objects import ObjectAssociation
from .hand.posing import HandPoser, Pose, pose_hand
from .hand.shipped import Hand, load_hand
from .hand.skeleton import Skeleton, load_skeleton
from .output.writer import BodyFrame, ResultsWriter, verdict
from .scene.read import Scene, SceneError, load_scene
from .solver.body import ElasticBody
from .solver.iteration import ContactSettings, solve_frame
from .solver.pairs import ContactPair
from .solver.results import FrameResult

__all__ = [
    "AutoFlexResult",
    "Ball",
    "BallError",
    "BallSpec",
    "BodyFrame",
    "Clamp",
    "Closest",
    "ContactPair",
    "ContactSettings",
    "ElasticBody",
    "FrameResult",
    "Hand",
    "HandPoser",
    "JLDMap",
    "Key",
    "Keyframes",
    "ObjectAssociation",
    "Plane",
    "Pose",
    "PoseError",
    "ResultsWriter",
    "RigError",
    "Scene",
    "SceneError",
    "Skeleton",
    "SurfaceError",
    "TriangleSurface",
    "auto_flex",
    "bone_surfaces",
    "load_hand",
    "load_scene",
    "load_skeleton",
    "make_ball",
    "pose_hand",
    "render_sequence",
    "skin_surface",
    "solve_frame",
    "surface_of_mesh",
    "verdict",
]
