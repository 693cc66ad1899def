"""The checks of a user's object surface: each bad mesh refused with its one-line message."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import meshio
import numpy as np
import pytest

from contact.errors import ObjectError
from contact.geometry import enclosed_volume
from contact.objects import MAX_EXTENT, check_object_surface, read_surface
from meshes.objects.make import OBJECTS_DIR, can_surface, cube_surface


def cube(edge: float = 0.04, center=(0.0, 0.0, 0.0), size: float | None = None):
    p, t = cube_surface(edge, size or edge)
    return p + np.asarray(center), t


def join(*surfaces):
    pts, tris, off = [], [], 0
    for p, t in surfaces:
        pts.append(p)
        tris.append(t + off)
        off += len(p)
    return np.concatenate(pts), np.concatenate(tris)


def write(path: Path, points, triangles) -> Path:
    meshio.write_points_cells(path, np.asarray(points), [("triangle", np.asarray(triangles))])
    return path


def check_file(path: Path, where: str = "object[1].mesh"):
    return check_object_surface(*read_surface(path, where=where), path, where=where)


def refused(path: Path, where: str = "object[1].mesh") -> str:
    with pytest.raises(ObjectError) as info:
        check_file(path, where)
    msg = str(info.value)
    assert msg.startswith(f"{where} = '{path}': ")
    assert "\n" not in msg
    return msg


def test_shipped_objects_pass_and_face_out():
    for name, volume in (("can", math.pi * 0.026**2 * 0.10), ("cube", 0.04**3)):
        path = OBJECTS_DIR / f"{name}.stl"
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            p, t = check_file(path)
        assert enclosed_volume(p, t) == pytest.approx(volume, rel=0.01)
        assert np.ptp(p, axis=0) == pytest.approx(
            [0.052, 0.052, 0.10] if name == "can" else [0.04] * 3, rel=1e-3
        )
    p, t = can_surface()
    x = p[t]
    edges = np.linalg.norm(x - np.roll(x, 1, axis=1), axis=2)
    assert 0.0035 < edges.mean() < 0.0045


def test_open_box(tmp_path):
    p, t = cube()
    msg = refused(write(tmp_path / "open.stl", p, t[2:]))
    assert "the surface is open: 4 edge(s) used by one triangle only" in msg
    assert "e.g. the edge from (" in msg and "closed surface" in msg


def test_two_cubes_sharing_an_edge(tmp_path):
    msg = refused(write(tmp_path / "edge.obj", *join(cube(), cube(center=(0.04, 0.04, 0.0)))))
    assert "not manifold: 1 edge(s) shared by more than two triangles" in msg
    assert "the edge from (0.02, 0.02, -0.02) to (0.02, 0.02, 0.02) in 4 triangles" in msg


def test_one_triangle_wound_the_other_way(tmp_path):
    p, t = cube()
    t[5] = t[5, ::-1]
    msg = refused(write(tmp_path / "wound.ply", p, t))
    assert "inconsistently oriented: 3 edge(s) traversed twice the same way" in msg


def test_inverted_cube_warns_and_flips(tmp_path):
    p, t = cube(size=0.01)
    path = write(tmp_path / "inside_out.stl", p, t[:, ::-1])
    with pytest.warns(UserWarning, match=r"the surface is wound inward .*flipped to face out"):
        q, s = check_file(path)
    assert enclosed_volume(q, s) == pytest.approx(0.04**3, rel=1e-6)


def test_cavity_kept_and_lone_inverted_piece_flipped():
    outer, inner = cube(), cube(edge=0.02)
    hollow = join(outer, (inner[0], inner[1][:, ::-1]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        p, t = check_object_surface(*hollow, "hollow.stl")
    assert enclosed_volume(p, t) == pytest.approx(0.04**3 - 0.02**3)
    apart = join(cube(), (cube(center=(0.1, 0, 0))[0], cube()[1][:, ::-1]))
    with pytest.warns(UserWarning, match="1 of its 2 pieces are wound inward"):
        p, t = check_object_surface(*apart, "apart.stl")
    assert enclosed_volume(p, t) == pytest.approx(2 * 0.04**3)


def test_interpenetrating_cubes(tmp_path):
    msg = refused(write(tmp_path / "two.stl", *join(cube(), cube(center=(0.01, 0.01, 0.01)))))
    assert "the surface intersects itself:" in msg and "pair(s) of triangles intersect" in msg
    assert "e.g. triangle" in msg and " near (" in msg


def test_sliver_triangle(tmp_path):
    p, t = cube()
    a, b, c = t[0]
    m = len(p)
    p = np.vstack([p, 0.5 * (p[a] + p[b])])
    t = np.vstack([t[1:], [[a, m, c], [m, b, c], [a, b, m]]])  # (a, b, m) has no area
    msg = refused(write(tmp_path / "sliver.ply", p, t))
    assert "1 degenerate triangle(s)" in msg and "first: triangle 13 with corners" in msg


def test_repeated_node():
    p, t = cube()
    t = np.vstack([t, [[0, 0, 1]]])
    with pytest.raises(ObjectError, match="repeated node"):
        check_object_surface(p, t, "x.stl")


def test_cube_in_millimetres(tmp_path):
    msg = refused(write(tmp_path / "mm.stl", *cube(edge=40.0)), where="object.mesh")
    assert "the object is 40 m across: in millimetres? the scene is in metres; scale it by " in msg
    assert msg.endswith("scale it by 0.001")


@pytest.mark.parametrize(
    ("edge", "words"),
    [
        (4.0, "in centimetres? the scene is in metres; scale it by 0.01"),
        (4000.0, "far larger than a hand"),
        (4e-5, "too small to grasp (at least 0.001 m; a hand is 0.19 m long); in kilometres?"),
    ],
)
def test_other_sizes(edge, words):
    with pytest.raises(ObjectError) as info:
        check_object_surface(*cube(edge=edge), "x.stl")
    assert words in str(info.value)
    assert edge > MAX_EXTENT or edge < 1e-3


def test_duplicate_and_unused_points_cleaned():
    p, t = cube()
    x = p[t].reshape(-1, 3)  # every corner repeated, as in an STL file
    t = np.arange(len(x)).reshape(-1, 3)
    q, s = check_object_surface(np.vstack([x, [[9.0, 9.0, 9.0]]]), t, "x")
    assert len(q) == 8 and len(s) == 12


def test_a_surface_only_pyvista_reads(tmp_path):
    import pyvista as pv

    path = tmp_path / "ball.vtp"
    pv.Sphere(radius=0.03).save(path)
    p, t = check_file(path)
    assert enclosed_volume(p, t) == pytest.approx(4 / 3 * math.pi * 0.03**3, rel=0.02)
