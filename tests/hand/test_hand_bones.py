"""Bone surfaces: swept shapes, closed and outward, apart across joints, rigid under FK."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import fem
from contact.errors import RigError
from contact.geometry.surfaces import enclosed_volume, surface_arrays
from contact.hand.bones import bone_profile, bone_surfaces, sweep_bone
from contact.hand.skeleton import load_skeleton

RIG = Path(__file__).resolve().parents[2] / "meshes" / "hand" / "rig.toml"


@pytest.fixture(scope="module")
def skeleton():
    return load_skeleton(RIG)


@pytest.fixture(scope="module")
def rest(skeleton):
    return bone_surfaces(skeleton, edge=0.003)


def test_bones_closed_outward_with_wider_ends(skeleton, rest):
    assert list(rest) == skeleton.bone_names
    for name, poly in rest.items():
        pts, tri = surface_arrays(poly)
        fem.check_surface(pts, tri, source=name)
        assert enclosed_volume(pts, tri) > 0
        bone = skeleton.bones[name]
        y, w = bone_profile(bone, 0.0, 0.001)
        mid = np.argmin(np.abs(y - 0.5 * (y[0] + bone.length)))
        assert w[mid, 0] < w.max(axis=0)[0]  # a waist: the ends are wider than the shaft
        np.testing.assert_allclose(w[mid], bone.shaft, rtol=0.3)


def test_metacarpal_heads_are_dorsal_under_the_knuckles(skeleton, rest):
    """The knuckles: bone close under the dorsal skin, deeper under the palm (Gourret et al.
    1989)."""
    for f in ("index", "middle", "ring", "little"):
        head = rest[f"{f}_metacarpal"].points
        mcp = skeleton.joints[f"{f}_mcp"].position
        near = np.linalg.norm(head - mcp, axis=1) < 0.008
        assert head[near, 2].max() > mcp[2] + 0.004  # dorsal bump of the head


def test_no_contact_across_joints_at_rest(skeleton, rest):
    gap = skeleton.spec.gap
    for name, bone in skeleton.bones.items():
        joint = skeleton.spec.joints.get(bone.joint)
        if joint is None:
            continue
        parents = [n for n, b in skeleton.bones.items() if b.joint == joint.parent]
        axis = bone.frame[:, 1]
        lo = ((rest[name].points - bone.start) @ axis).min()
        for p in parents:
            hi = ((rest[p].points - bone.start) @ axis).max()
            assert lo - hi >= gap - 1e-12, (name, p)


def test_fk_moves_bones_rigidly(skeleton, rest):
    rng = np.random.default_rng(3)
    angles = {k: float(rng.uniform(lo, hi)) for k, (lo, hi) in skeleton.limits.items()}
    posed = bone_surfaces(skeleton, edge=0.003, angles=angles)
    for name, poly in posed.items():
        a, b = rest[name].points, poly.points
        np.testing.assert_allclose(
            np.linalg.norm(a - a[0], axis=1), np.linalg.norm(b - b[0], axis=1), atol=1e-12
        )
        assert poly.volume == pytest.approx(rest[name].volume, rel=1e-9)


def test_base_past_the_end_is_an_error(skeleton):
    bone = skeleton.bones["index_distal"]
    with pytest.raises(RigError, match="bone index_distal: its base"):
        sweep_bone(bone, bone.length, 0.001)


def test_bones_stay_apart_over_every_joint_range(skeleton):
    """Every joint keeps its bones at least ``flesh.gap`` apart over its whole range (the
    limits and a grid in between): flesh in the gap need not invert at any pose. Before
    the wrist was reshaped the carpus entered the forearm by 3.5 mm (flexion 55, ulnar
    deviation 30)."""
    from contact.hand.bones import joint_clearance

    gap = skeleton.spec.gap
    for joint in skeleton.joint_names:
        clearance, at = joint_clearance(skeleton, joint, steps=5, edge=0.001)
        assert clearance >= 0.98 * gap, (joint, clearance, at)
