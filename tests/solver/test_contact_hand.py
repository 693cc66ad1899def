"""The coarse hand at rest pressed by a ball: the ball sits in a cup of four tilted rigid
planes (which hold it sideways, as fingers would) that rises into the palm."""

import functools

import numpy as np
import pytest

import fem
from contact import load_hand
from contact.geometry.plane import Plane
from contact.solver import ContactSettings, solve_frame
from contact.solver.body import ElasticBody
from contact.solver.pairs import ContactPair

R = 0.02
E_FLESH = 1.0e5


@functools.cache
def hand_body():
    h = load_hand("coarse")
    bones = {n: h.bone_nodes(n) for n in h.skeleton.bone_names if h.bone_nodes(n).size}
    body = ElasticBody(
        "hand",
        h.flesh,
        fem.LinearElastic(E_FLESH, 0.4),
        prescribed=fem.node_dofs(h.prescribed_nodes),
        supports=bones,
        contact_faces=h.skin_faces,
    )
    # the ball's top touches the lowest skin node above its centre's footprint
    x, skin = h.flesh.points, body.contact_nodes
    centre = np.array([0.01, 0.06])
    under = skin[np.linalg.norm(x[skin, :2] - centre, axis=1) < R]
    return body, np.array([*centre, x[under, 2].min() - R])


@functools.cache
def scene(ratio, press):
    hand, c = hand_body()
    ball = ElasticBody(
        "ball",
        fem.ball_mesh(R, divisions=8, layers=4, center=c),
        fem.LinearElastic(ratio * E_FLESH, 0.4),
    )
    planes = []
    tilt = np.radians(35.0)
    for k, phi in enumerate(np.radians([0.0, 90.0, 180.0, 270.0])):
        d = np.array([np.sin(tilt) * np.cos(phi), np.sin(tilt) * np.sin(phi), -np.cos(tilt)])
        planes.append(Plane(c + R * d, -d, motion=[0, 0, press], name=f"cup{k}"))
    pairs = [ContactPair(ball, p) for p in planes]
    pairs += [ContactPair(ball, hand), ContactPair(hand, ball)]
    return [ball, hand], pairs, planes


def solve(ratio, press, **settings):
    bodies, pairs, planes = scene(ratio, press)
    return bodies, solve_frame(bodies, pairs, planes, ContactSettings(**settings))


@pytest.mark.parametrize("ratio", [0.01, 0.1, 10.0, 100.0])
def test_contact_space_holds_the_ball_against_the_palm(ratio):
    (ball, hand), res = solve(ratio, 0.005)
    assert res.converged, res.stop_reason
    # the unilateral solve opens and closes rows itself: a few updates bring geometry
    # (were 7 at ratio 0.01 when the updates released pulling rows)
    assert res.iterations <= 5
    assert res.penetration_ratio <= 1e-3
    on_hand = res.total_contact_force("hand")
    assert on_hand[2] > 0  # the ball pushes the palm up (the palm faces -z)
    cup = sum(res.obstacle_forces.values())
    scale = np.linalg.norm(on_hand)
    # action equals reaction; the free ball in balance; the bones carry the hand
    assert np.abs(res.total_contact_force("ball") + on_hand + cup).max() <= 1e-10 * scale
    assert np.abs(res.total_contact_force("ball")).max() <= 1e-9 * scale
    bones = sum(res.support_forces["hand"].values())
    assert np.abs(bones + on_hand).max() <= 1e-9 * scale
    # the palm's bones carry it: the metacarpals above the ball, nothing in the thumb
    forces = {k: np.linalg.norm(v) for k, v in res.support_forces["hand"].items()}
    top = max(forces, key=forces.get)
    assert top.endswith("_metacarpal") and not top.startswith("thumb")
    assert forces["thumb_distal"] <= 1e-3 * forces[top]
    # nothing left inside by more than 1e-3 of the local element size
    assert 0 < res.penetration_ratio <= 1e-3
    local = max(np.sqrt(b.node_areas[b.contact_nodes].max()) for b in (ball, hand))
    assert res.max_penetration <= 1e-3 * local


def test_a_frame_whose_rows_cannot_be_renewed_is_not_converged(monkeypatch):
    # the soft skin's facets turn under the stiff ball: its rows are linearised again on
    # the same facet until the gaps close (the test above); without that, the nodes left
    # inside make the frame not converged, never a silent "converged"
    import contact.solver.contactset as contactset

    monkeypatch.setattr(contactset, "RELINEARISE", 0)
    bodies, pairs, planes = scene(100.0, 0.005)
    res = solve_frame(bodies, pairs, planes, ContactSettings())
    assert not res.converged
    assert res.stop_reason.startswith("penetration left: node ")
    assert "of pair ball/hand" in res.stop_reason
    assert res.penetration_ratio > 1e-3


def test_a_node_in_a_concave_crease_of_the_skin_is_held_by_both_facets():
    # pressed deeper, a ball node comes to a crease of the skin: held on one facet it is
    # inside the next and the other way round; it keeps a row on each, both pushing
    from contact.solver.contactset import CORNER_COS

    bodies, pairs, planes = scene(10.0, 0.008)
    res = solve_frame(bodies, pairs, planes, ContactSettings())
    assert res.converged, res.stop_reason
    assert res.penetration_ratio <= 1e-3
    c = res.contacts
    keys = np.column_stack([np.unique(c["pair"], return_inverse=True)[1], c["node"]])
    uniq, counts = np.unique(keys, axis=0, return_counts=True)
    assert counts.max() == 2
    for key in uniq[counts == 2]:
        both = np.flatnonzero((keys == key).all(axis=1))
        assert (c["force"][both] > 0).all()
        assert c["normal"][both[0]] @ c["normal"][both[1]] < CORNER_COS


def test_seed_loop_holds_a_soft_ball_and_fails_a_stiff_one():
    _, ref = solve(0.1, 0.005)
    _, soft = solve(0.1, 0.005, algorithm="seed")
    assert soft.converged, soft.stop_reason
    f = soft.total_contact_force("hand")[2]
    # the same answer, to the seed loop's own tolerance (its last change 1e-4 of the
    # displacement) and its contact set
    assert f == pytest.approx(ref.total_contact_force("hand")[2], rel=0.03)
    _, stiff = solve(10.0, 0.005, algorithm="seed")
    assert not stiff.converged
    assert stiff.stop_reason.startswith(("diverged: ", "iteration limit", "cycling"))


def test_a_deeper_press_passes_the_bone_limit_and_names_the_bone():
    _, shallow = solve(0.1, 0.005)
    forces = {k: np.linalg.norm(v) for k, v in shallow.support_forces["hand"].items()}
    top = max(forces, key=forces.get)
    limits = {name: 1.5 * forces[top] for name in forces}
    _, ok = solve(0.1, 0.005, support_limits=limits)
    assert ok.converged and not ok.over_limit
    _, deep = solve(0.1, 0.008, support_limits=limits)
    assert deep.converged and deep.stop_reason == "converged"
    assert deep.over_limit[top][0] > deep.over_limit[top][1] == limits[top]
