"""Joint gaps: no free node tied to two bones (contact.hand.jointgap), on a tiny fixture and on
the shipped fine hand; the relaxer stops when it cannot mend and the pose names the
joint and element."""

from __future__ import annotations

import numpy as np
import pytest

import fem
from contact.errors import PoseError
from contact.hand.flesh import joint_pairs
from contact.hand.jointgap import bridging_nodes, gap_edges, split_joint_gaps
from contact.hand.posing import HandPoser
from contact.hand.quality import tet_volumes
from contact.hand.relax import FleshRelaxer
from contact.hand.restarts import maxmin, rigid_motion
from contact.hand.shipped import load_hand
from contact.hand.skeleton import PIVOT_SUFFIX


def _gap_fixture():
    """A free node p in a 1 mm gap between bone 0 (below) and bone 1 (above).

    p (node 0) sits at the origin; bone 0's nodes 1-3 lie 0.5 mm below it, bone 1's nodes
    4-6 0.5 mm above; one tetrahedron on each side, and a third one, on bone 0, that does
    not touch p.
    """
    tri = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 2.0]]) * 1e-3
    below = np.column_stack([tri, np.full(3, -0.5e-3)])
    above = np.column_stack([tri, np.full(3, 0.5e-3)])
    points = np.vstack([[0.3e-3, 0.3e-3, 0.0], below, above, [[0.6e-3, 0.6e-3, -1.5e-3]]])
    tets = np.array([[0, 1, 3, 2], [0, 4, 5, 6], [7, 1, 2, 3]])
    bone_id = np.array([-1, 0, 0, 0, 1, 1, 1, -1])
    return points, tets, bone_id


def test_fixture_is_positive_and_bridges():
    points, tets, bone_id = _gap_fixture()
    assert (tet_volumes(points, tets) > 0).all()
    assert bridging_nodes(tets, bone_id).tolist() == [0]
    # p has three edges to each bone: ties keep bone 0, the edges to bone 1 are split
    assert sorted(map(tuple, gap_edges(tets, bone_id).tolist())) == [(0, 4), (0, 5), (0, 6)]


def test_split_leaves_two_layers_and_keeps_volume_and_orientation():
    points, tets, bone_id = _gap_fixture()
    mesh = fem.Mesh(points, {"tetra": tets}, {"tetra": np.array([3, 4, 5])})
    out, bid, cell_bone = split_joint_gaps(mesh, bone_id, np.array([7, 8, 9]))
    t = out.cells["tetra"]
    assert out.n_points == 8 + 3 and len(t) == 3 + 3  # one tet bisected three times
    vol = tet_volumes(out.points, t)
    assert (vol > 0).all()
    np.testing.assert_allclose(vol.sum(), tet_volumes(points, tets).sum(), rtol=1e-12)
    assert len(bridging_nodes(t, bid)) == 0
    assert bid.tolist() == [*bone_id.tolist(), -1, -1, -1]
    # the middle nodes are the edges' midpoints; the halves keep region and bone
    np.testing.assert_allclose(out.points[8:], 0.5 * (points[0] + points[[4, 5, 6]]))
    assert sorted(out.regions["tetra"].tolist()) == [3, 4, 4, 4, 4, 5]
    assert sorted(cell_bone.tolist()) == [7, 8, 8, 8, 8, 9]
    # the unchanged boundary of bone 0's side, and a second split does nothing
    again = split_joint_gaps(out, bid, cell_bone)
    assert again[0] is out


def test_untouched_without_bridging_nodes():
    points, tets, bone_id = _gap_fixture()
    mesh = fem.Mesh(points, {"tetra": tets[[0, 2]]})
    bid = bone_id.copy()
    out = split_joint_gaps(mesh, bid, np.zeros(2, dtype=np.int64))
    assert out[0] is mesh


def test_relaxer_stops_when_no_position_mends_and_says_so():
    """Bone 1 turned so that its face passes the node's other bone face: no position of
    p keeps both its tetrahedra positive; the relaxer stops once the energy stalls."""
    points, tets, bone_id = _gap_fixture()
    relaxer = FleshRelaxer(points, tets[:2], bone_id >= 0, maxiter=40)
    x = points.copy()
    x[4:7, 2] -= 1.2e-3  # bone 1 sinks 0.2 mm below bone 0's top
    x[0, 2] = 0.0
    y, moved = relaxer.relax(x)
    assert moved == 1
    assert (tet_volumes(y, tets[:2]) <= 0).any()  # cannot be mended
    assert relaxer.stats["stalled"] >= 1
    assert relaxer.stats["iterations"] < 40 * relaxer.stats["passes"]


@pytest.fixture(scope="module")
def fine():
    return load_hand("fine")


def test_fine_hand_has_no_node_tied_to_both_bones_of_a_joint(fine):
    """The shipped fine mesh went through split_joint_gaps: the bridging nodes left lie
    in a tetrahedron with nodes of two bones that no joint joins (neighbouring
    metacarpals)."""
    tets = fine.flesh.cells["tetra"]
    assert len(gap_edges(tets, fine.bone_id)) == 0
    left = bridging_nodes(tets, fine.bone_id)
    print(f"fine hand: {fine.flesh.n_points} nodes, {len(tets)} tets, {len(left)} bridging")
    assert len(left) < 100
    names = fine.skeleton.bone_names
    joints = {tuple(sorted(p)) for p in joint_pairs(fine.skeleton)}
    bones = fine.bone_id
    for node in left:
        ring = np.unique(tets[(tets == node).any(axis=1)])
        pair = tuple(sorted(set(bones[ring][bones[ring] >= 0].tolist())))
        assert pair not in joints, (node, [names[b] for b in pair])


#: Single-joint poses whose JLD mapping left the free node of a joint gap between both
#: bones' faces on the fine hand (no relaxation mends them without the split).
FINE_POSES = [{"index_pip": 82.5}, {"middle_mcp": 67.5}]


def _pose_id(angles: dict[str, float]) -> str:
    return "-".join(f"{k}{v:g}" for k, v in angles.items())


@pytest.mark.parametrize("angles", FINE_POSES, ids=_pose_id)
def test_fine_hand_deep_single_joint_poses_keep_every_tet_positive(fine, angles):
    poser = HandPoser(fine)
    pose = poser.pose(angles)  # raises PoseError naming joint and element otherwise
    assert len(pose.inverted) == 0 and pose.min_quality > 0.0
    assert pose.relaxed > 0


#: Single-joint limits where the relaxer's Newton passes stalled with one split
#: tetrahedron folded over its bone node (the untangling energy alone, five rings of free
#: nodes, kept it inverted): the restart from the bone's rigid motion mends them.
FOLDED_POSES = [{"index_pip": 110.0}, {"ring_pip": 110.0}]


@pytest.mark.parametrize("angles", FOLDED_POSES, ids=_pose_id)
def test_fine_hand_fold_over_a_bone_node_is_mended_by_a_restart(fine, angles):
    poser = HandPoser(fine)
    pose = poser.pose(angles)  # raises PoseError naming joint and element otherwise
    assert pose.min_quality > 0.002
    assert poser.relaxer.stats["restarts"] >= 1 and poser.relaxer.stats["stalled"] >= 1
    # the same relaxer without the bones (no restart) leaves the fold
    tets = fine.flesh.cells["tetra"]
    plain = FleshRelaxer(fine.flesh.points, tets, fine.bone_id >= 0)
    jld = fine.flesh.points + poser.flesh_map.displacement(angles)
    y, _ = plain.relax(jld)
    folded = np.flatnonzero(tet_volumes(y, tets) <= 0)
    assert 1 <= len(folded) <= 3
    # a split tetrahedron: one node on a bone, three free (one of them a split node)
    assert ((fine.bone_id[tets[folded]] >= 0).sum(axis=1) == 1).all()


def _random_full_limits_pose(limits: dict, seed: int, index: int) -> dict[str, float]:
    """Pose ``index`` of the random full-limits poses of benchmarks.posing.sample_range."""
    rng = np.random.default_rng(seed)
    poses = [{k: rng.uniform(lo, hi) for k, (lo, hi) in limits.items()} for _ in range(index + 1)]
    return poses[index]


@pytest.mark.slow
def test_fine_hand_fold_of_a_split_tetrahedron_is_mended(fine):
    """A random full-limits pose (seed 7, the 23rd: wrist 69 deg, index MCP 85 deg with
    15 deg pivot, little PIP 105 deg) folds the index MCP's split tetrahedron 88404 (one
    node on the index proximal phalanx, three free). The pose comes out with nothing
    inverted. The fallback's step
    alone, maximising the least ``J`` around the tetrahedron's free nodes and one ring
    from the mapped points, turns it positive, where the summed penalty of the restarts'
    untangling left its ``J`` about -0.002 (its neighbours are left to the passes)."""
    angles = _random_full_limits_pose(fine.skeleton.limits, 7, 22)
    assert angles["index_mcp"] == pytest.approx(84.9, abs=0.05)
    poser = HandPoser(fine)
    pose = poser.pose(angles)  # raises PoseError naming joint and element otherwise
    assert len(pose.inverted) == 0 and pose.min_quality > 1e-3
    tets = fine.flesh.cells["tetra"]
    jld = fine.flesh.points + poser.flesh_map.displacement(angles)
    assert tet_volumes(jld, tets[[88404]])[0] < 0.0
    assert (fine.bone_id[tets[88404]] >= 0).sum() == 1
    relaxer = poser.relaxer
    free = relaxer.mesh.ring(tets[88404], 1)
    free = free[~relaxer.fixed[free]]
    x = jld.copy()
    maxmin(relaxer.mesh, x, free)
    assert tet_volumes(x, tets[[88404]])[0] > 0.0


def test_rigid_motion_of_a_bone_is_recovered_from_its_nodes(fine):
    """The restart's rigid motion (a least-squares fit to the bone's nodes) is the bone's
    transform to round-off."""
    poser = HandPoser(fine, relax=False)
    pose = poser.pose({"index_mcp": 40.0, "index_pip": 70.0, "wrist": 30.0}, check=False)
    relaxer = FleshRelaxer(
        fine.flesh.points, fine.flesh.cells["tetra"], fine.bone_id >= 0, bone_id=fine.bone_id
    )
    names = fine.skeleton.bone_names
    for name in ("index_middle", "carpus"):
        rot, shift = rigid_motion(relaxer.mesh, pose.points, names.index(name))
        t = pose.transforms[name]
        np.testing.assert_allclose(rot, t[:3, :3], atol=1e-12)
        np.testing.assert_allclose(shift, t[:3, 3], atol=1e-14)
    with pytest.raises(ValueError, match="bone_id"):
        FleshRelaxer(fine.flesh.points, fine.flesh.cells["tetra"], fine.bone_id >= 0, bone_id=[0])


def test_pose_error_names_joint_and_element_of_what_is_left(fine):
    """Without the relaxer the JLD mapping inverts the fine hand's index MCP at 90 deg;
    the error names the joint and the element, and lists them all."""
    poser = HandPoser(fine, relax=False)
    with pytest.raises(PoseError) as info:
        poser.pose({"index_mcp": 90.0})
    exc = info.value
    assert exc.joint == "index_mcp" and f"element {exc.element}" in str(exc)
    assert exc.element in exc.elements and len(exc.elements) > 1
    assert PIVOT_SUFFIX not in exc.joint


@pytest.mark.slow
@pytest.mark.parametrize("fraction", [0.75, 1.0])
def test_fine_hand_over_the_limits_keeps_every_tet_positive(fine, fraction):
    """The posing benchmark's poses at 0.75 and at the full limits (every angle alone at
    each limit, 40 random poses) leave no tetrahedron inverted (minutes in all)."""
    from benchmarks.posing import sample_range

    row = sample_range(HandPoser(fine), fraction, 40)
    print(
        f"fine hand at {fraction} of the limits: {row['inverted_poses']}/{row['poses']} "
        f"inverted, min quality {row['min_quality']:.4f}, {row['mean_s']:.2f} s a pose (max "
        f"{row['max_s']:.2f})"
    )
    assert row["inverted_poses"] == 0, row["unmended"]
    assert row["min_quality"] > 1e-3
