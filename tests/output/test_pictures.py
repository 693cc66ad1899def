"""The grasp's pictures, forces.png and the VTU's field data (bone ids, region names, units)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

import fem
from contact.output import (
    BodyFrame,
    ResultsWriter,
    body_picture,
    frame_forces,
    rendering_available,
    units_name,
)
from contact.output.picturedata import held_body
from contact.output.pictures import Picture, _bars
from fem.stress import cell_stress, von_mises
from tests.output.test_output import SOFT, STEEL, ball_on_pad, frame_result, scene_bodies

NAMES = ("lower", "upper")


def named_bodies() -> dict[str, BodyFrame]:
    """The unit scene's bodies, the 'hand' (a block of two regions) with names and bones."""
    bodies = scene_bodies()
    hand = bodies["hand"]
    bone = np.arange(hand.mesh.n_cells) % 2
    bodies["hand"] = BodyFrame(
        hand.mesh, hand.materials, region_names=NAMES, cell_bone=bone, bone_names=("a", "b")
    )
    return bodies


def test_vtu_has_bone_ids_region_names_bone_forces_and_units(tmp_path):
    import pyvista as pv

    bodies = named_bodies()
    res = frame_result({k: b.mesh for k, b in bodies.items()})
    with ResultsWriter(tmp_path / "r", pictures=False) as w:
        w.add_frame(0, 0.25, res, bodies)
        out = w.finish({})
    grid = pv.read(out / "hand_0000.vtu")
    np.testing.assert_array_equal(grid.cell_data["bone"], np.arange(grid.n_cells) % 2)
    field = grid.field_data
    assert field["region lower"][0] == 0 and field["region upper"][0] == 1
    assert field["bone a"][0] == 0 and field["bone b"][0] == 1
    np.testing.assert_array_equal(field["bone_force index_distal (N)"][0], [0.0, 1.0, 2.0])
    assert field["time (s)"][0] == 0.25
    units = units_name()
    assert units in field and "displacement m" in units and "von_mises Pa" in units
    ball = pv.read(out / "ball_0000.vtu")
    assert units in ball.field_data and "bone" not in ball.cell_data
    # meshio (fem.read_mesh_data) still reads the files
    mesh, _, cdata = fem.read_mesh_data(out / "hand_0000.vtu")
    assert mesh.n_points == bodies["hand"].mesh.n_points and "bone" in cdata


def test_forces_png_written_and_listed(tmp_path):
    bodies = named_bodies()
    meshes = {k: b.mesh for k, b in bodies.items()}
    with ResultsWriter(tmp_path / "r", pictures=False) as w:
        for i in range(2):
            w.add_frame(i, 0.5 * i, frame_result(meshes, scale=1.0 + i), bodies)
        out = w.finish({})
    summary = json.loads((out / "summary.json").read_text())
    assert summary["files"]["forces"] == "forces.png"
    assert (out / "forces.png").stat().st_size > 1000


def test_forces_per_region_and_plane():
    bodies = named_bodies()
    meshes = {k: b.mesh for k, b in bodies.items()}
    res = frame_result(meshes)
    hand = meshes["hand"]
    fn = np.zeros(hand.n_points)
    top = np.flatnonzero(hand.points[:, 2] > 0.019)
    fn[top] = 0.5
    res.contact_fields["hand"] = {"normal_force": fn}
    res.contact_force["hand"] = np.zeros((hand.n_points, 3))
    res.contact_force["hand"][top, 2] = 0.5
    points = {k: m.points for k, m in meshes.items()}
    plane = ("plate", np.array([0.0, 0.0, 0.05]), np.array([0.0, 0.0, -1.0]))
    f = frame_forces(0.0, res, points, {"hand": (hand, NAMES)}, [plane], 0.05)
    assert f.fingers == {"lower": 0.0, "upper": 0.5 * len(top)}
    assert f.grip == pytest.approx(0.5 * len(top))
    upper = next(p for p in f.regions if p.label == "upper")
    np.testing.assert_allclose(upper.force, [0.0, 0.0, -0.5 * len(top)])  # on the others
    plate = next(p for p in f.regions if p.label == "plane plate")
    np.testing.assert_allclose(plate.force, [0.0, 0.0, 3.5])  # minus the obstacle force
    assert f.bones == {"index_distal": pytest.approx(np.sqrt(5.0)), "thumb_distal": 4.0}
    given = frame_forces(0.0, res, points, {"hand": (hand, NAMES)}, [plane], 0.05, grip=2.0)
    assert given.grip == 2.0


def test_colour_ranges_are_per_body():
    ball = fem.ball_mesh(0.01, divisions=4, layers=2, center=(0.0, 0.0, 0.03))
    hand = fem.box_mesh((0.02, 0.02, 0.02), (2, 2, 2))
    pics = []
    for name, mesh, mat, scale in (("ball", ball, SOFT, 1.0), ("hand", hand, STEEL, 1e3)):
        u = np.c_[1e-3 * scale * mesh.points[:, 0], np.zeros((mesh.n_points, 2))]
        vm = {k: von_mises(s) for k, s in cell_stress(mesh, mat, u.ravel()).items()}
        fields = {"normal_force": np.zeros(mesh.n_points)}
        pics.append(body_picture(name, mesh, mat, u, vm, fields))
    forces = frame_forces(0.0, frame_result({}), {}, {}, [], 1.0)
    bars = _bars([Picture(0, 0.0, pics, [], forces)])
    assert bars["ball"].top < 1e-3 * bars["hand"].top  # each body its own range
    assert bars["ball"].cmap != bars["hand"].cmap
    assert "ball" in bars["ball"].title and "(kPa)" in bars["ball"].title
    assert "(MPa)" in bars["hand"].title
    # a body at rest is round-off: no bar
    noise = {k: np.full(len(c), 1e-13) for k, c in ball.cells.items()}
    still = np.zeros((ball.n_points, 3))
    rest = body_picture("rest", ball, SOFT, still, noise, {"normal_force": still[:, 0]})
    assert _bars([Picture(0, 0.0, [rest], [], forces)])["rest"].blank


def _image(path):
    from PIL import Image

    return np.asarray(Image.open(path).convert("RGB")).astype(int)


def test_pictures_not_blank_differ_between_frames_and_mark_failures(tmp_path):
    ok, reason = rendering_available()
    if not ok:
        pytest.skip(f"no off-screen rendering on this machine: {reason}")
    d = tmp_path / "res"
    from contact.solver.iteration import solve_frame

    with ResultsWriter(d, window_size=(480, 320), gif=False) as w:
        for i, depth in enumerate((0.02, 0.1)):
            bodies, pairs, planes = ball_on_pad(depth)
            res = solve_frame(bodies, pairs, planes)
            if i == 1:  # drawn as a frame that did not converge
                res = dataclasses.replace(
                    res, converged=False, stop_reason="iteration limit reached"
                )
            w.add_frame(
                i,
                0.1 * i,
                res,
                {b.name: BodyFrame(b.mesh, b.materials) for b in bodies},
                planes=[(p.name, p.point + p.motion, p.normal) for p in planes],
            )
        out = w.finish({})
    assert json.loads((out / "summary.json").read_text())["pictures"] == "written"
    a, b = (_image(out / "frames" / f"frame_{i:04d}.png") for i in (0, 1))
    assert a.shape == (320, 480, 3) and np.ptp(a) > 100 and np.ptp(b) > 100
    assert np.abs(a - b).sum(axis=2).astype(bool).mean() > 0.01  # the scene moved

    def red(img: np.ndarray) -> int:  # the verdict's and the failure's red text
        return int((np.abs(img - np.array([0xCF, 0x22, 0x2E])).sum(axis=2) < 80).sum())

    assert red(a) == 0 and red(b) > 50
    assert (out / "forces.png").is_file()


def test_the_held_body_is_the_smallest_and_one_for_any_order():
    ball = fem.ball_mesh(0.01, divisions=4, layers=2).points
    hand = fem.box_mesh((0.04, 0.04, 0.005), (2, 2, 1)).points  # thinner, yet larger
    assert held_body({"hand": hand, "ball": ball}) == "ball"
    assert held_body({"ball": ball, "hand": hand}) == "ball"
    assert held_body({"a": ball, "b": ball.copy()}) == "a"  # equal: the first
    with pytest.raises(ValueError, match="at least one body"):
        held_body({})


def test_a_force_label_stays_in_its_view():
    ok, reason = rendering_available()
    if not ok:
        pytest.skip(f"no off-screen rendering on this machine: {reason}")
    import pyvista as pv

    from contact.output.drawing import label_anchors

    plotter = pv.Plotter(off_screen=True, window_size=(900, 600), shape=(1, 3))
    try:
        plotter.subplot(0, 2)  # a narrow panel at the right, as the held body's
        plotter.camera_position = [(0, 0, 5), (0, 0, 0), (0, 1, 0)]
        plotter.reset_camera(bounds=(-1, 1, -1, 1, -1, 1))
        points = np.array([[0.9, 0.9, 0], [-0.3, -0.3, 0]])
        labels = ["plane table 0.452 N", "x"]
        at = label_anchors(plotter, points, labels, 11)
        np.testing.assert_allclose(at[1], points[1], atol=1e-12)  # inside: left where it is
        ren = plotter.renderer
        ren.SetWorldPoint(*at[0], 1.0)
        ren.WorldToDisplay()
        x, y, _ = ren.GetDisplayPoint()
        assert 600 < x and x + 0.65 * 11 * len(labels[0]) + 8 <= 900  # back in its panel
        assert y + 1.6 * 11 + 4 <= 600
        assert at[0][2] == pytest.approx(0.0, abs=1e-9)  # at its point's depth
    finally:
        plotter.close()
