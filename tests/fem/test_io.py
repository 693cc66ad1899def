"""Mesh IO through meshio and conversion to and from pyvista."""

from __future__ import annotations

import numpy as np
import pytest
import pyvista as pv

import fem
from fem import io as fem_io


def _mixed_mesh() -> fem.Mesh:
    """Hexahedra and wedges side by side (not conforming; fine for IO)."""
    hexes = fem.box_mesh((1.0, 1.0, 1.0), (2, 1, 1))
    wedges = fem.box_mesh((1.0, 1.0, 1.0), (1, 2, 1), origin=(2.0, 0.0, 0.0), element="wedge")
    pts = np.concatenate([hexes.points, wedges.points])
    cells = {
        "hexahedron": hexes.cells["hexahedron"],
        "wedge": wedges.cells["wedge"] + hexes.n_points,
    }
    return fem.Mesh(pts, cells, {"hexahedron": [1, 2], "wedge": [3, 3, 4, 4]})


def _meshes() -> dict[str, fem.Mesh]:
    out = {}
    for kind in ("tetra", "hexahedron", "wedge"):
        m = fem.box_mesh((1.0, 2.0, 0.5), (2, 2, 1), element=kind)
        regions = {kind: np.arange(m.n_cells) % 3 + 7}
        out[kind] = fem.Mesh(m.points * [1.0, 1.1, 0.9] + 0.123, m.cells, regions)
    out["mixed"] = _mixed_mesh()
    return out


@pytest.mark.parametrize("name", ["tetra", "hexahedron", "wedge", "mixed"])
def test_vtu_round_trip(tmp_path, name):
    mesh = _meshes()[name]
    rng = np.random.default_rng(1)
    u = rng.normal(size=(mesh.n_points, 3))
    t = rng.normal(size=mesh.n_points)
    flat = rng.normal(size=(mesh.n_cells, 6))
    per_type = {k: np.arange(len(c), dtype=np.int32) for k, c in mesh.cells.items()}
    path = tmp_path / "m.vtu"
    fem.write_mesh(path, mesh, {"u": u, "t": t}, {"stress": flat, "n": per_type})
    back, pdata, cdata = fem.read_mesh_data(path)
    assert np.array_equal(back.points, mesh.points)
    assert list(back.cells) == list(mesh.cells)
    for k in mesh.cells:
        assert np.array_equal(back.cells[k], mesh.cells[k])
        assert np.array_equal(back.regions[k], mesh.regions[k])
        assert np.array_equal(cdata["n"][k], per_type[k])
    assert np.array_equal(pdata["u"], u)
    assert np.array_equal(pdata["t"], t)
    assert np.array_equal(np.concatenate([cdata["stress"][k] for k in mesh.cells]), flat)
    assert "region" not in cdata
    assert fem.read_mesh(path).n_cells == mesh.n_cells
    assert [p.name for p in tmp_path.iterdir()] == ["m.vtu"]


def test_vtu_wedges_have_positive_volume_in_vtk(tmp_path):
    mesh = _meshes()["wedge"]
    fem.write_mesh(tmp_path / "w.vtu", mesh)
    grid = pv.read(tmp_path / "w.vtu")
    vol = grid.compute_cell_sizes().cell_data["Volume"]
    assert np.allclose(vol, mesh.volumes["wedge"])
    assert (vol > 0).all()
    # the file holds our connectivity as is
    assert np.array_equal(grid.cells_dict[pv.CellType.WEDGE], mesh.cells["wedge"])


@pytest.mark.parametrize(("name", "kind"), [("m.vtk", "mixed"), ("m.msh", "wedge")])
def test_legacy_vtk_and_gmsh_round_trip(tmp_path, name, kind):
    mesh = _meshes()[kind]
    fem.write_mesh(tmp_path / name, mesh)
    back = fem.read_mesh(tmp_path / name)
    for k in mesh.cells:
        assert np.array_equal(back.cells[k], mesh.cells[k])
        assert np.array_equal(back.regions[k], mesh.regions[k])
    assert np.allclose(back.points, mesh.points)


@pytest.mark.parametrize("name", ["tetra", "hexahedron", "wedge", "mixed"])
def test_pyvista_round_trip_and_positive_volumes(name):
    mesh = _meshes()[name]
    u = np.arange(mesh.n_points * 3.0).reshape(-1, 3)
    grid = fem.to_pyvista(mesh, {"u": u}, {"id": np.arange(mesh.n_cells)})
    vol = grid.compute_cell_sizes().cell_data["Volume"]
    assert (vol > 0).all()
    assert np.allclose(vol, np.concatenate([mesh.volumes[k] for k in mesh.cells]))
    assert np.array_equal(grid.point_data["u"], u)
    back = fem.from_pyvista(grid)
    assert np.array_equal(back.points, mesh.points)
    for k in mesh.cells:
        assert np.array_equal(back.cells[k], mesh.cells[k])
        assert np.array_equal(back.regions[k], mesh.regions[k])


def test_from_pyvista_drops_surface_cells_and_unused_points():
    mesh = _meshes()["tetra"]
    pts = np.concatenate([mesh.points, [[9.0, 9.0, 9.0]]])
    tets = mesh.cells["tetra"]
    cells = np.concatenate(
        [np.hstack([np.full((len(tets), 1), 4), tets]).ravel(), [3, 0, 1, len(pts) - 1]]
    )
    types = np.concatenate([np.full(len(tets), pv.CellType.TETRA), [pv.CellType.TRIANGLE]])
    grid = pv.UnstructuredGrid(cells, types.astype(np.uint8), pts)
    back = fem.from_pyvista(grid)
    assert back.n_points == mesh.n_points
    assert np.array_equal(back.cells["tetra"], tets)


def test_from_pyvista_without_volume_cells():
    with pytest.raises(fem.MeshError, match=r"no volume cells.*TRIANGLE"):
        fem.from_pyvista(pv.Sphere())


def test_read_keeps_volume_cells_renumbers_and_uses_fallback_region_name(tmp_path):
    mesh = _meshes()["hexahedron"]
    hexes = mesh.cells["hexahedron"]
    pts = np.concatenate([[[5.0, 5.0, 5.0]], mesh.points])  # unused point first
    cells = np.concatenate(
        [[3, 0, 1, 2], np.hstack([np.full((len(hexes), 1), 8), hexes + 1]).ravel()]
    )
    types = np.concatenate([[pv.CellType.TRIANGLE], np.full(len(hexes), pv.CellType.HEXAHEDRON)])
    grid = pv.UnstructuredGrid(cells, types.astype(np.uint8), pts)
    grid.cell_data["CellEntityIds"] = np.concatenate([[99], mesh.regions["hexahedron"]])
    grid.save(tmp_path / "g.vtu")
    back = fem.read_mesh(tmp_path / "g.vtu")
    assert list(back.cells) == ["hexahedron"]
    assert np.array_equal(back.points, mesh.points)
    assert np.array_equal(back.cells["hexahedron"], hexes)
    assert np.array_equal(back.regions["hexahedron"], mesh.regions["hexahedron"])


def test_read_errors_name_the_file(tmp_path):
    missing = tmp_path / "missing.vtu"
    with pytest.raises(fem.MeshError, match=r"missing\.vtu does not exist"):
        fem.read_mesh(missing)
    unknown = tmp_path / "m.unknownext"
    unknown.write_text("hello")
    with pytest.raises(fem.MeshError, match=r"m\.unknownext: unknown format"):
        fem.read_mesh(unknown)
    garbage = tmp_path / "garbage.vtu"
    garbage.write_text("this is not XML")
    with pytest.raises(fem.MeshError, match=r"cannot read mesh file .*garbage\.vtu") as info:
        fem.read_mesh(garbage)
    err = info.value  # no chained meshio traceback
    assert err.__cause__ is None and (err.__context__ is None or err.__suppress_context__)
    surface = tmp_path / "surface.vtu"
    pv.Sphere().cast_to_unstructured_grid().save(surface)
    with pytest.raises(
        fem.NoVolumeCellsError, match=r"surface\.vtu has no volume cells.*triangle"
    ) as no:
        fem.read_mesh(surface)
    assert no.value.surface and no.value.cell_types == ("triangle",)
    with pytest.raises(fem.MeshError, match="is not a file"):
        fem.read_mesh(tmp_path)


def test_read_tangled_cells_names_the_file(tmp_path):
    mesh = _meshes()["tetra"]
    grid = fem.to_pyvista(mesh)
    tets = mesh.cells["tetra"].copy()
    tets[1] = tets[1][[0, 2, 1, 3]]  # one cell of many wound the other way: tangled
    bad = pv.UnstructuredGrid({pv.CellType.TETRA: tets}, grid.points)
    bad.save(tmp_path / "inv.vtu")
    with pytest.raises(fem.MeshError, match=r"inv\.vtu: tetra element 1 is inverted"):
        fem.read_mesh(tmp_path / "inv.vtu")


@pytest.mark.parametrize("kind", ["tetra", "hexahedron", "wedge"])
def test_cells_wound_the_other_way_throughout_are_reordered(tmp_path, kind, caplog):
    import meshio

    mesh = _meshes()[kind]
    mirrored = mesh.cells[kind][:, fem_io._MIRROR[kind]]
    path = tmp_path / "mirrored.msh"  # Gmsh: our node order as is
    meshio.write(path, meshio.Mesh(mesh.points, [(kind, mirrored)]), file_format="gmsh22")
    with caplog.at_level("WARNING", logger="fem.io"):
        read = fem.read_mesh(path)
    assert "wound the other way" in caplog.text and "mirrored.msh" in caplog.text
    np.testing.assert_allclose(read.volumes[kind], mesh.volumes[kind], rtol=1e-12)
    assert (read.volumes[kind] > 0).all()


def test_second_order_cells_are_read_on_their_corners(tmp_path, caplog):
    import meshio

    mesh = _meshes()["tetra"]
    tets = mesh.cells["tetra"]
    edges = np.sort(tets[:, [[0, 1], [1, 2], [0, 2], [0, 3], [1, 3], [2, 3]]], axis=2)
    uniq, inv = np.unique(edges.reshape(-1, 2), axis=0, return_inverse=True)
    mid = 0.5 * (mesh.points[uniq[:, 0]] + mesh.points[uniq[:, 1]])
    t10 = np.hstack([tets, inv.reshape(-1, 6) + mesh.n_points])
    path = tmp_path / "quadratic.vtu"
    meshio.write(path, meshio.Mesh(np.vstack([mesh.points, mid]), [("tetra10", t10)]))
    with caplog.at_level("WARNING", logger="fem.io"):
        read = fem.read_mesh(path)
    assert "second-order cells (tetra10)" in caplog.text
    assert read.n_points == mesh.n_points  # the mid-edge nodes are dropped
    np.testing.assert_array_equal(read.cells["tetra"], tets)


def test_write_is_atomic_on_bad_data(tmp_path):
    mesh = _meshes()["wedge"]
    path = tmp_path / "m.vtu"
    fem.write_mesh(path, mesh)
    before = path.read_bytes()
    with pytest.raises(fem.MeshError, match=r"m\.vtu.*point data 'u' must have"):
        fem.write_mesh(path, mesh, point_data={"u": np.zeros(3)})
    with pytest.raises(fem.MeshError, match=r"m\.vtu.*cell data 's'"):
        fem.write_mesh(path, mesh, cell_data={"s": np.zeros(mesh.n_cells + 1)})
    with pytest.raises(fem.MeshError, match=r"m\.vtu.*cell data 's'.*cell types"):
        fem.write_mesh(path, mesh, cell_data={"s": {"tetra": np.zeros(2)}})
    with pytest.raises(fem.MeshError, match="reserved"):
        fem.write_mesh(path, mesh, cell_data={"region": np.zeros(mesh.n_cells)})
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["m.vtu"]


def test_write_failure_inside_meshio_leaves_nothing_behind(tmp_path, monkeypatch):
    mesh = _meshes()["tetra"]
    path = tmp_path / "m.vtu"
    fem.write_mesh(path, mesh)
    before = path.read_bytes()
    meshio = fem_io._meshio()

    def half_write(filename, *args, **kwargs):
        with open(filename, "w") as fh:
            fh.write("<VTKFile half written")
        raise OSError("disk full")

    monkeypatch.setattr(meshio, "write", half_write)
    with pytest.raises(fem.MeshError, match=r"cannot write mesh file .*m\.vtu: OSError: disk full"):
        fem.write_mesh(path, mesh)
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["m.vtu"]
    with pytest.raises(fem.MeshError, match=r"new\.vtu"):
        fem.write_mesh(tmp_path / "new.vtu", mesh)
    assert [p.name for p in tmp_path.iterdir()] == ["m.vtu"]


def test_write_errors_name_the_path(tmp_path):
    mesh = _meshes()["tetra"]
    with pytest.raises(fem.MeshError, match=r"m\.nosuchformat: unknown format"):
        fem.write_mesh(tmp_path / "m.nosuchformat", mesh)
    with pytest.raises(fem.MeshError, match="does not exist"):
        fem.write_mesh(tmp_path / "no" / "m.vtu", mesh)
    assert list(tmp_path.iterdir()) == []


def test_float_region_ids_must_be_integral(tmp_path):
    mesh = _meshes()["tetra"]
    grid = fem.to_pyvista(mesh)
    grid.cell_data["region"] = grid.cell_data["region"] + 0.5
    grid.save(tmp_path / "f.vtu")
    with pytest.raises(fem.MeshError, match=r"f\.vtu.*'region'.*integers"):
        fem.read_mesh(tmp_path / "f.vtu")
