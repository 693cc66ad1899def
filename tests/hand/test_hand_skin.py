"""The skin: metaballs, blend groups, surface checks, and the shipped skin surfaces."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import fem
from contact.geometry.surfaces import (
    check_closed_surface,
    count_pieces,
    enclosed_volume,
    poly_from_arrays,
    self_intersections,
    surface_arrays,
)
from contact.hand.metaballs import field_on_grid, field_threshold, skin_surface
from contact.hand.shipped import hand_files
from contact.hand.skeleton import load_skeleton

TINY = """
[rig]
name = "tiny"
length_unit = "m"
angle_unit = "deg"

[flesh]
gap = 0.001
min_thickness = 0.001

[joints.knuckle]
parent = "root"
position = [0.0, 0.0, 0.0]
flexion_axis = [-1.0, 0.0, 0.0]
flexion = [0.0, 90.0]

[bones.stick]
joint = "knuckle"
part = "palm"
end = [0.0, 0.04, 0.0]
base = [0.004, 0.003, 0.004]
shaft = [0.003, 0.003]
head = [0.004, 0.003, 0.004]

[skin]
reach = 1.6
base_group = "palm"
groups = ["palm", "a", "b"]

[[skin.primitives]]
joint = "knuckle"
group = "GA"
center = [-0.0108, 0.02, 0.0]
radii = [0.01, 0.02, 0.01]
weight = 1.0

[[skin.primitives]]
joint = "knuckle"
group = "GB"
center = [0.0108, 0.02, 0.0]
radii = [0.01, 0.02, 0.01]
weight = 1.0
"""


def tiny(tmp_path, ga="a", gb="b"):
    path = tmp_path / "tiny.toml"
    path.write_text(TINY.replace("GA", ga).replace("GB", gb))
    return load_skeleton(path)


def test_lone_primitive_is_its_ellipsoid(tmp_path):
    sk = tiny(tmp_path)
    grid = field_on_grid(sk, spacing=0.0005)
    level = field_threshold(sk.spec.reach)
    v = grid.point_data["field"]
    # the centre of primitive a and a point on its surface along x, away from b
    for point, expected in (((-0.0108, 0.02, 0.0), 1.0), ((-0.0208, 0.02, 0.0), level)):
        i = grid.find_closest_point(point)
        assert v[i] == pytest.approx(expected, rel=1e-6)


def test_groups_do_not_blend_but_one_group_does(tmp_path):
    # two ellipsoids 1.6 mm apart: in different groups they stay apart (max of fields),
    # in the same group their fields add and they fuse into one piece
    sk = tiny(tmp_path)
    grid = field_on_grid(sk, spacing=0.0005)
    poly = grid.contour([field_threshold(sk.spec.reach)], scalars="field")
    pts, tri = surface_arrays(poly.clean())
    assert count_pieces(len(pts), tri) == 2
    fused = skin_surface(tiny(tmp_path, "a", "a"), resolution=0.0005)
    assert fused.n_cells > 0  # checked: closed, manifold, one piece
    with_palm = skin_surface(tiny(tmp_path, "a", "palm"), resolution=0.0005)  # blends with base
    assert with_palm.volume == pytest.approx(fused.volume, rel=1e-3)


def test_skin_in_two_pieces_is_an_error(tmp_path):
    with pytest.raises(fem.MeshError, match="2 separate pieces"):
        skin_surface(tiny(tmp_path), resolution=0.0005)


def test_self_intersection_detector():
    p1, t1 = fem.sphere_surface(1.0, refinement=2)
    assert len(self_intersections(p1, t1)) == 0
    p2, t2 = fem.sphere_surface(1.0, center=(1.2, 0, 0), refinement=2)
    pts, tri = np.vstack([p1, p2]), np.vstack([t1, t2 + len(p1)])
    assert len(self_intersections(pts, tri)) > 0
    with pytest.raises(fem.MeshError, match="triangles intersect"):
        check_closed_surface(poly_from_arrays(pts, tri), "two spheres")
    with pytest.raises(fem.MeshError, match="face inward"):
        check_closed_surface(poly_from_arrays(p1, t1[:, ::-1]), "inside out")
    with pytest.raises(fem.MeshError, match="open edge"):
        check_closed_surface(poly_from_arrays(p1, t1[1:]), "open")


@pytest.mark.parametrize("resolution", ["coarse", "fine"])
def test_shipped_skin(resolution):
    """Closed, manifold, outward, one piece, no self-intersection; volume and size of an
    adult hand: 350-365 cm^3 with a 5 cm wrist stub, 18.5-19.2 cm from the wrist crease
    (y = 0) to the middle fingertip, 11-13 cm across with the thumb, 4.5-5.5 cm thick."""
    import pyvista as pv

    skin = pv.read(hand_files(resolution)["skin"])
    check_closed_surface(skin, f"{resolution} skin")
    pts, tri = surface_arrays(skin)
    assert 340e-6 < enclosed_volume(pts, tri) < 370e-6
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    assert 0.185 < hi[1] < 0.192
    assert 0.11 < hi[0] - lo[0] < 0.13
    assert 0.045 < hi[2] - lo[2] < 0.055
    assert -0.06 < lo[1] < -0.04


def test_rig_skin_matches_shipped_coarse():
    sk = load_skeleton(Path(hand_files("coarse")["rig"]))
    skin = skin_surface(sk, resolution=0.002, check_self_intersections=False)
    import pyvista as pv

    shipped = pv.read(hand_files("coarse")["skin"])
    assert skin.volume == pytest.approx(shipped.volume, rel=0.03)
