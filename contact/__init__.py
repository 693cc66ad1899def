"""contact: a hand grasping a deformable ball, solved by finite elements with contact.

Built on :mod:`fem`, its subpackages follow the data: :mod:`contact.scene` reads a scene,
:mod:`contact.hand` models and poses the hand (rig, bones, metaball skin, flesh, keyframes,
JLD mapping: step 1 of a frame), :mod:`contact.geometry` answers closest-point questions
on planes and triangle surfaces, :mod:`contact.solver` resolves the contact (steps 2 to 5
of Gourret, Magnenat-Thalmann and Thalmann 1989, in contact space or as their literal
loop), :mod:`contact.output` writes the results folder, :mod:`contact.cases` holds the
verification cases. ``python -m contact.grasp SCENE.toml`` runs a scene.
"""

from __future__ import annotations

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
from .objects.ball import Ball, BallError, BallSpec, make_ball
from .output import BodyFrame, ResultsWriter, verdict
from .scene import Scene, SceneError, load_scene
from .solver import ContactSettings, solve_frame
from .solver.body import ElasticBody
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
