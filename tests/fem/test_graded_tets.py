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
