"""Posing the hand: the API the contact solver uses, no inverted tetrahedra over the tested
range of motion, inversion errors that name the joint and the element, and pictures."""

from __future__ import annotations

import numpy as np
import pytest

import fem
from contact.errors import PoseError, RigError
from contact.hand import load_hand
from contact.keyframes import Keyframes
from contact.posing import HandPoser, Pose, pose_hand, tet_quality
from contact.skeleton import PIVOT_SUFFIX

#: Fraction of every joint's limits the shipped coarse mesh takes without inverting a
#: tetrahedron (measured: a few PIP and MCP poses invert between 0.2 and 0.25, first the
#: tetrahedra whose four nodes are fixed to two bones across the joint).
SAFE = 0.2


@pytest.fixture(scope="module")
def hand():
    return load_hand("coarse")


@pytest.fixture(scope="module")
def poser(hand):
    return HandPoser(hand)


def test_pose_hand_gives_points_and_bone_transforms(hand):
    angles = {"index_mcp": 15.0, "index_pip": 20.0, "thumb_cmc_pivot": 5.0}
    pose = pose_hand(hand, angles)
    assert isinstance(pose, Pose)
    assert pose.points.shape == hand.flesh.points.shape
    assert set(pose.transforms) == set(hand.skeleton.bone_names)
    np.testing.assert_allclose(pose.points - hand.flesh.points, pose.displacement, atol=1e-18)
    # bone nodes are the prescribed displacements: rigid with their bone
    nodes = hand.bone_nodes("index_middle")
    t = pose.transforms["index_middle"]
    np.testing.assert_allclose(
        pose.points[nodes], hand.flesh.points[nodes] @ t[:3, :3].T + t[:3, 3], atol=1e-15
    )
    assert np.linalg.norm(pose.displacement[nodes], axis=1).min() > 1e-3
    mesh = pose.mesh()
    assert isinstance(mesh, fem.Mesh) and mesh.volumes["tetra"].min() > 0
    assert pose.angles["index_pip"] == 20.0 and pose.angles["middle_pip"] == 0.0
    assert 0.0 < pose.min_quality < 1.0
    assert pose_hand(hand, angles).points.tobytes() == pose.points.tobytes()  # cached poser


def test_rest_pose_is_the_rest_mesh_exactly(hand, poser):
    pose = poser.pose({})
    assert np.array_equal(pose.points, hand.flesh.points)
    assert not pose.displacement.any()
    assert np.array_equal(poser.skin_points({}), np.asarray(hand.skin.points))


def test_unknown_or_out_of_range_angles_are_errors(poser):
    with pytest.raises(RigError, match="unknown joint angle 'index_pop'"):
        poser.pose({"index_pop": 10.0})
    with pytest.raises(RigError, match=r"index_pip = 130 deg is outside its limits \[0, 110\]"):
        poser.pose({"index_pip": 130.0})


def test_100_random_poses_leave_every_tet_positive(hand, poser):
    rng = np.random.default_rng(2024)
    limits = hand.skeleton.limits
    worst = np.inf
    for _ in range(100):
        angles = {n: rng.uniform(SAFE * lo, SAFE * hi) for n, (lo, hi) in limits.items()}
        pose = poser.pose(angles)  # raises PoseError on an inverted tetrahedron
        assert len(pose.inverted) == 0
        worst = min(worst, pose.min_quality)
    rest = tet_quality(hand.flesh.points, hand.flesh.cells["tetra"]).min()
    print(f"min tet quality over 100 random poses: {worst:.4f} (rest {rest:.4f})")
    assert worst > 0.0


def test_each_limit_poses_or_names_its_joint_and_element(hand, poser):
    """Every angle alone at SAFE of its limits poses; at its limit, either it poses or the
    error names that joint and an inverted element."""
    failed = []
    for name, (lo, hi) in hand.skeleton.limits.items():
        joint = name.removesuffix(PIVOT_SUFFIX)
        for limit in (lo, hi):
            if limit == 0.0:
                continue
            assert len(poser.pose({name: SAFE * limit}).inverted) == 0
            try:
                poser.pose({name: limit})
            except PoseError as exc:
                failed.append((name, limit))
                assert exc.joint == joint, (name, str(exc))
                assert f"element {exc.element}" in str(exc) and joint in str(exc)
                pose = poser.pose({name: limit}, check=False)
                assert exc.element in pose.inverted and len(pose.inverted) == len(exc.elements)
                assert (
                    tet_quality(pose.points, hand.flesh.cells["tetra"][[exc.element]]) <= 0
                ).all()
    # deep flexions are beyond what the shipped mesh can take (28 of the 40 limits, measured)
    assert ("index_pip", 110.0) in failed and ("index_mcp", -20.0) not in failed
    assert 20 <= len(failed) <= 32


def test_error_names_the_joint_and_the_element(poser):
    with pytest.raises(PoseError, match=r"element \d+ \(nodes \[.*\]\), at joint index_pip"):
        poser.pose({"index_pip": 110.0})


def test_sequence_to_png_frames_and_gif(hand, poser, tmp_path):
    pv = pytest.importorskip("pyvista")
    pv.OFF_SCREEN = True
    from PIL import Image

    from contact.animation import render_sequence

    kf = Keyframes(
        hand.skeleton,
        [
            {"time": 0.0, "angles": {"index_mcp": 0.0}},
            {"time": 1.0, "angles": {"index_mcp": 18.0, "index_pip": 20.0}},
        ],
    )
    files = render_sequence(poser, kf, [0.0, 1.0], tmp_path, window_size=(240, 180))
    assert [f.suffix for f in files] == [".png", ".png", ".gif"]
    first, last = (np.asarray(Image.open(f).convert("L"), dtype=float) for f in files[:2])
    assert first.std() > 5.0 and last.std() > 5.0  # not blank
    assert np.abs(first - last).mean() > 0.5  # the finger moved
    gif = Image.open(files[2])
    assert gif.n_frames == 2
