"""The shipped hand meshes: flesh tets with bone holes, prescribed nodes, quality."""

from __future__ import annotations

import json

import numpy as np
import pytest
import pyvista as pv

import fem
from contact.geometry.surfaces import check_closed_surface, enclosed_volume, surface_arrays
from contact.hand.autoflex import fingertip_node
from contact.hand.bones import bone_surfaces
from contact.hand.build import COARSE, FINE, FINGERTIPS
from contact.hand.checks import bone_gaps, flesh_thickness
from contact.hand.quality import tet_dihedral_angles
from contact.hand.shipped import HAND_DIR, hand_files, load_hand


@pytest.fixture(scope="module", params=["coarse", "fine", "fingertips"])
def hand(request):
    return load_hand(request.param)


def test_flesh_mesh_is_valid(hand):
    mesh = hand.flesh
    # fem.Mesh validated it on reading (indices, positive Jacobians); read again explicitly
    again = fem.read_mesh(hand_files(hand.resolution)["flesh"])
    assert again.n_points == mesh.n_points and again.n_cells == mesh.n_cells
    # the joints are open: no tet has its four nodes fixed to two bones or more
    b = hand.bone_id[mesh.cells["tetra"]]
    across = (b >= 0).all(axis=1) & (b.min(axis=1) != b.max(axis=1))
    assert not across.any()
    assert list(mesh.cells) == ["tetra"]
    assert (mesh.volumes["tetra"] > 0).all()
    assert set(np.unique(mesh.region_ids)) <= set(range(len(hand.part_names)))
    assert len(np.unique(mesh.region_ids)) == len(hand.part_names)  # every part has flesh
    assert hand.bone_id.shape == (mesh.n_points,)
    assert hand.cell_bone.shape == (mesh.n_cells,)
    if hand.resolution == "coarse":
        assert 2000 < mesh.n_points < 8000


def test_every_bone_has_prescribed_nodes_on_its_surface(hand):
    diag = np.linalg.norm(np.ptp(hand.flesh.points, axis=0))
    for i, name in enumerate(hand.skeleton.bone_names):
        nodes = hand.bone_nodes(name)
        assert len(nodes) >= 20, name
        d = pv.PolyData(hand.flesh.points[nodes]).compute_implicit_distance(hand.bones[name])
        assert np.abs(d["implicit_distance"]).max() < 4e-3 * diag, name
        assert (hand.bone_id[nodes] == i).all()
    # prescribed nodes lie on the boundary (the hole walls), and the skin is free
    boundary = hand.flesh.boundary.nodes
    assert set(hand.prescribed_nodes) <= set(boundary.tolist())
    assert len(hand.prescribed_nodes) < len(boundary)


def test_bones_are_holes(hand):
    """Inward bone surfaces became holes: flesh volume = skin volume - bone volumes."""
    skin = enclosed_volume(*surface_arrays(hand.skin))
    bones = sum(enclosed_volume(*surface_arrays(b)) for b in hand.bones.values())
    # less the joint cavities: the tets tied to both bones of a joint (open_joints, 5 %)
    cavities = skin - bones - hand.flesh.volume
    assert 0.0 < cavities < 0.06 * (skin - bones)
    assert bones > 0.1 * skin


def test_bones_inside_skin_with_flesh_and_apart(hand):
    spec = hand.skeleton.spec
    thick = flesh_thickness(hand.skin, hand.bones)
    assert min(thick.values()) >= spec.min_flesh  # no bone node outside, flesh >= 1.5 mm
    gaps = bone_gaps(hand.bones)
    assert min(gaps.values()) >= spec.gap - 1e-9
    for name, poly in hand.bones.items():
        check_closed_surface(poly, name)


def test_bone_files_match_the_rig(hand):
    res = {"coarse": COARSE, "fine": FINE, "fingertips": FINGERTIPS}[hand.resolution]
    rebuilt = bone_surfaces(hand.skeleton, edge=res.bone_edge)
    for name, poly in hand.bones.items():
        assert poly.n_points == rebuilt[name].n_points
        np.testing.assert_allclose(
            np.sort(poly.points, axis=0), np.sort(rebuilt[name].points, axis=0), atol=1e-9
        )


def test_mesh_quality_and_report(hand):
    dih = tet_dihedral_angles(hand.flesh.points, hand.flesh.cells["tetra"])
    assert dih.min() > 3.0
    report = json.loads((HAND_DIR / "quality.json").read_text())[hand.resolution]
    assert report["flesh"]["n_points"] == hand.flesh.n_points
    assert report["flesh"]["min_dihedral_deg"] == pytest.approx(dih.min(), abs=0.01)


def _tip_edges(hand, finger: str, reach: float = 0.008) -> float:
    """Median skin edge (m) within ``reach`` of a finger's tip node."""
    f = hand.flesh.boundary.faces["triangle"]
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    x = hand.flesh.points
    near = np.linalg.norm(x[e[:, 0]] - x[fingertip_node(hand, finger)], axis=1) < reach
    return float(np.median(np.linalg.norm(x[e[near, 0]] - x[e[near, 1]], axis=1)))


def test_the_fingertips_hand_is_fine_at_the_tips_and_coarse_elsewhere():
    tips, coarse, fine = (load_hand(r) for r in ("fingertips", "coarse", "fine"))
    for finger in ("thumb", "index", "middle", "ring", "little"):
        assert _tip_edges(tips, finger) < 1.2 * FINGERTIPS.tip_edge, finger
        assert _tip_edges(coarse, finger) > 1.4 * _tip_edges(tips, finger), finger
    assert tips.flesh.n_points < 0.6 * fine.flesh.n_points
    # meshed from the fine skin (test_hand_skin checks that one)
    np.testing.assert_array_equal(surface_arrays(tips.skin)[0], surface_arrays(fine.skin)[0])


def test_load_hand_errors(tmp_path):
    with pytest.raises(ValueError, match="unknown hand resolution 'medium'"):
        load_hand("medium")
    (tmp_path / "rig.toml").write_text((HAND_DIR / "rig.toml").read_text())
    with pytest.raises(fem.MeshError, match=r"flesh_coarse\.vtu does not exist"):
        load_hand("coarse", tmp_path)


def test_skin_faces_are_the_closed_outer_skin(hand):
    from contact.geometry.surfacequery import TriangleSurface

    faces = hand.skin_faces
    tri = faces.faces["triangle"]
    surface = TriangleSurface(hand.flesh.points, tri)
    assert surface.is_closed
    # it encloses the whole hand: the skin's volume, not a bone's or a cavity's
    skin = enclosed_volume(*surface_arrays(hand.skin))
    assert surface.volume == pytest.approx(skin, rel=0.02)
    assert (hand.bone_id[tri] < 0).any(axis=1).all()  # no face lies on a bone
    assert faces.n_faces < hand.flesh.boundary.n_faces
