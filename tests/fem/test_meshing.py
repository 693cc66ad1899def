"""Surface checks and tetrahedral meshing with pytetwild (non-deterministic: tolerances)."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest
import pytetwild
import pyvista as pv

import fem

R = 1.0


def _signed_volumes(mesh: fem.Mesh) -> np.ndarray:
    x = mesh.points[mesh.cells["tetra"]]
    return (
        np.einsum("ij,ij->i", np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), x[:, 3] - x[:, 0])
        / 6.0
    )


def test_sphere_surface_is_closed_and_outward():
    pts, tri = fem.sphere_surface(2.0, center=(1.0, 2.0, 3.0), refinement=2)
    fem.check_surface(pts, tri)
    assert len(tri) == 320
    assert np.allclose(np.linalg.norm(pts - [1.0, 2.0, 3.0], axis=1), 2.0)
    x = pts[tri] - [1.0, 2.0, 3.0]
    enclosed = np.einsum("ij,ij->i", x[:, 0], np.cross(x[:, 1], x[:, 2])).sum() / 6.0
    assert 0.95 * 4 / 3 * math.pi * 8 < enclosed < 4 / 3 * math.pi * 8


def test_open_surface_names_open_edges():
    pts, tri = fem.sphere_surface(R, refinement=1)
    a, b, c = tri[0].tolist()
    with pytest.raises(fem.MeshError, match="not closed: 3 open edge") as info:
        fem.check_surface(pts, tri[1:])
    for i, j in ((a, b), (b, c), (a, c)):
        assert f"({min(i, j)}, {max(i, j)})" in str(info.value)


def test_many_open_edges_are_counted_and_listed_up_to_ten():
    pts, tri = fem.sphere_surface(R, refinement=1)
    with pytest.raises(fem.MeshError, match=r"open edge.*\(\d+ more\)") as info:
        fem.check_surface(pts, tri[: len(tri) // 2])
    assert str(info.value).count("), (") == 9


def test_non_manifold_edge_is_named():
    pts, tri = fem.sphere_surface(R, refinement=1)
    a, b, _ = tri[0].tolist()
    pts = np.concatenate([pts, [[3.0, 0.0, 0.0]]])
    fin = np.array([[a, b, len(pts) - 1], [b, a, len(pts) - 1]])  # a flap on edge (a, b)
    with pytest.raises(fem.MeshError, match="non-manifold: 1 edge") as info:
        fem.check_surface(pts, np.concatenate([tri, fin]))
    assert f"({min(a, b)}, {max(a, b)}) in 4 triangles" in str(info.value)


def test_flipped_triangle_is_named():
    pts, tri = fem.sphere_surface(R, refinement=1)
    bad = tri.copy()
    bad[7] = bad[7, ::-1]
    with pytest.raises(fem.MeshError, match="inconsistently oriented: 3 edge") as info:
        fem.check_surface(pts, bad)
    a, b, c = bad[7].tolist()
    assert any(f"({i}, {j})" in str(info.value) for i, j in ((a, b), (b, c), (c, a)))


def test_bad_arrays_are_rejected():
    pts, tri = fem.sphere_surface(R, refinement=1)
    with pytest.raises(fem.MeshError, match="outside"):
        fem.check_surface(pts, np.concatenate([tri, [[0, 1, len(pts)]]]))
    with pytest.raises(fem.MeshError, match="repeat a node"):
        fem.check_surface(pts, np.concatenate([tri, [[0, 1, 1]]]))
    with pytest.raises(fem.MeshError, match="shape"):
        fem.check_surface(pts[:, :2], tri)
    with pytest.raises(fem.MeshError, match=r"surf\.stl: bad surface"):
        fem.check_surface(pts, tri[1:], source="surf.stl")


def test_tetrahedralize_rejects_bad_surface_before_meshing(monkeypatch):
    def boom(*args, **kwargs):
        raise AssertionError("pytetwild must not be called")

    monkeypatch.setattr(pytetwild, "tetrahedralize", boom)
    pts, tri = fem.sphere_surface(R, refinement=1)
    with pytest.raises(fem.MeshError, match="not closed"):
        fem.tetrahedralize((pts, tri[1:]), R / 3)
    with pytest.raises(fem.MeshError, match="edge_length"):
        fem.tetrahedralize((pts, tri), 0.0)


def test_solid_sphere():
    pts, tri = fem.sphere_surface(R, refinement=3)
    mesh = fem.tetrahedralize((pts, tri), R / 3)
    assert list(mesh.cells) == ["tetra"]
    assert (_signed_volumes(mesh) > 0).all()
    assert mesh.volume == pytest.approx(4 / 3 * math.pi * R**3, rel=0.03)
    assert mesh.used_points.all()
    assert np.linalg.norm(mesh.points, axis=1).max() < R * 1.01
    assert (mesh.regions["tetra"] == 0).all()


def test_hollow_sphere_from_inward_inner_surface():
    r = 0.5 * R
    po, to = fem.sphere_surface(R, refinement=3)
    pi, ti = fem.sphere_surface(r, refinement=3)
    surface = pv.PolyData.from_regular_faces(
        np.concatenate([po, pi]), np.concatenate([to, ti[:, ::-1] + len(po)])
    )
    mesh = fem.tetrahedralize(surface, R / 4)
    assert (_signed_volumes(mesh) > 0).all()
    assert mesh.volume == pytest.approx(4 / 3 * math.pi * (R**3 - r**3), rel=0.03)
    centroids = mesh.points[mesh.cells["tetra"]].mean(axis=1)
    assert np.linalg.norm(centroids, axis=1).min() > 0.9 * r  # nothing inside the hole


def test_surface_from_file(tmp_path):
    pts, tri = fem.sphere_surface(R, refinement=2)
    path = tmp_path / "ball.stl"
    pv.PolyData.from_regular_faces(pts, tri).save(path)
    mesh = fem.tetrahedralize(path, R / 2, optimize=False)
    assert mesh.volume == pytest.approx(4 / 3 * math.pi * R**3, rel=0.06)
    with pytest.raises(fem.MeshError, match=r"nothere\.stl does not exist"):
        fem.tetrahedralize(tmp_path / "nothere.stl", R / 2)
    open_path = tmp_path / "open.stl"
    pv.PolyData.from_regular_faces(pts, tri[1:]).save(open_path)
    with pytest.raises(fem.MeshError, match=r"open\.stl: bad surface, not closed"):
        fem.tetrahedralize(open_path, R / 2)


def test_pytetwild_failure_and_empty_result(monkeypatch):
    pts, tri = fem.sphere_surface(R, refinement=1)

    def fail(*args, **kwargs):
        raise RuntimeError("envelope exploded")

    monkeypatch.setattr(pytetwild, "tetrahedralize", fail)
    with pytest.raises(fem.MeshError, match=r"pytetwild failed.*envelope exploded"):
        fem.tetrahedralize((pts, tri), R / 3)
    empty = (np.zeros((0, 3)), np.zeros((0, 4), dtype=np.int32))
    monkeypatch.setattr(pytetwild, "tetrahedralize", lambda *a, **k: empty)
    with pytest.raises(fem.MeshError, match="no tetrahedra"):
        fem.tetrahedralize((pts, tri), R / 3)


def test_orientation_slivers_and_unused_points(monkeypatch):
    box = fem.box_mesh(divisions=(1, 1, 1), element="tetra")
    tets = box.cells["tetra"].copy()
    tets[::2] = tets[::2][:, [1, 0, 2, 3]]  # both orientations, as fTetWild may emit
    pts = np.concatenate([box.points, [[0.5, 0.0, 0.0], [7.0, 7.0, 7.0]]])
    sliver = [[0, 1, 8, 2]]  # nodes 0, 1 and the new node 8 are collinear
    out = (pts, np.concatenate([tets, sliver]).astype(np.int32))
    monkeypatch.setattr(pytetwild, "tetrahedralize", lambda *a, **k: out)
    pts_s, tri_s = fem.sphere_surface(R, refinement=1)
    with pytest.warns(UserWarning, match="dropped 1 zero-volume sliver"):
        mesh = fem.tetrahedralize((pts_s, tri_s), R / 3)
    assert mesh.n_cells == len(tets)
    assert mesh.n_points == box.n_points
    assert (_signed_volumes(mesh) > 0).all()
    assert mesh.volume == pytest.approx(1.0)


def test_no_warning_without_slivers(monkeypatch):
    box = fem.box_mesh(divisions=(1, 1, 1), element="tetra")
    out = (box.points, box.cells["tetra"][:, [0, 2, 1, 3]].astype(np.int32))
    monkeypatch.setattr(pytetwild, "tetrahedralize", lambda *a, **k: out)
    pts, tri = fem.sphere_surface(R, refinement=1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mesh = fem.tetrahedralize((pts, tri), R / 3)
    assert mesh.volume == pytest.approx(1.0)


def test_sizing_field_is_passed_to_pytetwild(monkeypatch):
    seen = {}
    box = fem.box_mesh(divisions=(1, 1, 1), element="tetra")

    def fake(vertices, faces, **kwargs):
        seen.update(kwargs)
        return box.points, box.cells["tetra"].astype(np.int32)

    monkeypatch.setattr(pytetwild, "tetrahedralize", fake)
    grid = fem.to_pyvista(box)
    grid.point_data["h"] = np.full(box.n_points, 0.1)
    grid.point_data.active_scalars_name = "h"
    grid.cell_data.remove("region")
    pts, tri = fem.sphere_surface(R, refinement=1)
    fem.tetrahedralize((pts, tri), R / 3, sizing_field=grid)
    assert seen["edge_length_abs"] == R / 3
    assert np.allclose(seen["bg_values"], 0.1)
    assert seen["bg_tets"].shape == (6, 4)
    with pytest.raises(fem.MeshError, match="sizing_field"):
        fem.tetrahedralize((pts, tri), R / 3, sizing_field=42)


@pytest.mark.slow
def test_sizing_field_refines_locally():
    pts, tri = fem.sphere_surface(R, refinement=3)
    bg = pv.ImageData(dimensions=(5, 5, 5), spacing=(0.6,) * 3, origin=(-1.2,) * 3)
    bg = bg.to_tetrahedra().clean()
    bg.point_data["h"] = np.where(bg.points[:, 0] > 0, R / 8, R / 3)
    bg.point_data.active_scalars_name = "h"
    mesh = fem.tetrahedralize((pts, tri), R / 3, sizing_field=bg)
    x = mesh.points[mesh.cells["tetra"]].mean(axis=1)[:, 0]
    assert (x > 0).sum() > 2 * (x < 0).sum()


def test_tetrahedralize_leaves_no_file_behind(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    fem.tetrahedralize(fem.sphere_surface(1.0, refinement=2), 0.5, optimize=False)
    assert list(tmp_path.iterdir()) == []
    assert Path.cwd() == tmp_path


def test_tetwild_options_pass_through():
    surf = fem.sphere_surface(1.0, refinement=2)
    m = fem.tetrahedralize(surf, 0.5, epsilon=2e-3, num_opt_iter=5, stop_energy=20.0)
    assert m.volume == pytest.approx(4 / 3 * math.pi, rel=0.1)
    with pytest.raises(fem.MeshError, match="pytetwild failed"):
        fem.tetrahedralize(surf, 0.5, no_such_option=1)
