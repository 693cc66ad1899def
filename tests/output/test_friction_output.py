"""Friction in the results folder: contact point data, summary keys, the stick/slip picture."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import fem
from contact.output import (
    CONTACT_FIELDS,
    BodyFrame,
    ResultsWriter,
    contact_point_data,
    rendering_available,
    status_markers,
)
from contact.solver.results import FrameResult, FrictionReport, IterationRecord

SOFT = fem.LinearElastic(E=1e5, nu=0.45)


def bodies() -> dict[str, BodyFrame]:
    """A ball resting on a pad: the pad's top at z = 0, the ball above it."""
    return {
        "ball": BodyFrame(fem.ball_mesh(0.01, divisions=4, layers=2, center=(0, 0, 0.01)), SOFT),
        "pad": BodyFrame(fem.box_mesh((0.04, 0.04, 0.01), (4, 4, 1), (-0.02, -0.02, -0.01)), SOFT),
    }


def ball_fields(mesh: fem.Mesh) -> dict[str, np.ndarray]:
    """Contact fields on the ball's lowest nodes: the lowest sticks, the others slip."""
    n = mesh.n_points
    z = mesh.points[:, 2]
    low = np.flatnonzero(z < z.min() + 0.002)
    lowest = low[np.argmin(z[low])]
    status = np.zeros(n, dtype=int)
    status[low] = 2
    status[lowest] = 1
    normal = np.zeros(n)
    normal[low] = 0.5
    tangential = np.zeros((n, 3))
    tangential[low, 0] = 0.1
    cone = np.zeros(n)
    cone[low] = 1.0
    cone[lowest] = 0.4
    return {
        "normal_force": normal,
        "tangential_force": tangential,
        "contact_status": status,
        "cone_use": cone,
    }


def result(meshes: dict[str, fem.Mesh], friction: bool) -> FrameResult:
    """A hand-made frame: the ball sunk 0.1 mm, its lowest nodes in contact with the pad."""
    disp = {k: np.zeros((m.n_points, 3)) for k, m in meshes.items()}
    disp["ball"][:, 2] = -1e-4
    fields = ball_fields(meshes["ball"])
    force = {k: np.zeros((m.n_points, 3)) for k, m in meshes.items()}
    force["ball"][:, 2] = fields["normal_force"]
    report = FrictionReport(
        iterations=7,
        residual=3e-13,
        tolerance=1e-10,
        stick=1,
        slip=int((fields["contact_status"] == 2).sum()),
        max_slip=2.5e-6,
        max_cone_use=1.0,
        tangential_force={"ball-pad": np.array([0.3, 0.0, 0.0]), "floor": np.array([0, 0.4, 0])},
    )
    return FrameResult(
        converged=True,
        stop_reason="converged",
        algorithm="contact-space",
        iterations=1,
        history=(IterationRecord(1, 5, 0, 0, 1e-9, 0.0, np.zeros(3)),),
        displacement=disp,
        contact_force=force,
        obstacle_forces={},
        support_forces={},
        over_limit={},
        contacts={"pair": np.array(["ball-pad"] * 5)},
        max_penetration=0.0,
        friction=report if friction else None,
        held=True if friction else None,
        contact_fields={"ball": fields} if friction else {},
    )


def write(directory: Path, frictions: tuple[bool, ...], pictures: bool = False) -> Path:
    b = bodies()
    meshes = {k: v.mesh for k, v in b.items()}
    with ResultsWriter(directory, pictures=pictures, gif=False, window_size=(320, 240)) as w:
        for i, f in enumerate(frictions):
            w.add_frame(i, 0.5 * i, result(meshes, f), b)
        return w.finish({"name": "friction"})


def test_vtu_carries_contact_fields_zeros_where_none(tmp_path):
    out = write(tmp_path / "r", (True, False))
    meshes = {k: v.mesh for k, v in bodies().items()}
    want = ball_fields(meshes["ball"])
    _, pdata, _ = fem.read_mesh_data(out / "ball_0000.vtu")
    for name, values in want.items():
        np.testing.assert_array_equal(pdata[name], values)
    assert pdata["contact_status"].dtype.kind == "i"
    # the pad (no fields in the result) and the frictionless frame: zeros of the right shape
    for vtu, mesh in (("pad_0000.vtu", meshes["pad"]), ("ball_0001.vtu", meshes["ball"])):
        _, pdata, _ = fem.read_mesh_data(out / vtu)
        for name, tail in CONTACT_FIELDS.items():
            assert pdata[name].shape == (mesh.n_points, *tail)
            assert not pdata[name].any()
        assert {"displacement", "contact_force"} <= set(pdata)


def test_summary_friction_and_held(tmp_path):
    out = write(tmp_path / "r", (True, False))
    frames = json.loads((out / "summary.json").read_text())["frames"]
    rich, plain = frames
    assert rich["held"] is True
    f = rich["friction"]
    assert f == {
        "iterations": 7,
        "residual": 3e-13,
        "tolerance": 1e-10,
        "stick": 1,
        "slip": f["slip"],
        "max_slip": 2.5e-6,
        "max_cone_use": 1.0,
        "tangential_force": {
            "ball-pad": {"force": [0.3, 0.0, 0.0], "magnitude": 0.3},
            "floor": {"force": [0.0, 0.4, 0.0], "magnitude": 0.4},
        },
    }
    assert f["slip"] >= 1
    assert plain["friction"] is None and plain["held"] is None
    assert rich["files"]["status_picture"] is None  # no pictures asked for
    # the existing keys stay
    for key in ("contact_force", "obstacle_forces", "contacts", "verdict", "history"):
        assert key in plain


def test_contact_point_data_checks_shapes():
    fields = contact_point_data({"cone_use": np.ones(4)}, 4)
    assert fields["cone_use"].tolist() == [1.0] * 4
    assert fields["tangential_force"].shape == (4, 3)
    assert fields["contact_status"].dtype == np.int32
    with pytest.raises(ValueError, match=r"'tangential_force' of body 'ball'.*\(4, 3\)"):
        contact_point_data({"tangential_force": np.zeros(4)}, 4, "ball")


def test_status_markers_keep_closed_nodes_at_deformed_positions():
    x = {"a": np.arange(12.0).reshape(4, 3), "b": np.ones((2, 3))}
    m = status_markers(x, {"a": np.array([0, 1, 2, 0])})
    np.testing.assert_array_equal(m.points, x["a"][[1, 2]])
    assert m.status.tolist() == [1, 2] and m.count(1) == 1 and m.count(2) == 1


def test_status_picture_written_for_friction_frames(tmp_path):
    ok, reason = rendering_available()
    if not ok:
        pytest.skip(f"no off-screen rendering on this machine: {reason}")
    out = write(tmp_path / "r", (True, False), pictures=True)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["pictures"] == "written"
    files = [f["files"] for f in summary["frames"]]
    assert files[0]["status_picture"] == "frames/status_0000.png"
    assert files[1]["status_picture"] is None
    names = sorted(p.name for p in (out / "frames").iterdir())
    # the ball (the smaller body) touches in frame 0 only: its pressure picture
    assert [f["pressure_picture"] for f in files] == ["frames/pressure_0000.png", None]
    assert names == ["frame_0000.png", "frame_0001.png", "pressure_0000.png", "status_0000.png"]
    from PIL import Image

    img = np.asarray(Image.open(out / "frames" / "status_0000.png").convert("RGB")).astype(int)
    assert img.shape == (240, 320, 3)

    def pixels(rgb: tuple[int, int, int]) -> int:
        return int((np.abs(img - np.array(rgb)).sum(axis=2) < 60).sum())

    assert pixels((0x1F, 0x77, 0xB4)) > 5  # stick: a blue dot and the legend
    assert pixels((0xFF, 0x7F, 0x0E)) > 5  # slip: orange

    img = np.asarray(Image.open(out / "frames" / "pressure_0000.png").convert("RGB")).astype(int)
    assert img.shape[1] == 320
    # the node of the largest pressure is the scale's top (dark red); the rest grey
    assert pixels((0x80, 0x00, 0x26)) > 5
    assert pixels((0xD0, 0xD0, 0xD0)) > 100
