"""Posing the hand: the API the contact solver uses, no inverted tetrahedra over the tested
range of motion, inversion errors that name the joint and the element, and pictures."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

import fem
from contact.errors import PoseError, RigError
from contact.hand.keyframes import Keyframes
from contact.hand.posing import HandPoser, Pose, pose_hand
from contact.hand.quality import tet_quality, tet_volumes
from contact.hand.relax import FleshRelaxer
from contact.hand.relax_reference import eigen_gradients, eigenvectors, isotropic_eigen
from contact.hand.relaxmesh import cofactor
from contact.hand.restarts import RELAX_UNTANGLE, maxmin
from contact.hand.shipped import load_hand
from contact.hand.skeleton import PIVOT_SUFFIX

#: Fraction of the joint limits of the quick random poses.
SAFE = 0.5
#: The power grasp's range (degrees): caps on the rig's limits (the full limits are the
#: slow full-range test's).
GRASP_CAPS = {"_pip": 95.0, "_dip": 70.0, "wrist": 45.0}
#: Single-joint limits the coarse mesh cannot take: none. (A free node trapped between
#: the two bones of a joint, with tetrahedra on both, can make one; a PoseError names it.)
UNREACHABLE: set[tuple[str, float]] = set()


def grasp_limits(limits: dict[str, tuple[float, float]]) -> dict[str, tuple[float, float]]:
    """The rig's limits capped to the power grasp's range (:data:`GRASP_CAPS`)."""
    out = {}
    for name, (lo, hi) in limits.items():
        for key, cap in GRASP_CAPS.items():
            if (name.endswith(key) and not name.startswith("thumb")) or name.startswith(key):
                lo, hi = max(lo, -cap), min(hi, cap)
        out[name] = (lo, hi)
    return out


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


def _random_poses(poser, limits, n, seed=2024):
    rng = np.random.default_rng(seed)
    worst, relaxed = np.inf, 0
    for _ in range(n):
        angles = {k: rng.uniform(lo, hi) for k, (lo, hi) in limits.items()}
        pose = poser.pose(angles)  # raises PoseError on an inverted tetrahedron
        assert len(pose.inverted) == 0
        worst = min(worst, pose.min_quality)
        relaxed += pose.relaxed > 0
    return worst, relaxed


def test_100_random_poses_leave_every_tet_positive(hand, poser):
    """Every angle uniform within half its limits."""
    limits = {k: (SAFE * lo, SAFE * hi) for k, (lo, hi) in hand.skeleton.limits.items()}
    worst, relaxed = _random_poses(poser, limits, 100)
    rest = tet_quality(hand.flesh.points, hand.flesh.cells["tetra"]).min()
    print(
        f"100 random poses at {SAFE} of the limits: min tet quality {worst:.4f} "
        f"(rest {rest:.4f}), {relaxed} relaxed"
    )
    assert worst > 0.0


@pytest.mark.slow
def test_100_random_poses_over_the_full_limits_leave_every_tet_positive(hand, poser):
    """Every angle uniform over its whole range (fingers fully flexed or hyperextended,
    thumb opposed, wrist bent and deviated at once): about a second a pose."""
    worst, relaxed = _random_poses(poser, hand.skeleton.limits, 100)
    print(f"100 random poses over the full limits: min tet quality {worst:.4f}, {relaxed} relaxed")
    assert worst > 0.0


@pytest.mark.slow
def test_100_random_grasp_poses_leave_every_tet_positive(hand, poser):
    """Every angle uniform over the power grasp's range (full limits, PIP <= 95, DIP <= 70,
    wrist +-45): fingers fully flexed, thumb opposed, wrist bent (under a minute)."""
    worst, relaxed = _random_poses(poser, grasp_limits(hand.skeleton.limits), 100)
    print(f"100 random poses over the grasp range: min tet quality {worst:.4f}, {relaxed} relaxed")
    assert worst > 0.0


def test_each_limit_poses_or_names_its_joint_and_element(hand, poser):
    """Every angle alone at each of its limits poses (the power grasp's caps too), but
    the documented :data:`UNREACHABLE` ones, whose error names the joint and element."""
    failed, worst = [], np.inf
    caps = grasp_limits(hand.skeleton.limits)
    for name, (lo, hi) in hand.skeleton.limits.items():
        joint = name.removesuffix(PIVOT_SUFFIX)
        for limit in {lo, hi, *caps[name]} - {0.0}:
            try:
                worst = min(worst, poser.pose({name: limit}).min_quality)
            except PoseError as exc:
                failed.append((name, limit))
                assert exc.joint == joint, (name, str(exc))
                assert f"element {exc.element}" in str(exc) and joint in str(exc)
                pose = poser.pose({name: limit}, check=False)
                assert exc.element in pose.inverted and len(pose.inverted) == len(exc.elements)
                assert (
                    tet_quality(pose.points, hand.flesh.cells["tetra"][[exc.element]]) <= 0
                ).all()
    print(f"single-joint limits: min tet quality {worst:.4f}, unreachable {sorted(failed)}")
    assert set(failed) <= UNREACHABLE and worst > 0.0


def test_error_names_the_joint_and_the_element(hand):
    jld_only = HandPoser(hand, relax=False)  # the JLD mapping alone folds a deep flexion
    with pytest.raises(PoseError, match=r"element \d+ \(nodes \[.*\]\), at joint middle_pip"):
        jld_only.pose({"middle_pip": 110.0})


def test_relaxer_leaves_fair_poses_alone_and_untangles(hand, poser):
    """The JLD mapping alone inverts a deep flexion; the relaxer makes it positive, moving
    only free nodes; a mild pose is the JLD mapping itself."""
    jld_only = HandPoser(hand, relax=False)
    angles = {"index_mcp": 90.0, "index_pip": 90.0}
    assert len(jld_only.pose(angles, check=False).inverted) > 0
    pose = poser.pose(angles)
    assert pose.relaxed > 0 and pose.min_quality > 0.0
    fixed = hand.bone_id >= 0
    np.testing.assert_array_equal(
        pose.points[fixed], jld_only.pose(angles, check=False).points[fixed]
    )
    mild = {"index_mcp": 10.0}
    assert poser.pose(mild).relaxed == 0
    assert np.array_equal(poser.pose(mild).points, jld_only.pose(mild).points)


def test_max_min_untangling_lifts_the_least_volume_to_its_target():
    """The restart's fallback (contact.hand.restarts.maxmin) moves the free node of a flipped
    tetrahedron until its ``J`` reaches RELAX_UNTANGLE, the fixed nodes held."""
    rest = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.2, 0.2, 1.0]]) * 1e-3
    tets = np.array([[0, 1, 2, 3]])
    fixed = np.array([True, True, True, False])
    relaxer = FleshRelaxer(rest, tets, fixed, bone_id=np.array([0, 0, 0, -1]))
    x = rest.copy()
    x[3, 2] = -0.5e-3  # through the fixed face: J = -0.5
    maxmin(relaxer.mesh, x, np.array([3]))
    j = tet_volumes(x, tets)[0] / tet_volumes(rest, tets)[0]
    assert j == pytest.approx(RELAX_UNTANGLE, abs=1e-6)
    np.testing.assert_array_equal(x[:3], rest[:3])


def test_sequence_to_png_frames_and_gif(hand, poser, tmp_path):
    pv = pytest.importorskip("pyvista")
    pv.OFF_SCREEN = True
    from PIL import Image

    from contact.hand.animation import render_sequence

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


#: Levi-Civita symbol; ``d^2 det F / dF_ij dF_kl = sum_mn _HDET[ij, kl, mn] F_mn``.
_LEVI = np.zeros((3, 3, 3))
_LEVI[0, 1, 2] = _LEVI[1, 2, 0] = _LEVI[2, 0, 1] = 1.0
_LEVI[0, 2, 1] = _LEVI[2, 1, 0] = _LEVI[1, 0, 2] = -1.0
_HDET = np.einsum("ikm,jln->ijklmn", _LEVI, _LEVI).reshape(81, 9)


def test_isotropic_eigensystem_projects_as_a_9x9_eigensolver():
    """The analytic eigensystem is the 9 x 9 Hessian's, and projects it as eigh does.

    Its vectors' gradients in a tetrahedron's nodes are ``B^T q`` (``vec F = B vec x``).
    """
    rng = np.random.default_rng(0)
    f = rng.normal(size=(400, 3, 3))
    f[:5] = np.eye(3)  # repeated singular values
    f[5:10] = np.diag([1.0, 1.0, -0.5])  # inverted
    f[10:15] = np.diag([1e-9, 1.0, 2.0])  # flat
    f[15:20] = -np.eye(3)
    fv, gv = f.reshape(-1, 9), cofactor(f).reshape(-1, 9)
    a, cb = rng.uniform(0.1, 1.0, 400), rng.normal(size=400)
    cj, c = rng.uniform(0.0, 5.0, 400), rng.normal(size=400)
    hf = (2.0 * cb)[:, None, None] * fv[:, :, None] * gv[:, None, :]
    hf += hf.transpose(0, 2, 1)
    hf += cj[:, None, None] * gv[:, :, None] * gv[:, None, :]
    hf += c[:, None, None] * (fv @ _HDET.T).reshape(-1, 9, 9)
    hf += a[:, None, None] * np.eye(9)
    w, v = np.linalg.eigh(hf)
    assert (w < 0.0).any(axis=1).sum() > 100  # most need projecting
    expect = (v * np.maximum(w, 1e-8 * a[:, None])[:, None, :]) @ v.transpose(0, 2, 1)
    u, vt, ev, wq = isotropic_eigen(f, a, cb, cj, c)
    q = eigenvectors(u, vt, ev)
    scale = np.abs(hf).max()
    np.testing.assert_allclose(
        q.transpose(0, 2, 1) @ q, np.broadcast_to(np.eye(9), q.shape), atol=1e-12
    )
    np.testing.assert_allclose(hf @ q, q * wq[:, None, :], rtol=0.0, atol=1e-11 * scale)
    np.testing.assert_allclose(np.sort(wq, axis=1), w, rtol=0.0, atol=1e-11 * scale)
    got = (q * np.maximum(wq, 1e-8 * a[:, None])[:, None, :]) @ q.transpose(0, 2, 1)
    np.testing.assert_allclose(got, expect, rtol=0.0, atol=1e-11 * scale)
    # F = X^T D: B[3 i + j, 3 n + i] = D[n, j]
    dmat = rng.normal(size=(400, 4, 3))
    b = np.zeros((400, 3, 3, 4, 3))
    for i in range(3):
        b[:, i, :, :, i] = dmat.transpose(0, 2, 1)
    expect_g = b.reshape(400, 9, 12).transpose(0, 2, 1) @ q
    np.testing.assert_allclose(eigen_gradients(u, vt, ev, dmat), expect_g, atol=1e-13)


def test_harmonic_fill_reproduces_an_affine_displacement(hand, poser):
    """The fill's P1 harmonic extension is exact on an affine field: scrambled inner free
    nodes among nodes displaced by ``u = A x + b`` go back onto it (on the skin the fill
    has a free surface: no such identity there)."""
    relaxer = poser.relaxer
    rest = hand.flesh.points
    a = np.array([[0.10, -0.20, 0.05], [0.15, 0.02, -0.10], [-0.05, 0.10, 0.20]])
    b = np.array([0.01, -0.02, 0.005])
    x = rest + rest @ a.T + b
    inner = np.ones(len(rest), dtype=bool)
    inner[hand.flesh.boundary.nodes] = False
    inner &= hand.bone_id < 0
    core = relaxer.mesh.ring(np.flatnonzero(inner)[:1], 2)
    core = core[inner[core]]
    assert len(core) > 10
    exact = x[core].copy()
    x[core] += np.random.default_rng(3).normal(scale=0.003, size=(len(core), 3))
    relaxer.mesh.fill(x, core)
    np.testing.assert_allclose(x[core], exact, rtol=0.0, atol=1e-12)


def test_first_pass_rings_bound_the_moved_nodes(hand):
    """The first pass moves the free nodes within ``pass_rings`` rings of the degraded
    tetrahedra: one ring moves fewer than two, and both leave every tetrahedron positive."""
    jld = HandPoser(hand, relax=False).pose({"index_mcp": 90.0, "index_pip": 90.0}, check=False)
    moved = []
    for rings in (1, 2):
        relaxer = FleshRelaxer(
            hand.flesh.points,
            hand.flesh.cells["tetra"],
            hand.bone_id >= 0,
            bone_id=hand.bone_id,
            pass_rings=rings,
        )
        _, n, q = relaxer.relax_quality(jld.points)
        assert q.min() > 0.0 and relaxer.stats["passes"] == 1
        moved.append(n)
    assert 0 < moved[0] < moved[1]


def test_warm_start_keeps_the_mapping_where_it_is_fair(hand, poser):
    """A warm start only offers a start to the parts the mapping degrades: from a deep
    pose, the rest pose is still the rest mesh exactly and a mild pose the mapping itself;
    a deep pose keeps its bones where the cold one puts them, with every tet positive."""
    deep = {"wrist": 60.0, "index_mcp": 85.0, "index_pip": 95.0, "middle_mcp": 85.0}
    cold = poser.pose(deep)
    assert cold.relaxed > 0 and cold.correction is not None
    mapped = hand.flesh.points + poser.flesh_map.displacement(cold.angles)
    np.testing.assert_array_equal(cold.correction, cold.points - mapped)
    rest = poser.pose({}, start=cold)
    assert np.array_equal(rest.points, hand.flesh.points) and rest.relaxed == 0
    mild = {"index_mcp": 10.0}
    assert np.array_equal(poser.pose(mild, start=cold).points, poser.pose(mild).points)
    near = {k: 0.97 * v for k, v in deep.items()}
    warm = poser.pose(near, start=cold)
    fixed = hand.bone_id >= 0
    np.testing.assert_array_equal(warm.points[fixed], poser.pose(near).points[fixed])
    assert warm.min_quality > 0.0
    # the correction is what the relaxer moved: zero on every node it left alone
    moved = np.flatnonzero(np.abs(warm.correction).sum(axis=1) > 0)
    assert 0 < len(moved) <= warm.relaxed
    assert not fixed[moved].any()
    other = dataclasses.replace(cold, correction=cold.correction[:-1])
    with pytest.raises(ValueError, match=r"another mesh \(\d+ nodes; this hand's flesh has"):
        poser.pose(near, start=other)


def test_warm_start_turns_the_correction_with_its_segment(hand, poser):
    """The previous frame's correction is carried by each node's segment: turned by the
    segment's rotation between the two poses, unchanged where the segment did not turn,
    its length kept."""
    deep = {"wrist": 60.0, "index_mcp": 85.0, "index_pip": 95.0, "middle_mcp": 85.0}
    cold = poser.pose(deep)
    near = dict(deep, index_pip=80.0, wrist=55.0)
    tf = hand.skeleton.forward_kinematics(hand.skeleton.check_angles(near))
    carried = poser._carried(cold, tf)
    c = cold.correction
    np.testing.assert_allclose(np.linalg.norm(carried, axis=1), np.linalg.norm(c, axis=1))
    names = poser.flesh_map.topology.names
    seg = poser.flesh_map.segment
    on = np.abs(c).sum(axis=1) > 0
    turned = 0
    for b, name in enumerate(names):
        nodes = np.flatnonzero((seg == b) & on)
        if not len(nodes):
            continue
        rot = tf[name][:3, :3] @ cold.transforms[name][:3, :3].T
        np.testing.assert_allclose(carried[nodes], c[nodes] @ rot.T, atol=1e-15)
        if np.abs(rot - np.eye(3)).max() > 1e-3:  # a segment the change of pose turned
            turned += 1
            assert np.abs(carried[nodes] - c[nodes]).max() > 1e-2 * np.abs(c[nodes]).max()
    assert turned >= 2  # the wrist's and the index's at least
    # the same pose: the correction as it is
    np.testing.assert_allclose(poser._carried(cold, cold.transforms), c, atol=1e-15)


def _sequence_steps(poser, poses, warm):
    steps, worst, previous = 0, np.inf, None
    for angles in poses:
        pose = poser.pose(angles, start=previous if warm else None)
        steps += poser.relaxer.stats["iterations"]
        worst = min(worst, pose.min_quality)
        previous = pose
    return steps, worst


def test_warm_started_sequence_takes_fewer_newton_steps_on_the_fine_hand():
    """Frames of a keyframed sequence (24 a second) near three quarters of the limits:
    started from the previous frame, the relaxer takes fewer Newton steps for as good a
    worst tetrahedron."""
    fine = HandPoser(load_hand("fine"))
    lim = fine.hand.skeleton.limits
    rng = np.random.default_rng(5)
    a0 = {n: rng.uniform(0.75 * lo, 0.75 * hi) for n, (lo, hi) in lim.items()}
    a1 = {n: rng.uniform(0.75 * lo, 0.75 * hi) for n, (lo, hi) in lim.items()}
    poses = [{n: a0[n] + s * (a1[n] - a0[n]) / 24.0 for n in lim} for s in range(5)]
    cold, q_cold = _sequence_steps(fine, poses, warm=False)
    warm, q_warm = _sequence_steps(fine, poses, warm=True)
    print(f"5 frames: cold {cold} Newton steps (min quality {q_cold:.4f}), warm {warm}")
    assert warm < 0.7 * cold
    assert q_warm >= 0.9 * q_cold > 0.0


def test_a_warm_start_is_mended_around_its_degraded_tetrahedra_alone(hand, poser):
    """A warm start that the frame's motion leaves fair but for a tetrahedron turned over is
    mended by Newton's method on the free nodes within ``rings`` rings of it: the rest of
    the part keeps the warm start exactly (fewer than half the nodes the cold relaxation
    of the pose moves), and the worst quality is the cold one's."""
    relaxer = poser.relaxer
    jld = HandPoser(hand, relax=False).pose({"index_mcp": 90.0, "index_pip": 90.0}, check=False)
    cold, _, q_cold = relaxer.relax_quality(jld.points)
    moved_cold = np.flatnonzero(np.abs(cold - jld.points).sum(axis=1) > 0)
    inner = np.ones(len(cold), dtype=bool)
    inner[hand.flesh.boundary.nodes] = False
    inner &= hand.bone_id < 0
    node = moved_cold[inner[moved_cold]][0]
    # the node pushed through the face opposite it in one of its tetrahedra
    tet = relaxer.tets[np.flatnonzero((relaxer.tets == node).any(axis=1))[0]]
    a, b, c = cold[tet[tet != node]]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n)
    warm = cold.copy()
    warm[node] -= 1.5 * np.dot(warm[node] - a, n) * n
    q_warm = tet_quality(warm, relaxer.tets)
    assert (q_warm <= 0.0).sum() >= 1
    x, _, q = relaxer.relax_quality(jld.points, warm=warm)
    assert relaxer.stats["mended"] == 1 and relaxer.stats["polished"] == 0
    assert q.min() > 0.0 and q.min() >= 0.99 * q_cold.min()
    moved = np.flatnonzero(np.abs(x - warm).sum(axis=1) > 0)
    low = np.flatnonzero(q_warm < relaxer._floor)
    ring = relaxer.mesh.ring(np.unique(relaxer.tets[low]), relaxer.rings)
    assert node in moved and np.isin(moved, ring).all()
    assert len(moved) < 0.5 * len(moved_cold)


def test_warm_frames_keep_the_cold_frames_quality_at_a_quarter_of_the_limits():
    """A sequence near rest (a quarter of the limits, 24 frames a second): the warm frames'
    worst tetrahedron is the cold frames' (a warm start mended wherever it was below the
    mapping's energy carried stale corrections: 0.010 where the fill gave 0.030)."""
    from benchmarks.posing import sequence_keys

    fine = HandPoser(load_hand("fine"))
    sk = fine.hand.skeleton
    frames = Keyframes(sk, sequence_keys(sk.limits, 0.25, np.random.default_rng(0)))
    with warnings.catch_warnings():  # the spline's overshoots, clamped
        warnings.simplefilter("ignore", RuntimeWarning)
        poses = [frames.pose(t) for t in np.arange(20, 45) / 24]
    cold = min(fine.pose(a, check=False).min_quality for a in poses)
    warm, previous = np.inf, None
    for a in poses:
        previous = fine.pose(a, check=False, start=previous)
        warm = min(warm, previous.min_quality)
    assert warm >= 0.95 * cold > 0.02


def test_newton_patience_stops_a_run_that_finds_no_better_iterate(monkeypatch):
    """A run whose worst tetrahedron stays inverted at the same quality finds no better
    iterate (fewer inverted, then a better worst quality): with ``patience`` it stops
    after that many steps; without, it goes on until its energy stalls. Either way it
    keeps the best iterate: its start. (The worst tetrahedron is held at -0.1 by a
    stand-in for the qualities.)"""
    from contact.hand import relaxkernels
    mesh = fem.box_mesh((1.0, 1.0, 1.0), (3, 3, 3), element="tetra")
    pts = mesh.points
    fixed = np.any((pts <= 1e-12) | (pts >= 1.0 - 1e-12), axis=1)
    free = np.flatnonzero(~fixed)
    x = pts.copy()
    x[free] += 0.05 * np.random.default_rng(0).standard_normal((len(free), 3))
    real = relaxkernels.volumes_quality

    def held_worst(y, tets):
        vols, q = real(y, tets)
        q = q.copy()
        q[0] = -0.1
        return vols, q

    monkeypatch.setattr(relaxkernels, "volumes_quality", held_worst)
    steps = {}
    for patience in (0, 2):
        relaxer = FleshRelaxer(pts, mesh.cells["tetra"], fixed)
        relaxer.stats = dict.fromkeys(("iterations", "stalled"), 0)
        y = x.copy()
        relaxer._newton(y, free, patience)
        steps[patience] = relaxer.stats["iterations"]
        np.testing.assert_array_equal(y, x)
    assert steps[2] == 2 < steps[0], steps
