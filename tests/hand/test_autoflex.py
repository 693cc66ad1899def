"""Automatic flexion: the dichotomous search of the AUTO_F commands (Magnenat-Thalmann,
Laperrière and Thalmann 1988)."""

from __future__ import annotations

import numpy as np
import pytest

from contact.errors import RigError
from contact.hand.autoflex import (
    auto_flex,
    expected_halvings,
    fingertip_node,
    plane_distance,
    sphere_distance,
)
from contact.hand.posing import pose_hand
from contact.hand.shipped import load_hand

R = 0.02  # sphere radius (m)


@pytest.fixture(scope="module")
def hand():
    return load_hand("coarse")


@pytest.fixture(scope="module")
def ball(hand):
    """A sphere the index fingertip meets at index_mcp = 25 deg (other joints bent too)."""
    base = {"index_pip": 20.0, "index_dip": 10.0, "wrist": 5.0}
    tip = fingertip_node(hand, "index")
    p = [pose_hand(hand, {**base, "index_mcp": a}, check=False).points[tip] for a in (25.0, 25.1)]
    ahead = (p[1] - p[0]) / np.linalg.norm(p[1] - p[0])
    return base, tip, p[0] + R * ahead


def test_fingertips_lie_at_the_end_of_their_finger(hand):
    for finger in ("thumb", "index", "middle", "ring", "little"):
        bone = hand.skeleton.bones[f"{finger}_distal"]
        x = hand.flesh.points[fingertip_node(hand, finger)]
        assert np.linalg.norm(x - bone.end) < 0.012, finger
        assert (x - bone.start) @ (bone.end - bone.start) > bone.length**2
    with pytest.raises(RigError, match="unknown fingertip 'toe'"):
        fingertip_node(hand, "toe")


def test_dichotomous_search_meets_epsilon_within_the_expected_halvings(hand, ball):
    base, tip, centre = ball
    eps = 1e-5
    res = auto_flex(hand, "index", sphere_distance(centre, R), "index_mcp", base, epsilon=eps)
    assert res.converged and res.reason == "within epsilon"
    assert abs(res.distance) < eps
    assert res.angle == pytest.approx(25.0, abs=0.05)
    lever = np.linalg.norm(hand.flesh.points[tip] - hand.skeleton.joints["index_mcp"].position)
    bound = expected_halvings(lever, 90.0 / 16, eps)  # one scan step of 0..90 deg
    print(f"{res.halvings} halvings (bound {bound}) to {res.distance * 1e6:.2f} um")
    assert 1 <= res.halvings <= bound
    scanned = len(res.history) - res.halvings
    assert 2 <= scanned <= 17
    assert [d > 0 for _, d in res.history[: scanned - 1]] == [True] * (scanned - 1)
    # the pose it returns puts the node where the search saw it
    posed = pose_hand(hand, res.angles, check=False).points[tip]
    assert np.linalg.norm(posed - centre) - R == pytest.approx(res.distance, abs=1e-12)
    # with the vertex number instead of the name
    by_node = auto_flex(hand, tip, sphere_distance(centre, R), "index_mcp", base, epsilon=eps)
    assert by_node.angle == res.angle


def test_press_depth_bends_further(hand, ball):
    base, _, centre = ball
    touch = auto_flex(hand, "index", sphere_distance(centre, R), "index_mcp", base)
    press = auto_flex(hand, "index", sphere_distance(centre, R), "index_mcp", base, press=0.003)
    assert press.converged and press.target == -0.003
    assert press.distance == pytest.approx(-0.003, abs=1e-5)
    assert press.angle > touch.angle + 1.0


def test_first_contact_stops_at_the_pad_that_reaches_the_ball_before_the_tip(hand):
    # a ball under the index's middle phalanx: flexing the MCP brings the finger's pad
    # to it long before the tip, which curls past it
    base = {"index_pip": 40.0, "index_dip": 20.0}
    skin = hand.skin_faces.nodes
    bone = hand.skeleton.bones["index_middle"]
    tip = fingertip_node(hand, "index")
    mid = 0.5 * (bone.start + bone.end)
    at = {a: pose_hand(hand, {**base, "index_mcp": a}, check=False).points for a in (0.0, 30.0)}
    # the pad: the skin node near the middle phalanx that the flexion moves most
    near = skin[np.linalg.norm(hand.flesh.points[skin] - mid, axis=1) < 0.012]
    pad = near[np.argmax(np.linalg.norm(at[30.0][near] - at[0.0][near], axis=1))]
    ahead = at[30.0][pad] - at[0.0][pad]
    centre = at[30.0][pad] + R * ahead / np.linalg.norm(ahead)
    ball = sphere_distance(centre, R)
    res = auto_flex(hand, "index", ball, "index_mcp", base, press=0.001, first_contact=True)
    assert res.converged and res.node != tip
    assert res.distance == pytest.approx(-0.001, abs=1e-4)
    posed = pose_hand(hand, res.angles, check=False).points
    # the node it names is the deepest skin node the joint moved, at the press asked
    assert ball(posed[[res.node]])[0] == pytest.approx(res.distance, abs=1e-9)
    moved = skin[np.linalg.norm(posed[skin] - hand.flesh.points[skin], axis=1) > 1e-6]
    assert ball(posed[moved]).min() >= res.distance - 1e-9
    assert ball(posed[[tip]])[0] > 0.0  # the tip has not reached the ball
    assert res.angle < 31.0  # the pad itself touches at 30 degrees: something did first
    # the seed's search for the tip alone drives the finger through the ball
    seed = auto_flex(hand, "index", ball, "index_mcp", base, press=0.001)
    assert seed.node == tip and (not seed.converged or seed.angle > res.angle + 5.0)


def test_no_contact_in_the_bracket_is_reported_not_raised(hand):
    far = plane_distance([0.0, 0.0, -0.5], [0.0, 0.0, 1.0])  # half a metre below the palm
    res = auto_flex(hand, "middle", far, "middle_pip", bracket=(0.0, 60.0))
    assert not res.converged and "does not reach" in res.reason
    assert res.halvings == 0 and res.distance > 0.4
    with pytest.raises(RigError, match="unknown joint angle 'middle_pap'"):
        auto_flex(hand, "middle", far, "middle_pap")
    with pytest.raises(RigError, match=r"bracket \[0, 200\] of middle_pip"):
        auto_flex(hand, "middle", far, "middle_pip", bracket=(0.0, 200.0))


def test_fingertip_is_the_farthest_boundary_node_nearest_its_bone(hand):
    nodes = hand.flesh.boundary.nodes
    x = hand.flesh.points[nodes]
    sk = hand.skeleton
    a = np.stack([b.start for b in sk.bones.values()])
    ab = np.stack([b.end for b in sk.bones.values()]) - a
    t = np.clip(np.einsum("nbk,bk->nb", x[:, None] - a, ab) / (ab * ab).sum(1), 0.0, 1.0)
    nearest = np.argmin(np.linalg.norm(x[:, None] - (a + t[..., None] * ab), axis=2), axis=1)
    for finger in ("thumb", "index", "middle", "ring", "little"):
        bone = sk.bones[f"{finger}_distal"]
        mine = nearest == sk.bone_names.index(bone.name)
        along = np.where(mine, (x - bone.start) @ ((bone.end - bone.start) / bone.length), -np.inf)
        assert fingertip_node(hand, finger) == nodes[np.argmax(along)], finger


def test_search_maps_are_kept_per_hand(hand, ball):
    """A second search of the same point reuses its localisation and finds the same angle."""
    from contact.hand.autoflex import _point_map

    base, tip, centre = ball
    first = auto_flex(hand, "index", sphere_distance(centre, R), "index_mcp", base)
    assert _point_map(hand, tip) is _point_map(hand, tip)
    again = auto_flex(hand, "index", sphere_distance(centre, R), "index_mcp", base)
    assert again.angle == first.angle and again.history == first.history
    other = load_hand("coarse")  # another hand: its own maps
    assert _point_map(other, tip) is not _point_map(hand, tip)
