"""Keyframes: Kochanek-Bartels splines through joint-angle keys, validated and clamped."""

from __future__ import annotations

import numpy as np
import pytest

from contact.errors import RigError
from contact.hand.keyframes import Keyframes, kb_tangents, kochanek_bartels
from contact.hand.shipped import HAND_DIR
from contact.hand.skeleton import load_skeleton


@pytest.fixture(scope="module")
def skeleton():
    return load_skeleton(HAND_DIR / "rig.toml")


def catmull_rom(p: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Uniform Catmull-Rom (matrix form) with reflected end points, keys at 0, 1, 2, ..."""
    ext = np.concatenate([[2 * p[0] - p[1]], p, [2 * p[-1] - p[-2]]])
    i = np.clip(np.floor(at).astype(int), 0, len(p) - 2)
    u = at - i
    m = 0.5 * np.array([[0, 2, 0, 0], [-1, 0, 1, 0], [2, -5, 4, -1], [-1, 3, -3, 1]])
    g = np.stack([ext[i], ext[i + 1], ext[i + 2], ext[i + 3]], 1)
    basis = np.stack([np.ones_like(u), u, u * u, u * u * u], 1)
    return np.einsum("nk,kj,nj->n", basis, m, g)


def test_spline_passes_through_its_keys():
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.uniform(0.2, 2.0, 7))
    p = rng.uniform(-30, 60, 7)
    tcb = rng.uniform(-0.8, 0.8, (3, 7))
    v = kochanek_bartels(t, p, t, *tcb)
    np.testing.assert_allclose(v, p, atol=1e-12)


def test_zero_tension_continuity_bias_is_catmull_rom():
    p = np.array([0.0, 10.0, 45.0, 30.0, 80.0, 20.0])
    at = np.linspace(0.0, 5.0, 501)
    v = kochanek_bartels(np.arange(6.0), p, at)
    np.testing.assert_allclose(v, catmull_rom(p, at), atol=1e-12)
    ts, td = kb_tangents(np.arange(6.0), p)
    np.testing.assert_allclose(ts[1:-1], 0.5 * (p[2:] - p[:-2]))  # (P[i+1] - P[i-1]) / 2
    np.testing.assert_allclose(td, ts)


def test_tension_one_stops_at_each_key_and_unequal_spacing_stays_c1():
    t = np.array([0.0, 1.0, 3.0, 3.5])
    p = np.array([0.0, 40.0, 10.0, 60.0])
    ts, td = kb_tangents(t, p, tension=1.0)
    np.testing.assert_array_equal(ts, 0.0)
    np.testing.assert_array_equal(td, 0.0)
    # continuity = 0: the time derivative matches on both sides of the inner keys
    h = 1e-6
    for k in (1, 2):
        left = (kochanek_bartels(t, p, t[k]) - kochanek_bartels(t, p, t[k] - h)) / h
        right = (kochanek_bartels(t, p, t[k] + h) - kochanek_bartels(t, p, t[k])) / h
        assert abs(left - right) < 1e-3 * max(1.0, abs(left))
    # continuity != 0 breaks it
    c = [0.0, 0.8, 0.0, 0.0]
    left = (kochanek_bartels(t, p, 1.0, 0, c) - kochanek_bartels(t, p, 1.0 - h, 0, c)) / h
    right = (kochanek_bartels(t, p, 1.0 + h, 0, c) - kochanek_bartels(t, p, 1.0, 0, c)) / h
    assert abs(left - right) > 1.0


def test_keyframes_interpolate_hold_and_default_to_rest(skeleton):
    kf = Keyframes(
        skeleton,
        [
            {"time": 0.0, "angles": {"index_mcp": 0.0, "index_pip": 10.0}},
            {"time": 1.0, "angles": {"index_mcp": 45.0}},
            {"time": 2.0, "angles": {"index_mcp": 30.0, "index_pip": 60.0}, "tension": 0.5},
        ],
    )
    a = kf.angles([0.0, 1.0, 2.0, 3.0])
    np.testing.assert_allclose(a["index_mcp"], [0.0, 45.0, 30.0, 30.0])
    # index_pip has keys at 0 and 2 only: Hermite midpoint with end tangents 50 and
    # (1 - 0.5) * 50: 10/2 + 50/8 + 60/2 - 25/8
    np.testing.assert_allclose(a["index_pip"], [10.0, 38.125, 60.0, 60.0])
    np.testing.assert_array_equal(a["middle_pip"], 0.0)
    assert set(a) == set(skeleton.angle_names)
    assert kf.animated == ["index_mcp", "index_pip"]
    assert kf.pose(1.0)["index_mcp"] == pytest.approx(45.0)


def test_overshoot_is_clamped_and_reported(skeleton):
    # PIP 0..110: keys 100, 110, 100 with bias -1 overshoot the limit after t = 2
    kf2 = Keyframes(
        skeleton,
        [
            {"time": 0.0, "angles": {"index_pip": 0.0}},
            {"time": 1.0, "angles": {"index_pip": 100.0}},
            {"time": 2.0, "angles": {"index_pip": 110.0}},
            {"time": 3.0, "angles": {"index_pip": 100.0}, "bias": -1.0},
        ],
    )
    times = np.linspace(0.0, 3.0, 301)
    raw = kochanek_bartels([0, 1, 2, 3], [0, 100, 110, 100], times, 0, 0, [0, 0, 0, -1])
    assert raw.max() > 110.5  # the spline itself overshoots the limit
    with pytest.warns(RuntimeWarning, match="index_pip at t = .* clamped to its limit 110"):
        a = kf2.angles(times)["index_pip"]
    assert a.max() == 110.0
    over = raw > 110.0
    np.testing.assert_array_equal(a[~over], raw[~over])
    assert len(kf2.clamps) == over.sum()
    assert all(c.angle == "index_pip" and c.limit == 110.0 and c.value > 110 for c in kf2.clamps)


@pytest.mark.parametrize(
    ("keys", "message"),
    [
        (
            [{"time": 0.0, "angles": {"index_pap": 10.0}}],
            r"keyframe 0 \(t = 0\): unknown .*index_pap",
        ),
        (
            [{"time": 0.0, "angles": {}}, {"time": 1.0, "angles": {"index_pip": 120.0}}],
            r"keyframe 1 \(t = 1\): joint angle index_pip = 120 deg is outside its limits "
            r"\[0, 110\]",
        ),
        (
            [{"time": 1.0, "angles": {}}, {"time": 1.0, "angles": {"index_pip": 10.0}}],
            r"keyframe 1 \(t = 1\): key times must increase",
        ),
        ([{"time": 0.0, "angles": {}, "tension": 2.0}], r"keyframe 0 .*tension = 2.0"),
        ([{"time": 0.0, "angles": {}, "speed": 2.0}], r"keyframe 0: unknown key 'speed'"),
        ([], "at least one key"),
    ],
)
def test_bad_keys_name_the_key_and_joint(skeleton, keys, message):
    with pytest.raises(RigError, match=message):
        Keyframes(skeleton, keys)
