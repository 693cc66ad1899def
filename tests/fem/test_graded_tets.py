"""Tests of the graded tetrahedral octant (fTetWild under a sizing field)."""

from __future__ import annotations

import numpy as np
import pytest

import fem
from fem.graded_tets import graded_octant_surface, graded_tet_octant, octant_sizing_field

R = 1.0
C = np.array([0.0, 0.0, R])


def test_surface_is_closed_on_sphere_and_planes():
    pts, tri = graded_octant_surface(R, 0.05, 0.2, center=C)
    fem.check_surface(pts, tri)
    d = pts - C
    on_plane = (np.abs(d) <= 1e-12).any(axis=1)
    on_sphere = np.abs(np.linalg.norm(d, axis=1) - R) <= 1e-12
    assert (on_plane | on_sphere).all()
    assert (d[:, :2] >= -1e-12).all() and (d[:, 2] <= 1e-12).all()


def test_sizing_field_covers_octant_and_grades():
    pts, tets, h = octant_sizing_field(R, 0.02, 0.2, center=C)
    assert tets.shape[1] == 4 and h.shape == (len(pts),)
    assert h.min() == pytest.approx(0.02) and h.max() == pytest.approx(R / 5)
    pole = np.linalg.norm(pts, axis=1)  # the pole is the origin
    assert np.allclose(h[pole <= 0.2], 0.02) and (h[pole > 1.0] > 0.2 * R - 1e-12).all()
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    assert (lo < C - np.array([0, 0, R])).all() and (hi > C + np.array([R, R, 0])).all()


def test_a_layered_sizing_field_is_fine_on_the_sphere_and_grows_with_depth():
    from fem.graded_tets import _size_at

    pole = C - np.array([0.0, 0.0, R])
    below = pole + np.array([[0.0, 0.0, t] for t in (0.0, 0.1, 0.3)])  # straight inwards
    h = _size_at(below, C, R, 0.01, 0.2, R / 5, 1.3, depth_growth=1.5)
    assert h == pytest.approx([0.01, 0.01 + 0.5 * 0.1, 0.01 + 0.5 * 0.3])
    # on the sphere: fine within 0.2 of the pole, growing by 0.3 per unit beyond
    ang = np.array([0.1, 0.5])
    on = C + R * np.column_stack([np.sin(ang), 0 * ang, -np.cos(ang)])
    chord = 2 * R * np.sin(ang / 2)
    want = 0.01 + 0.3 * np.maximum(chord - 0.2, 0.0)
    assert _size_at(on, C, R, 0.01, 0.2, R / 5, 1.3, depth_growth=1.5) == pytest.approx(want)
    # the solid zone of old: the same point below the pole is fine within 0.2
    assert _size_at(below, C, R, 0.01, 0.2, R / 5, 1.3)[:2] == pytest.approx([0.01, 0.01])
    with pytest.raises(fem.MeshError, match="depth_growth"):
        graded_tet_octant(R, 0.05, 0.2, depth_growth=1.0)
    with pytest.raises(fem.MeshError, match="surface_size"):
        graded_tet_octant(R, 0.05, 0.2, surface_size=0.01)


def test_bad_sizes_raise():
    with pytest.raises(fem.MeshError):
        graded_tet_octant(R, 0.0, 0.2)
    with pytest.raises(fem.MeshError):
        graded_tet_octant(R, 0.05, 0.2, growth=1.0)


@pytest.mark.slow
def test_graded_tet_octant_is_exact_on_its_boundary_and_finer_at_the_pole():
    mesh = graded_tet_octant(R, 0.04, 0.2, center=C)
    assert set(mesh.cells) == {"tetra"}
    assert mesh.volume == pytest.approx(np.pi / 6, rel=0.02)
    nodes = np.unique(mesh.boundary.faces["triangle"])
    d = mesh.points[nodes] - C
    on_plane = (d == 0.0).any(axis=1)
    on_sphere = np.abs(np.linalg.norm(d, axis=1) - R) <= 1e-12
    assert (on_plane | on_sphere).all()
    x = mesh.points[mesh.cells["tetra"]]
    edge = np.linalg.norm(x[:, 1] - x[:, 0], axis=1)
    dist = np.linalg.norm(x.mean(axis=1), axis=1)
    assert np.median(edge[dist < 0.15]) < 0.5 * np.median(edge[dist > 0.6])


def test_a_sliver_snapping_flattened_on_the_boundary_is_dropped():
    """A tetrahedron whose four boundary nodes snapped into one plane fills nothing: it is
    dropped (its neighbours close the boundary); one with an interior node is not."""
    from fem.errors import MeshError
    from fem.graded_tets import _without_flat

    box = fem.box_mesh((1.0, 1.0, 1.0), (2, 2, 2), element="tetra")
    tets = box.cells["tetra"]
    boundary = np.zeros(box.n_points, dtype=bool)
    boundary[np.unique(box.boundary.faces["triangle"])] = True
    flat = np.flatnonzero(box.points[:, 2] == 0.0)[:4]  # on the face z = 0: coplanar
    mesh = _without_flat(box.points, np.vstack([tets, flat]), boundary)
    assert np.array_equal(mesh.cells["tetra"], tets) and mesh.n_points == box.n_points
    assert mesh.volumes["tetra"].sum() == pytest.approx(1.0, rel=1e-12)
    # turned by round-off: the same sliver, one node 1e-9 through the others' plane
    pts = box.points.copy()
    pts[flat[3], 2] = -1e-9
    x = pts[flat]
    if np.cross(x[1] - x[0], x[2] - x[0]) @ (x[3] - x[0]) > 0:
        flat = flat[[1, 0, 2, 3]]
    turned = _without_flat(pts, np.vstack([tets, flat]), boundary)
    assert np.array_equal(turned.cells["tetra"], tets)
    centre = int(np.argmin(np.linalg.norm(box.points - 0.5, axis=1)))  # interior
    flat_inside = [centre, *np.flatnonzero(box.points[:, 2] == 0.5)[:3]]  # z = 0.5 plane
    with pytest.raises(MeshError, match="degenerate"):
        _without_flat(box.points, np.vstack([tets, flat_inside]), boundary)


def test_a_snap_that_would_turn_a_cell_with_an_inner_node_is_taken_back():
    """Four tetrahedra about an inner node just inside a boundary node outside the sphere:
    snapping that node onto the sphere would pass the inner node and turn cells;
    it stays where it was, the other boundary nodes are snapped."""
    from fem.graded_tets import _snapped
    from fem.mesh import tet_volumes6 as _volumes

    ways = ([0.3, 0.3, -0.9], [0.5, 0.1, -0.9], [0.1, 0.5, -0.9], [0.45, 0.45, -0.6])
    unit = [np.asarray(v, float) / np.linalg.norm(v) for v in ways]
    corners = np.array([1.005 * unit[0], *(unit[1:])])
    corners[1:] *= 1.0 + np.array([1e-4, -1e-4, 2e-4])[:, None]  # near the sphere
    inner = corners[0] + 0.002 * (corners.mean(axis=0) - corners[0])
    pts = np.vstack([corners, inner])
    faces = ([1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1])
    tets = np.array([[*f, 4] for f in faces])
    tets[_volumes(pts, tets) < 0] = tets[_volumes(pts, tets) < 0][:, [1, 0, 2, 3]]
    assert (_volumes(pts, tets) > 0).all()
    snapped = pts.copy()
    snapped[:4] /= np.linalg.norm(snapped[:4], axis=1)[:, None]
    assert (_volumes(snapped, tets) < 0).sum() >= 2  # a plain snap turns cells
    out = _snapped(fem.Mesh(pts, {"tetra": tets}), 1.0, np.zeros(3), 1e-9)
    r = np.linalg.norm(out.points, axis=1)
    assert r[0] == 1.005 and np.allclose(r[1:4], 1.0, rtol=0, atol=1e-15)
    assert (_volumes(out.points, out.cells["tetra"]) > 0).all()
