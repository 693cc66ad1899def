"""The JLD mapping of the flesh: localisation, exact identity, rigid bones, continuity,
joint rounding and muscle inflation."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from contact.hand.jld import JLDMap
from contact.hand.jldframes import muscle_profile
from contact.hand.shipped import load_hand
from contact.hand.skeleton import Skeleton

#: A moderate pose moving every kind of joint (degrees).
POSE = {
    "wrist": 15.0,
    "wrist_pivot": -5.0,
    "ring_cmc": 8.0,
    "little_cmc": 10.0,
    "thumb_cmc": 15.0,
    "thumb_cmc_pivot": 10.0,
    "index_mcp": 20.0,
    "index_mcp_pivot": 5.0,
    "middle_mcp": 15.0,
    "index_pip": 20.0,
    "ring_pip": 15.0,
    "little_dip": 20.0,
    "thumb_ip": 20.0,
}


@pytest.fixture(scope="module")
def hand():
    return load_hand("coarse")


@pytest.fixture(scope="module")
def jld(hand):
    return JLDMap(hand.skeleton, hand.flesh.points, hand.bone_id)


def test_localisation_projection_ratio_thickness(hand):
    sk = hand.skeleton
    bone = sk.bones["index_middle"]
    d = (bone.end - bone.start) / bone.length
    side = np.cross(d, sk.joints["index_pip"].flexion_axis)
    pts = np.array([bone.start + 0.5 * (bone.end - bone.start), bone.end - 0.25 * bone.length * d])
    pts = np.vstack([pts, pts[0] + 0.004 * side])
    m = JLDMap(sk, pts, reference=(hand.flesh.points, hand.bone_id))
    names = sk.bone_names
    assert [names[s] for s in m.segment] == ["index_middle"] * 3
    # the ratio runs between the joint planes, which bisect the (nearly straight) chain
    np.testing.assert_allclose(m.ratio, [0.5, 0.75, 0.5], atol=0.01)
    np.testing.assert_allclose(m.thickness, [0.0, 0.0, 0.004], atol=2e-4)


def test_identity_is_exact_at_rest(hand, jld):
    x = hand.flesh.points
    assert np.array_equal(jld.map(), x)
    assert np.array_equal(jld.map({n: 0.0 for n in hand.skeleton.angle_names}), x)
    assert not np.any(jld.displacement({}))
    jld.map(POSE)  # a pose in between leaves nothing behind
    assert np.array_equal(jld.map({}), x)
    skin = np.asarray(hand.skin.points)
    ms = JLDMap(hand.skeleton, skin, reference=(x, hand.bone_id))
    assert np.array_equal(ms.map({}), skin)


def test_bone_nodes_move_rigidly_with_their_bone(hand, jld):
    posed = jld.map(POSE)
    tf = hand.skeleton.forward_kinematics(POSE)
    moved = 0
    for name in hand.skeleton.bone_names:
        nodes = hand.bone_nodes(name)
        t = tf[name]
        expect = hand.flesh.points[nodes] @ t[:3, :3].T + t[:3, 3]
        np.testing.assert_allclose(posed[nodes], expect, rtol=0, atol=1e-15)
        moved += not np.allclose(t, np.eye(4))
    assert moved >= 15


def _boundary_edges(hand, jld, per_kind: int, seed: int = 0) -> np.ndarray:
    """Edges between free nodes whose ends lie in different segments, zones or areas."""
    t = hand.flesh.cells["tetra"]
    e = np.unique(
        np.sort(
            t[:, [0, 0, 0, 1, 1, 2, 1, 2, 3, 2, 3, 3]]
            .reshape(-1, 2, 6)
            .transpose(0, 2, 1)
            .reshape(-1, 2),
            axis=1,
        ),
        axis=0,
    )
    e = e[(hand.bone_id[e] < 0).all(1)]
    loc = jld._main
    blended = np.zeros(hand.flesh.n_points, bool)
    blended[jld._pairs["idx"]] = True
    rigid = (loc["zone"] < 0) | (loc["s"] == 0.0) | (loc["s"] == 1.0)
    kinds = [
        loc["seg"][e[:, 0]] != loc["seg"][e[:, 1]],  # across a joint plane
        rigid[e[:, 0]] != rigid[e[:, 1]],  # area / buffer
        (loc["round_k"][e[:, 0]] > 0) != (loc["round_k"][e[:, 1]] > 0),  # rounding area
        blended[e[:, 0]] != blended[e[:, 1]],  # palm in-between area
    ]
    rng = np.random.default_rng(seed)
    pick = [rng.choice(np.flatnonzero(k), per_kind, replace=False) for k in kinds]
    assert all(len(p) == per_kind for p in pick)
    return e[np.concatenate(pick)]


def test_mapping_is_continuous_across_area_boundaries(hand, jld):
    """No jump above 2 um where the mapping changes segment, area or covering.

    Edges between free nodes that cross a boundary are sampled every 4 um or less; the
    20 largest steps are refined 200 times: a continuous mapping's step shrinks with the
    spacing (below 0.3 um for a stretch under 15), a jump stays.
    """
    edges = _boundary_edges(hand, jld, per_kind=10)
    k = 3000
    u = np.linspace(0.0, 1.0, k)[None, :, None]
    x = hand.flesh.points
    a, b = x[edges[:, 0]][:, None], x[edges[:, 1]][:, None]
    samples = (a + u * (b - a)).reshape(-1, 3)
    ref = (x, hand.bone_id)
    y = JLDMap(hand.skeleton, samples, reference=ref).map(POSE).reshape(len(edges), k, 3)
    assert (np.linalg.norm(b - a, axis=2) / (k - 1)).max() < 4e-6
    step = np.linalg.norm(np.diff(y, axis=1), axis=2)
    worst = np.argsort(step.ravel())[-20:]
    e, i = np.unravel_index(worst, step.shape)
    p0 = samples.reshape(len(edges), k, 3)[e, i]
    p1 = samples.reshape(len(edges), k, 3)[e, i + 1]
    v = np.linspace(0.0, 1.0, 201)[None, :, None]
    fine = (p0[:, None] + v * (p1 - p0)[:, None]).reshape(-1, 3)
    yf = JLDMap(hand.skeleton, fine, reference=ref).map(POSE).reshape(20, 201, 3)
    jump = np.linalg.norm(np.diff(yf, axis=1), axis=2).max()
    print(f"largest step {step.max() * 1e6:.2f} um; refined 200x: {jump * 1e6:.3f} um")
    assert jump < 2e-6, f"a jump of {jump * 1e6:.1f} um"
    # the samples at the ends agree with the flesh mapping of the nodes themselves
    posed = jld.map(POSE)
    np.testing.assert_allclose(y[:, 0], posed[edges[:, 0]], atol=1e-12)
    np.testing.assert_allclose(y[:, -1], posed[edges[:, 1]], atol=1e-12)


def _skeleton_with(hand, **values) -> Skeleton:
    spec = hand.skeleton.spec
    jld = {n: p.replace(**values) for n, p in (spec.jld or {}).items()}
    return Skeleton(dataclasses.replace(spec, jld=jld))


def test_muscle_profile_joins_two_exponentials_at_the_peak():
    r = np.linspace(0.0, 1.0, 1001)
    f = muscle_profile(r, 0.3, 2.0)
    assert f[0] == 0.0 and f[-1] == 0.0
    assert f.max() == pytest.approx(1.0) and r[np.argmax(f)] == pytest.approx(0.3)
    assert np.all(np.diff(f[r <= 0.3]) > 0) and np.all(np.diff(f[r >= 0.3]) < 0)
    h = 1e-6  # zero slope on both sides of the join point
    assert abs(muscle_profile(0.3 + h, 0.3, 2.0) - 1.0) < 1e-9
    assert abs(muscle_profile(0.3 - h, 0.3, 2.0) - 1.0) < 1e-9


@pytest.mark.parametrize(("key", "side"), [("rounding", 1.0), ("muscle", -1.0)])
def test_rounding_and_inflation_grow_with_flexion(hand, key, side):
    """Dorsal rounding at the PIP and palmar inflation of the middle phalanx."""
    other = "muscle" if key == "rounding" else "rounding"
    x, bid = hand.flesh.points, hand.bone_id
    on = JLDMap(_skeleton_with(hand, **{key: 0.3, other: 0.0}), x, bid)
    off = JLDMap(_skeleton_with(hand, rounding=0.0, muscle=0.0), x, bid)
    coef = on._main["round_k" if key == "rounding" else "musc_k"]
    names = hand.skeleton.joint_names
    which = on._main["round_j" if key == "rounding" else "musc_j"]
    joint = "index_pip"
    nodes = np.flatnonzero((coef > 0.01) & (which == names.index(joint)))
    assert len(nodes) >= 10
    normal = hand.skeleton.bones["index_middle"].frame[:, 2]  # dorsal
    growth = []
    for angle in (0.0, 20.0, 40.0, 60.0):
        d = on.map({joint: angle})[nodes] - off.map({joint: angle})[nodes]
        growth.append(np.linalg.norm(d, axis=1).mean())
        if angle:
            # outward: along the rest offset from the axis, turned with the pose
            posed_normal = hand.skeleton.forward_kinematics({joint: angle})["index_middle"]
            n = posed_normal[:3, :3] @ normal
            assert np.mean(side * (d @ n) > 0) > 0.8
    assert growth[0] == 0.0
    assert np.all(np.diff(growth) > 0), growth
    # linear in the flexion ratio: 60 deg gives three times 20 deg (to the rotation's effect)
    assert growth[3] / growth[1] == pytest.approx(3.0, rel=0.15)


def test_rig_jld_section_defaults_overrides_and_errors(tmp_path):
    from contact.errors import RigError
    from contact.hand.rigspec import JLD_DEFAULTS, read_rig
    from contact.hand.shipped import HAND_DIR

    text = (HAND_DIR / "rig.toml").read_text()
    spec = read_rig(HAND_DIR / "rig.toml")
    assert spec.jld_params("thumb_cmc").muscle_peak == 0.4
    assert spec.jld_params("index_pip") == JLD_DEFAULTS
    start = text.index("\n[jld]\n")
    end = text.index("# ----", start)
    old = tmp_path / "rig.toml"
    old.write_text(text[:start] + text[end:])  # a rig from before the [jld] section
    assert read_rig(old).jld_params("thumb_cmc") == JLD_DEFAULTS
    bad = text.replace("[jld.joints.thumb_cmc]", "[jld.joints.thumb_cmc]\nproximal = 0.7")
    (tmp_path / "bad.toml").write_text(bad)
    with pytest.raises(RigError, match=r"jld.joints.thumb_cmc.proximal = 0.7: must lie in"):
        read_rig(tmp_path / "bad.toml")
    (tmp_path / "bad2.toml").write_text(
        text.replace("[jld.joints.thumb_cmc]", "[jld.joints.thumb_xyz]")
    )
    with pytest.raises(RigError, match=r"jld.joints.thumb_xyz"):
        read_rig(tmp_path / "bad2.toml")


def test_a_subset_of_points_maps_as_in_the_whole(hand, jld):
    """Localised alone (against the whole flesh's bone nodes), points map as in the whole."""
    rng = np.random.default_rng(4)
    pick = rng.choice(hand.flesh.n_points, 40, replace=False)
    sub = JLDMap(
        hand.skeleton,
        hand.flesh.points[pick],
        hand.bone_id[pick],
        reference=(hand.flesh.points, hand.bone_id),
    )
    np.testing.assert_allclose(sub.map(POSE), jld.map(POSE)[pick], rtol=0, atol=1e-12)
    assert len(sub._surfaces.trees) < len(jld._surfaces.trees)  # only the bones these points need


def test_one_pose_at_a_time(jld):
    with pytest.raises(ValueError, match="one pose at a time"):
        jld.map({"index_mcp": [10.0, 20.0]})
