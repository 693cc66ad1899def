"""An object's mesh file read, checked and filled: surfaces, volume meshes, bad files."""

from __future__ import annotations

import math
from pathlib import Path

import meshio
import numpy as np
import pytest

import fem
from contact.errors import ObjectError
from contact.geometry.triangles import surface_of_mesh
from contact.objects import mesh_object
from meshes.objects.make import OBJECTS_DIR, cube_surface

EDGE = 0.04


def write(path: Path, points, triangles) -> Path:
    meshio.write_points_cells(path, np.asarray(points), [("triangle", np.asarray(triangles))])
    return path


@pytest.fixture(scope="module")
def filled_cube(tmp_path_factory) -> tuple[Path, fem.Mesh]:
    path = write(tmp_path_factory.mktemp("cube") / "cube.stl", *cube_surface(EDGE, EDGE))
    return path, mesh_object(path, 0.01, where="object[1].mesh")


def test_cube_filled(filled_cube):
    _, mesh = filled_cube
    assert set(mesh.cells) == {"tetra"}
    assert mesh.volume == pytest.approx(EDGE**3, rel=0.01)
    assert np.ptp(mesh.points, axis=0) == pytest.approx([EDGE] * 3, rel=1e-6)


def test_cylinder_filled(tmp_path):
    import pyvista as pv

    r, h = 0.026, 0.10
    cyl = pv.Cylinder(radius=r, height=h, direction=(0, 0, 1), resolution=32).triangulate()
    path = tmp_path / "cyl.stl"
    cyl.save(path, binary=True)
    mesh = mesh_object(path, 0.01, optimize=False)  # fTetWild's quick pass: a fast test
    assert mesh.volume == pytest.approx(math.pi * r**2 * h, rel=0.01)


def test_volume_mesh_used_as_it_is(filled_cube, tmp_path):
    _, mesh = filled_cube
    path = tmp_path / "cube.vtu"
    fem.write_mesh(path, mesh)
    again = mesh_object(path, 0.5)  # mesh_size ignored: used as it is
    assert again.n_cells == mesh.n_cells
    np.testing.assert_allclose(again.points, mesh.points)
    assert again.volume == pytest.approx(mesh.volume, rel=1e-12)
    tri = surface_of_mesh(again)[1]
    assert len(tri) == mesh.boundary.n_faces


def test_volume_mesh_with_an_inverted_tet(tmp_path):
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], float) * 0.02
    cells = [("tetra", np.array([[0, 1, 2, 3], [1, 3, 2, 4]]))]  # the second inverted
    path = tmp_path / "bad.vtu"
    meshio.write_points_cells(path, p, cells)
    with pytest.raises(ObjectError, match=r"^object\.mesh = '.*bad\.vtu': tetra element 1 is "):
        mesh_object(path)


def test_volume_mesh_boundary_checked(tmp_path):
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], float) * 40.0
    path = tmp_path / "mm.vtu"
    meshio.write_points_cells(path, p, [("tetra", np.array([[0, 1, 2, 3], [1, 2, 3, 4]]))])
    with pytest.raises(ObjectError, match="across: in millimetres"):
        mesh_object(path)


def test_missing_unreadable_and_empty_files(tmp_path):
    with pytest.raises(ObjectError, match=r"^object\[2\]\.mesh = '.*nope\.stl': no such file$"):
        mesh_object(tmp_path / "nope.stl", where="object[2].mesh")
    junk = tmp_path / "junk.stl"
    junk.write_bytes(b"\x00\x01 not a mesh")
    with pytest.raises(ObjectError, match=r"junk\.stl': not an STL file: 13 bytes") as info:
        mesh_object(junk)
    assert "\n" not in str(info.value)
    with pytest.raises(ObjectError, match="not a file"):
        mesh_object(tmp_path)
    lines = tmp_path / "lines.vtk"
    meshio.write_points_cells(lines, np.eye(3), [("line", np.array([[0, 1], [1, 2]]))])
    with pytest.raises(ObjectError, match="neither volume cells nor a triangle surface"):
        mesh_object(lines)


@pytest.mark.parametrize("size", [0.0, -1.0, float("nan")])
def test_bad_mesh_size(tmp_path, size):
    with pytest.raises(ObjectError, match=r"^object\.mesh_size = .*: must be a positive length"):
        mesh_object(tmp_path / "x.stl", size)


def test_bad_surface_refused_before_filling(tmp_path):
    p, t = cube_surface(EDGE, EDGE)
    with pytest.raises(ObjectError, match="the surface is open"):
        mesh_object(write(tmp_path / "open.obj", p, t[1:]))


def test_a_fill_too_fine_for_the_machine_is_refused_before_it_runs(monkeypatch):
    from contact.scene import sizing

    monkeypatch.setattr(sizing, "available_memory", lambda: 2e9)
    path = OBJECTS_DIR / "cube.stl"
    with pytest.raises(ObjectError) as info:
        mesh_object(path, 1e-4, where="object[0].mesh")
    msg = str(info.value)
    assert msg.startswith(f"object[0].mesh = '{path}': too fine at mesh_size 0.0001 m: about ")
    assert "give a larger mesh_size" in msg and "\n" not in msg
