"""STL, OBJ and PLY read and checked: good files as pyvista reads them, bad ones in one line."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from contact.errors import ObjectError
from contact.objects import read_surface

#: A tetrahedron 30 mm on its legs, wound outward.
POINTS = np.array([[0, 0, 0], [0.03, 0, 0], [0, 0.03, 0], [0, 0, 0.03]], np.float64)
TRIANGLES = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], np.int64)


def triangles_of(points: np.ndarray, tri: np.ndarray) -> set[tuple[tuple[float, ...], ...]]:
    """Each triangle as its corners, first at the least corner (numbering left out)."""
    out = set()
    for t in np.asarray(points)[np.asarray(tri)].round(6):
        k = min(range(3), key=lambda i: tuple(t[i]))
        out.add(tuple(tuple(t[(k + i) % 3]) for i in range(3)))
    return out


EXPECTED = triangles_of(POINTS, TRIANGLES)


def ply_header(fmt: str, extra: str = "") -> bytes:
    return (
        f"ply\nformat {fmt} 1.0\ncomment made by hand\nelement vertex 4\nproperty float x\n"
        f"property float y\nproperty float z\n{extra}element face 4\n"
        "property list uchar int vertex_indices\nend_header\n"
    ).encode()


def good_files(tmp_path: Path) -> dict[str, Path]:
    """The tetrahedron in every variant read here."""
    import pyvista as pv

    faces = np.hstack([np.full((4, 1), 3), TRIANGLES]).ravel()
    poly = pv.PolyData(POINTS, faces)
    files = {}
    for name, binary in (("binary.stl", True), ("ascii.stl", False), ("binary.ply", True)):
        poly.save(tmp_path / name, binary=binary)
        files[name] = tmp_path / name
    files["ascii.ply"] = tmp_path / "ascii.ply"
    files["ascii.ply"].write_bytes(
        ply_header("ascii", "property uchar red\n")
        + b"".join(f"{x} {y} {z} 7\n".encode() for x, y, z in POINTS)
        + b"".join(f"3 {a} {b} {c}\n".encode() for a, b, c in TRIANGLES)
    )
    files["big_endian.ply"] = tmp_path / "big_endian.ply"
    files["big_endian.ply"].write_bytes(
        ply_header("binary_big_endian")
        + POINTS.astype(">f4").tobytes()
        + b"".join(b"\x03" + t.astype(">i4").tobytes() for t in TRIANGLES)
    )
    # OBJ: a quad split in two by the reader, slashes, and negative (relative) indices
    files["mixed.obj"] = tmp_path / "mixed.obj"
    files["mixed.obj"].write_text(
        "# tetrahedron\no tet\n"
        + "".join(f"v {x} {y} {z}\n" for x, y, z in POINTS)
        + "vn 0 0 1\nvt 0 0\ns off\n"
        + "f 1/1/1 3/1/1 2/1/1\nf -4//1 -3//1 -1//1\nf 1 4 3\nf -3 -2 -1\n"
    )
    # one vertex with a weight: lines not alike, read line by line
    files["weighted.obj"] = tmp_path / "weighted.obj"
    text = files["mixed.obj"].read_text()
    files["weighted.obj"].write_text(text.replace("v 0.0 0.0 0.0\n", "v 0.0 0.0 0.0 1.0\n"))
    assert text != files["weighted.obj"].read_text()
    return files


def test_good_files_read_as_written(tmp_path: Path) -> None:
    for name, path in good_files(tmp_path).items():
        points, tri = read_surface(path)
        assert triangles_of(points, tri) == EXPECTED, name
        assert len(points) == 4, name  # STL's corners shared, as the other formats give them


BAD = {
    "truncated.stl": "a truncated or damaged binary STL: its header declares 4 triangles "
    "(284 bytes), the file has 200 bytes",
    "negative.obj": "line 6: face index -9 refers to no vertex (4 defined before it; "
    "indices are 1..4, or -1..-4 counting back)",
    "header.ply": "PLY header line 3: 'element vertex' is not 'element <name> <count>'",
    "unended.ply": "a PLY header without 'end_header'",
    "truncated.ply": "a truncated PLY file: 1 of its 4 face rows",
    "index.ply": "face 3 refers to vertex 7: the file has vertices 0..3",
}


def bad_files(tmp_path: Path) -> dict[str, Path]:
    files = good_files(tmp_path)
    data = {
        "truncated.stl": files["binary.stl"].read_bytes()[:200],
        "negative.obj": b"v 0 0 0\nv 0.03 0 0\nv 0 0.03 0\nv 0 0 0.03\nf 1 3 2\nf 1 -9 4\n",
        "header.ply": b"ply\nformat ascii 1.0\nelement vertex\nproperty float x\nend_header\n",
        "unended.ply": b"ply\nformat ascii 1.0\nelement vertex 3\n",
        "truncated.ply": files["binary.ply"].read_bytes()[:-30],
        "index.ply": files["ascii.ply"].read_bytes().replace(b"3 1 2 3\n", b"3 1 2 7\n"),
    }
    out = {}
    for name, content in data.items():
        out[name] = tmp_path / name
        out[name].write_bytes(content)
    return out


@pytest.mark.parametrize("name", sorted(BAD))
def test_a_bad_file_is_one_line_saying_what_is_wrong(tmp_path: Path, name: str) -> None:
    path = bad_files(tmp_path)[name]
    with pytest.raises(ObjectError) as info:
        read_surface(path, where="object[0].mesh")
    assert str(info.value) == f"object[0].mesh = '{path}': {BAD[name]}"


def test_bad_files_reach_the_cli_as_one_line_exit_2(tmp_path: Path) -> None:
    """In a child process: VTK writes to the process's stderr, not to Python's."""
    files = bad_files(tmp_path)
    for name in ("negative.obj", "truncated.stl", "header.ply", "truncated.ply"):
        scene = tmp_path / f"{name}.toml"
        scene.write_text(
            f'[[object]]\nmesh = "{files[name].as_posix()}"\nmesh_size = 0.01\n\n'
            '[[plane]]\nname = "table"\npoint = [0.0, 0.0, -0.05]\nnormal = [0.0, 0.0, 1.0]\n\n'
            f'[frames]\ntimes = [0.0]\n\n[output]\ndirectory = "{(tmp_path / "out").as_posix()}"\n'
        )
    code = (
        "import sys; from contact.grasp import main\n"
        "for s in sys.argv[1:]:\n"
        "    print(main([s, '--quiet']), file=sys.stderr, flush=True)\n"
    )
    scenes = [
        str(tmp_path / f"{n}.toml")
        for n in ("negative.obj", "truncated.stl", "header.ply", "truncated.ply")
    ]
    run = subprocess.run(
        [sys.executable, "-c", code, *scenes],
        capture_output=True,
        text=True,
        timeout=120,
        env={"GRASP_CONTACT_CACHE": "off", "PATH": "/usr/bin:/bin"},
    )
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 8, run.stderr
    for k, name in enumerate(("negative.obj", "truncated.stl", "header.ply", "truncated.ply")):
        assert lines[2 * k].startswith(f"error: {scenes[k]}: object[0].mesh = '")
        assert lines[2 * k].endswith(BAD[name]) and lines[2 * k + 1] == "2"


def test_a_damaged_file_pyvista_reads_is_one_line_and_vtk_says_nothing(tmp_path: Path) -> None:
    """VTK's errors go to the process's stderr: read in a child process."""
    path = tmp_path / "damaged.vtp"
    path.write_text('<?xml version="1.0"?>\n<VTKFile type="PolyData"><PolyData><Piece ')
    code = (
        "import sys\nfrom contact.objects import mesh_object\n"
        "try:\n    mesh_object(sys.argv[1], 0.01)\n"
        "except ValueError as exc:\n    print(exc)\n"
    )
    run = subprocess.run(
        [sys.executable, "-c", code, str(path)], capture_output=True, text=True, timeout=60
    )
    assert run.stderr == ""
    assert run.stdout == (
        f"object.mesh = '{path}': cannot be read: VTK's reader found nothing in it "
        "(an empty or damaged file)\n"
    )
