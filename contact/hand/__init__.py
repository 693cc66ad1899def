"""The hand model: rig, skeleton, bones, metaball skin, flesh mesh, keyframes, posing (step 1).

Its modules, by what they do:

- **Rig and motion**: the rig file (:mod:`.rigspec`), the skeleton's joints and forward
  kinematics (:mod:`.skeleton`), keyframed angles (:mod:`.keyframes`), automatic flexion
  to a touch (:mod:`.autoflex`), objects that follow a joint (:mod:`.objects`), which part
  a node belongs to (:mod:`.fingers`).
- **The built meshes**: the metaball skin (:mod:`.metaballs`), the bone surfaces
  (:mod:`.bones`), the flesh tetrahedra (:mod:`.flesh`, :mod:`.jointgap`), their checks
  and quality (:mod:`.checks`, :mod:`.quality`), building them (:mod:`.build`) and the hand
  as shipped (:mod:`.shipped`).
- **Posing by JLD**: :mod:`.posing` places bones and flesh; the mapping is :mod:`.jld`,
  with :mod:`.jldframes`, :mod:`.jldlocalise` and :mod:`.jldpalm`.
- **The flesh relaxer** after the mapping: :mod:`.relax` drives it, on :mod:`.relaxmesh`'s
  patches, by :mod:`.relaxnewton`'s steps with :mod:`.blockcg`'s solver, compiled kernels
  (:mod:`.relaxkernels`, :mod:`.tetkernels`, checked against :mod:`.relax_reference`) and
  :mod:`.restarts` of inverted folds.
- **Pictures**: :mod:`.plot` and :mod:`.animation`.
"""

from __future__ import annotations

from .animation import render_sequence, write_gif
from .autoflex import (
    FINGERTIPS,
    AutoFlexResult,
    auto_flex,
    expected_halvings,
    fingertip_node,
    mesh_distance,
    plane_distance,
    sphere_distance,
    surface_distance,
)
from .blockcg import block_cg, block_pattern
from .bones import bone_profile, bone_surfaces, joint_clearance, sweep_bone
from .build import COARSE, FINE, Resolution, build_hand, hand_report, write_hand
from .checks import bone_gaps, check_hand_geometry, finger_widths, flesh_thickness
from .fingers import cell_parts, fingertips, node_parts, part_letters
from .flesh import (
    cell_bones,
    joint_pairs,
    label_bone_nodes,
    merged_surface,
    open_joints,
    tetrahedralize_flesh,
)
from .jld import JLDMap
from .jldframes import SkeletonTopology, muscle_profile, smoothstep
from .jointgap import bridging_nodes, gap_edges, split_joint_gaps
from .keyframes import Clamp, Key, Keyframes, kb_tangents, kochanek_bartels
from .metaballs import field_on_grid, field_threshold, posed_primitives, skin_surface
from .objects import ObjectAssociation, transform_points
from .plot import render_hand
from .posing import HandPoser, Pose, pose_hand
from .quality import (
    quality_summary,
    tet_aspect_ratios,
    tet_dihedral_angles,
    tet_quality,
    tet_volumes,
)
from .relax import RELAX_QUALITY, RELAX_STOP, FleshRelaxer
from .relaxkernels import patch_energy, step_terms, untangle_terms, volumes_quality
from .relaxmesh import RelaxMesh
from .relaxnewton import RELAX_STALL
from .restarts import RELAX_RESTARTS, RELAX_UNTANGLE
from .rigspec import (
    JLD_DEFAULTS,
    ROOT,
    BoneSpec,
    JLDParams,
    JointSpec,
    Primitive,
    RigSpec,
    read_rig,
)
from .shipped import HAND_DIR, RESOLUTIONS, Hand, hand_files, load_hand
from .skeleton import PIVOT_SUFFIX, Skeleton, load_skeleton, rotation_matrices

__all__ = [
    "COARSE",
    "FINE",
    "FINGERTIPS",
    "HAND_DIR",
    "JLD_DEFAULTS",
    "PIVOT_SUFFIX",
    "RELAX_QUALITY",
    "RELAX_RESTARTS",
    "RELAX_STALL",
    "RELAX_STOP",
    "RELAX_UNTANGLE",
    "RESOLUTIONS",
    "ROOT",
    "AutoFlexResult",
    "BoneSpec",
    "Clamp",
    "FleshRelaxer",
    "Hand",
    "HandPoser",
    "JLDMap",
    "JLDParams",
    "JointSpec",
    "Key",
    "Keyframes",
    "ObjectAssociation",
    "Pose",
    "Primitive",
    "RelaxMesh",
    "Resolution",
    "RigSpec",
    "Skeleton",
    "SkeletonTopology",
    "auto_flex",
    "block_cg",
    "block_pattern",
    "bone_gaps",
    "bone_profile",
    "bone_surfaces",
    "bridging_nodes",
    "build_hand",
    "cell_bones",
    "cell_parts",
    "check_hand_geometry",
    "expected_halvings",
    "field_on_grid",
    "field_threshold",
    "finger_widths",
    "fingertip_node",
    "fingertips",
    "flesh_thickness",
    "gap_edges",
    "hand_files",
    "hand_report",
    "joint_clearance",
    "joint_pairs",
    "kb_tangents",
    "kochanek_bartels",
    "label_bone_nodes",
    "load_hand",
    "load_skeleton",
    "merged_surface",
    "mesh_distance",
    "muscle_profile",
    "node_parts",
    "open_joints",
    "part_letters",
    "patch_energy",
    "plane_distance",
    "pose_hand",
    "posed_primitives",
    "quality_summary",
    "read_rig",
    "render_hand",
    "render_sequence",
    "rotation_matrices",
    "skin_surface",
    "smoothstep",
    "sphere_distance",
    "split_joint_gaps",
    "step_terms",
    "surface_distance",
    "sweep_bone",
    "tet_aspect_ratios",
    "tet_dihedral_angles",
    "tet_quality",
    "tet_volumes",
    "tetrahedralize_flesh",
    "transform_points",
    "untangle_terms",
    "volumes_quality",
    "write_gif",
    "write_hand",
]
