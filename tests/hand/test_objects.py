"""Object association (the JLD paper's OBJECTS): an object follows a joint between two times."""

from __future__ import annotations

import numpy as np
import pytest

from contact.errors import RigError
from contact.hand.keyframes import Keyframes
from contact.hand.objects import ObjectAssociation, transform_points
from contact.hand.shipped import HAND_DIR
from contact.hand.skeleton import load_skeleton


@pytest.fixture(scope="module")
def skeleton():
    return load_skeleton(HAND_DIR / "rig.toml")


@pytest.fixture(scope="module")
def keys(skeleton):
    return Keyframes(
        skeleton,
        [
            {"time": 0.0, "angles": {"index_mcp": 0.0, "index_pip": 0.0}},
            {"time": 10.0, "angles": {"index_mcp": 60.0, "index_pip": 80.0}},
            {"time": 15.0, "angles": {"index_mcp": 10.0, "index_pip": 5.0}},
        ],
    )


def test_apple_follows_the_second_index_joint_from_5_to_10(skeleton, keys):
    # "OBJECTS APPLE INDEX RIGHT KNUCKLES2 5 10"
    apple = ObjectAssociation("apple", "index_pip", 5.0, 10.0)
    pts = np.array([[-0.031, 0.14, -0.01], [-0.028, 0.15, -0.012]])  # under the middle phalanx
    for t in (0.0, 3.0, 5.0):
        np.testing.assert_array_equal(apple.transform(skeleton, keys.pose, t), np.eye(4))
    # in between: rigid, and fixed relative to the joint's posed frame
    for t in (6.0, 8.0, 10.0):
        tf = apple.transform(skeleton, keys.pose, t)
        np.testing.assert_allclose(tf[:3, :3] @ tf[:3, :3].T, np.eye(3), atol=1e-12)
        f_start = skeleton.joint_frames(keys.pose(5.0))["index_pip"]
        f_now = skeleton.joint_frames(keys.pose(t))["index_pip"]
        local_start = np.linalg.solve(f_start, np.c_[pts, np.ones(2)].T)
        local_now = np.linalg.solve(f_now, np.c_[transform_points(pts, tf), np.ones(2)].T)
        np.testing.assert_allclose(local_now, local_start, atol=1e-12)
    # the joint's centre carries the object: the apple moves with the finger
    moved = transform_points(pts, apple.transform(skeleton, keys.pose, 10.0))
    assert np.linalg.norm(moved - pts, axis=1).min() > 0.02
    # after the stop it stays where it was at 10, though the finger opens again
    final = apple.transform(skeleton, keys.pose, 10.0)
    for t in (12.0, 15.0, 30.0):
        np.testing.assert_allclose(apple.transform(skeleton, keys.pose, t), final, atol=1e-15)


def test_bad_associations_name_the_object(skeleton, keys):
    with pytest.raises(RigError, match="object pear: unknown joint 'index_knuckle'"):
        ObjectAssociation("pear", "index_knuckle", 0.0, 1.0).transform(skeleton, keys.pose, 0.5)
    with pytest.raises(RigError, match="object pear: association times"):
        ObjectAssociation("pear", "index_pip", 2.0, 1.0).check(skeleton)
