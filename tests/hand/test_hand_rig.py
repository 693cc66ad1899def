"""The hand rig file and the skeleton: validation and forward kinematics."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from contact.errors import RigError
from contact.hand.skeleton import PIVOT_SUFFIX, load_skeleton, rotation_matrices

RIG = Path(__file__).resolve().parents[2] / "meshes" / "hand" / "rig.toml"


@pytest.fixture(scope="module")
def skeleton():
    return load_skeleton(RIG)


def random_angles(skeleton, n, seed=0):
    rng = np.random.default_rng(seed)
    return {k: rng.uniform(lo, hi, n) for k, (lo, hi) in skeleton.limits.items()}


def test_rig_names_and_limits(skeleton):
    assert len(skeleton.bone_names) == 21
    for f in ("index", "middle", "ring", "little"):
        assert skeleton.limits[f"{f}_cmc"] == (0.0, 20.0)  # metacarpal flexion, as in the JLD paper
        assert skeleton.limits[f"{f}_mcp"] == (-20.0, 90.0)
        assert skeleton.limits[f"{f}_pip"] == (0.0, 110.0)
        assert skeleton.limits[f"{f}_dip"] == (0.0, 80.0)
        assert f"{f}_mcp{PIVOT_SUFFIX}" in skeleton.limits
    assert {"wrist", "wrist_pivot", "thumb_cmc", "thumb_cmc_pivot", "thumb_mcp", "thumb_ip"} <= set(
        skeleton.limits
    )
    for j in skeleton.joints.values():
        frame = j.frame
        np.testing.assert_allclose(frame.T @ frame, np.eye(3), atol=1e-12)
        assert np.linalg.det(frame) == pytest.approx(1.0)


def test_rotation_matrices_are_rotations():
    rng = np.random.default_rng(1)
    axes = rng.normal(size=(50, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    r = rotation_matrices(axes, rng.uniform(-180, 180, 50))
    np.testing.assert_allclose(
        r @ np.swapaxes(r, 1, 2), np.broadcast_to(np.eye(3), r.shape), atol=1e-12
    )
    np.testing.assert_allclose(np.einsum("nij,nj->ni", r, axes), axes, atol=1e-12)


def test_rest_pose_is_identity(skeleton):
    for t in skeleton.forward_kinematics().values():
        np.testing.assert_allclose(t, np.eye(4), atol=1e-12)


def test_fk_preserves_bone_lengths_and_joints(skeleton):
    angles = random_angles(skeleton, 200)
    transforms = skeleton.forward_kinematics(angles)
    joints = skeleton.joint_transforms(angles)
    for name, bone in skeleton.bones.items():
        t = transforms[name]
        assert t.shape == (200, 4, 4)
        r = t[:, :3, :3]
        np.testing.assert_allclose(
            r @ np.swapaxes(r, 1, 2), np.broadcast_to(np.eye(3), r.shape), atol=1e-12
        )
        np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-12)
        a = r @ bone.start + t[:, :3, 3]
        b = r @ bone.end + t[:, :3, 3]
        np.testing.assert_allclose(np.linalg.norm(b - a, axis=1), bone.length, rtol=1e-12)
    for name, j in skeleton.joints.items():  # a joint stays on its parent's bone
        own = joints[name][:, :3, :3] @ j.position + joints[name][:, :3, 3]
        par = joints[j.parent][..., :3, :3] @ j.position + joints[j.parent][..., :3, 3]
        np.testing.assert_allclose(own, par, atol=1e-12)


def test_flexion_toward_palm_and_pivot_toward_thumb(skeleton):
    tip = skeleton.bones["index_distal"].end
    t = skeleton.forward_kinematics({"index_mcp": 90.0})["index_distal"]
    moved = t[:3, :3] @ tip + t[:3, 3]
    assert moved[2] < tip[2] - 0.05  # the palm faces -z
    t = skeleton.forward_kinematics({"index_mcp_pivot": 15.0})["index_distal"]
    assert (t[:3, :3] @ tip + t[:3, 3])[0] < tip[0] - 0.01  # thumb side is -x
    t = skeleton.forward_kinematics({"thumb_mcp": 50.0, "thumb_ip": 60.0})["thumb_distal"]
    thumb = skeleton.bones["thumb_distal"].end
    assert (t[:3, :3] @ thumb + t[:3, 3])[0] > thumb[0] + 0.01  # across the palm


def test_angle_errors_name_the_joint(skeleton):
    with pytest.raises(RigError, match="index_pip = 120 deg is outside its limits \\[0, 110\\]"):
        skeleton.forward_kinematics({"index_pip": 120.0})
    with pytest.raises(RigError, match="index_cmc = -5"):
        skeleton.forward_kinematics({"index_cmc": [0.0, -5.0]})
    with pytest.raises(RigError, match="unknown joint angle 'index_knuckle'"):
        skeleton.forward_kinematics({"index_knuckle": 10.0})
    with pytest.raises(RigError, match="unknown joint angle 'index_pip_pivot'"):
        skeleton.forward_kinematics({"index_pip_pivot": 1.0})


def _edit(tmp_path, old, new, count=1):
    text = RIG.read_text()
    assert old in text, old
    path = tmp_path / "bad.toml"
    path.write_text(text.replace(old, new, count))
    return path


BAD = [
    (
        '[rig]\nname = "adult right hand"',
        '[rig]\nname = "adult right hand"\ncolour = 1',
        r"bad\.toml: rig\.colour: unknown key",
    ),
    (
        'parent = "index_cmc"',
        'parent = "index_cmx"',
        r"bad\.toml: joints\.index_mcp\.parent = 'index_cmx': unknown joint",
    ),
    (
        '{ joint = "index_mcp", group = "index"',
        '{ joint = "index_knuckle", group = "index"',
        r"bad\.toml: skin\.primitives\[\d+\]\.joint = 'index_knuckle': unknown joint",
    ),
    (
        'group = "index", center',
        'group = "pinky", center',
        r"skin\.primitives\[\d+\]\.group = 'pinky': unknown",
    ),
    (
        "radii = [0.0094,",
        "radii = [-0.0094,",
        r"skin\.primitives\[\d+\]\.radii\[0\] = -0\.0094: must be positive",
    ),
    ("weight = 0.525", "weight = 0.0", r"skin\.primitives\[\d+\]\.weight = 0\.0: must be positive"),
    (
        "flexion = [0.0, 110.0]",
        "flexion = [110.0, 0.0]",
        r"joints\.\w+_pip\.flexion = \[110\.0, 0\.0\]: the lower limit must not exceed the upper",
    ),
    (
        "flexion = [0.0, 110.0]",
        "flexion = [10.0, 110.0]",
        r"joints\.\w+_pip\.flexion = \[10\.0, 110\.0\]: the rest angle 0",
    ),
    ("flexion = [0.0, 80.0]", "flexion = [0.0, 200.0]", r"within \[-180, 180\]"),
    ("flexion = [0.0, 80.0]", 'flexion = "bent"', r"_dip\.flexion = 'bent': must be a list"),
    (
        '[joints.index_pip]\nparent = "index_mcp"',
        '[joints.index_pip]\nparent = "index_dip"',
        r"joints form a cycle",
    ),
    ("pivot = [-20.0, 20.0]\n", "\n", r"joints\.index_mcp: give both pivot_axis and pivot"),
    ('length_unit = "m"', 'length_unit = "mm"', r"rig\.length_unit = 'mm': unknown"),
    ("reach = 1.6", "reach = 0.9", r"skin\.reach = 0\.9: must exceed 1"),
    ("gap = 0.0010", "gap = -0.001", r"flesh\.gap = -0\.001: must be positive"),
    ("[bones.carpus]", "[bones.carpus2]\n[bones.carpus]", r"bones\.carpus2\.base: missing"),
    (
        'end = "index_pip"',
        'end = "middle_pip"',
        r"bones\.index_proximal\.end = 'middle_pip': that joint's parent is not 'index_mcp'",
    ),
    ("shaft = [0.0038,", "shaft = [0.0,", r"bones\.\w+\.shaft\[0\] = 0\.0: must be positive"),
    (
        "flexion_axis = [-1.000, -0.017, 0.000]",
        "flexion_axis = [0.0, 1.0, 0.0]",
        r"joints\.middle_mcp\.flexion_axis = \[0\.0, 1\.0, 0\.0\]: lies too close to the bone",
    ),
    ("[flesh]", "[flesh", r"bad\.toml: not valid TOML"),
]


@pytest.mark.parametrize(("old", "new", "message"), BAD, ids=[b[2][:30] for b in BAD])
def test_rig_errors_name_file_and_key(tmp_path, old, new, message):
    path = _edit(tmp_path, old, new)
    with pytest.raises(RigError, match=message) as info:
        load_skeleton(path)
    assert "\n" not in str(info.value)


def test_missing_rig_file(tmp_path):
    with pytest.raises(RigError, match=re.escape(str(tmp_path / "none.toml"))):
        load_skeleton(tmp_path / "none.toml")


def test_angle_vector_matches_the_per_angle_check(skeleton):
    angles = random_angles(skeleton, 7, seed=3)
    vec = skeleton.angle_vector(angles)
    assert vec.shape == (7, len(skeleton.angle_names))
    for i, name in enumerate(skeleton.angle_names):
        np.testing.assert_array_equal(vec[:, i], angles[name])
    scalar = skeleton.angle_vector({"index_mcp": 30.0, "wrist_pivot": -5})
    assert scalar.shape == (len(skeleton.angle_names),)
    assert scalar[skeleton.angle_names.index("index_mcp")] == 30.0
    assert scalar[skeleton.angle_names.index("wrist_pivot")] == -5.0
    assert np.count_nonzero(scalar) == 2
    assert skeleton.angle_vector({"index_mcp": [[1.0], [2.0]], "wrist": [0.0, 3.0, 4.0]}).shape == (
        2,
        3,
        len(skeleton.angle_names),
    )


def test_angle_errors_not_finite_and_first_in_order(skeleton):
    with pytest.raises(RigError, match="joint angle index_pip is not finite"):
        skeleton.check_angles({"index_pip": float("nan")})
    with pytest.raises(RigError, match="joint angle index_pip is not finite"):
        skeleton.angle_vector({"index_pip": [0.0, np.inf]})
    # both bad: the error names the first in angle_names order, whatever the dict's order
    names = skeleton.angle_names
    first, second = names.index("index_mcp"), names.index("little_dip")
    assert first < second
    with pytest.raises(RigError, match="index_mcp = 95 deg"):
        skeleton.angle_vector({"little_dip": 100.0, "index_mcp": 95.0})


def test_transform_stack_is_rodrigues_joint_by_joint(skeleton):
    angles = random_angles(skeleton, 3, seed=5)
    world = skeleton.transform_stack(skeleton.angle_vector(angles))
    jt = skeleton.joint_transforms(angles)
    for i, (name, j) in enumerate(skeleton.joints.items()):
        piv = angles.get(name + PIVOT_SUFFIX, np.zeros(3))
        axis = j.pivot_axis if j.pivot_axis is not None else [0.0, 0.0, 1.0]
        rot = rotation_matrices(axis, piv) @ rotation_matrices(j.flexion_axis, angles[name])
        local = np.tile(np.eye(4), (3, 1, 1))
        local[:, :3, :3] = rot
        local[:, :3, 3] = j.position - rot @ j.position
        expect = jt[j.parent] @ local
        np.testing.assert_allclose(world[:, i], expect, atol=1e-14)
        np.testing.assert_array_equal(jt[name], world[:, i])
