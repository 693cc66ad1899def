"""The results folder: VTU/PVD series, summary.json, verdict, the folder swap, pictures."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

import fem
from contact.errors import ContactError
from contact.geometry.plane import Plane
from contact.output import (
    STRESS_COMPONENTS,
    BodyFrame,
    OutputError,
    ResultsWriter,
    rendering_available,
    verdict,
    versions,
)
from contact.output.staging import MARKER
from contact.solver.body import ElasticBody
from contact.solver.iteration import solve_frame
from contact.solver.pairs import ContactPair
from contact.solver.results import FrameResult, IterationRecord
from fem.material import lame

STEEL = fem.LinearElastic(E=200e9, nu=0.3)
SOFT = fem.LinearElastic(E=1e5, nu=0.45)
STRAIN = 1e-3


def block() -> fem.Mesh:
    """A 2x2x2 hex block of side 2 cm, the upper half region 1 (wedges there)."""
    box = fem.box_mesh((0.02, 0.02, 0.02), (2, 2, 2))
    hexes = box.cells["hexahedron"]
    up = box.points[hexes].mean(axis=1)[:, 2] > 0.01
    wedges = np.concatenate([hexes[up][:, [0, 1, 2, 4, 5, 6]], hexes[up][:, [0, 2, 3, 4, 6, 7]]])
    return fem.Mesh(
        box.points,
        {"hexahedron": hexes[~up], "wedge": wedges},
        {"hexahedron": np.zeros((~up).sum(), int), "wedge": np.ones(len(wedges), int)},
    )


def frame_result(
    meshes: dict[str, fem.Mesh],
    *,
    scale: float = 1.0,
    converged: bool = True,
    stop_reason: str = "converged",
    over_limit: dict | None = None,
) -> FrameResult:
    """A hand-made result: uniaxial strain ``scale * STRAIN`` along x in every body."""
    disp = {
        n: np.c_[scale * STRAIN * m.points[:, 0], np.zeros((m.n_points, 2))]
        for n, m in meshes.items()
    }
    force = {}
    for n, m in meshes.items():
        f = np.zeros((m.n_points, 3))
        f[:3, 2] = [1.0, 2.0, 0.5 * scale]
        force[n] = f
    history = tuple(
        IterationRecord(
            k,
            3 + k,
            3 if k == 1 else 0,
            0,
            10.0 ** (-2 - 3 * k) * scale,
            1e-6 / k,
            np.array([0, 0, 3.5]),
        )
        for k in (1, 2, 3)
    )
    return FrameResult(
        converged=converged,
        stop_reason=stop_reason,
        algorithm="contact-space",
        iterations=len(history),
        history=history,
        displacement=disp,
        contact_force=force,
        obstacle_forces={"plate": np.array([0.0, 0.0, -3.5 * scale])},
        support_forces={
            "hand": {
                "index_distal": np.array([0.0, 1.0, 2.0]),
                "thumb_distal": np.array([0, 0, 4.0]),
            }
        },
        over_limit=over_limit or {},
        contacts={
            "pair": np.array(["ball-plate", "ball-plate", "hand-ball"]),
            "node": np.array([0, 1, 2]),
            "force": np.array([1.0, 2.0, 0.5]),
            "normal": np.tile([0.0, 0.0, 1.0], (3, 1)),
        },
        max_penetration=2e-7 * scale,
        penetration_ratio=1e-5 * scale,
        timings={"solve": 0.25, "query": 0.125},
    )


def scene_bodies() -> dict[str, BodyFrame]:
    ball = fem.ball_mesh(0.01, divisions=4, layers=2, center=(0.0, 0.0, 0.03))
    return {
        "ball": BodyFrame(ball, SOFT),
        "hand": BodyFrame(block(), {0: STEEL, 1: SOFT}),
    }


def strip_timings(obj):
    if isinstance(obj, dict):
        return {k: strip_timings(v) for k, v in obj.items() if k != "timings"}
    if isinstance(obj, list):
        return [strip_timings(v) for v in obj]
    return obj


def write_run(directory: Path, n: int = 2, **kwargs) -> tuple[Path, list[FrameResult]]:
    bodies = scene_bodies()
    meshes = {k: b.mesh for k, b in bodies.items()}
    results = [frame_result(meshes, scale=1.0 + i) for i in range(n)]
    with ResultsWriter(directory, pictures=False, gif=False, **kwargs) as w:
        for i, r in enumerate(results):
            w.add_frame(i, 0.5 * i, r, bodies, planes=[("plate", (0, 0, 0.05), (0, 0, -1))])
        out = w.finish({"name": "unit", "frames": [0.0, 0.5], "path": directory / "x.toml"})
    return out, results


# --- verdict ----------------------------------------------------------------------------


def test_verdict_converged_overlimit_and_not_converged():
    meshes = {"ball": scene_bodies()["ball"].mesh}
    ok = verdict(frame_result(meshes))
    assert ok == {"realistic": True, "reason": "converged; every bone under its limit"}
    # a bone over its limit: the frame converged, its verdict names every bone over
    over = verdict(
        frame_result(
            meshes,
            over_limit={"thumb_distal": (40.0, 30.0), "index_distal": (12.5, 10.0)},
        )
    )
    assert over["realistic"] is False
    assert over["reason"] == (
        "bone index_distal carries 12.5 N > its limit 10 N; "
        "bone thumb_distal carries 40 N > its limit 30 N"
    )
    stuck = verdict(frame_result(meshes, converged=False, stop_reason="cycling"))
    assert stuck == {"realistic": False, "reason": "not converged: cycling"}


# --- vtu, pvd, summary --------------------------------------------------------------------


def test_vtu_files_hold_the_result(tmp_path):
    out, results = write_run(tmp_path / "res")
    bodies = scene_bodies()
    for i, res in enumerate(results):
        for name, body in bodies.items():
            mesh, pdata, cdata = fem.read_mesh_data(out / f"{name}_{i:04d}.vtu")
            np.testing.assert_array_equal(mesh.points, body.mesh.points)
            assert set(mesh.cells) == set(body.mesh.cells)
            for kind in mesh.cells:
                np.testing.assert_array_equal(mesh.cells[kind], body.mesh.cells[kind])
                np.testing.assert_array_equal(mesh.regions[kind], body.mesh.regions[kind])
            np.testing.assert_array_equal(pdata["displacement"], res.displacement[name])
            np.testing.assert_array_equal(pdata["contact_force"], res.contact_force[name])
            assert set(cdata) == {"von_mises", "stress"}
            # uniaxial strain e along x: sxx = (lam + 2 mu) e, syy = szz = lam e, von Mises 2 mu e
            e = STRAIN * (1 + i)
            mats = body.materials if isinstance(body.materials, dict) else {0: body.materials}
            for kind, conn in mesh.cells.items():
                stress, vm = cdata["stress"][kind], cdata["von_mises"][kind]
                assert stress.shape == (len(conn), 6) and vm.shape == (len(conn),)
                for c in range(len(conn)):
                    m = mats[int(mesh.regions[kind][c])]
                    lam, mu = lame(m.E, m.nu)
                    want = [(lam + 2 * mu) * e, lam * e, lam * e, 0, 0, 0]
                    np.testing.assert_allclose(stress[c], want, rtol=1e-9, atol=1e-9 * m.E * e)
                    assert vm[c] == pytest.approx(2 * mu * e, rel=1e-9)
    assert STRESS_COMPONENTS == ("xx", "yy", "zz", "xy", "yz", "xz")


def test_pvd_lists_every_frame(tmp_path):
    out, _ = write_run(tmp_path / "res", n=3)
    for name in ("ball", "hand"):
        root = ET.parse(out / f"{name}.pvd").getroot()
        assert root.tag == "VTKFile" and root.get("type") == "Collection"
        sets = root.find("Collection").findall("DataSet")
        assert [float(d.get("timestep")) for d in sets] == [0.0, 0.5, 1.0]
        assert [d.get("file") for d in sets] == [f"{name}_{i:04d}.vtu" for i in range(3)]
        assert all((out / d.get("file")).is_file() for d in sets)


def test_pvd_opens_in_pyvista(tmp_path):
    import pyvista as pv

    out, results = write_run(tmp_path / "res")
    reader = pv.get_reader(str(out / "ball.pvd"))
    assert reader.time_values == [0.0, 0.5]
    reader.set_active_time_value(0.5)
    grid = reader.read()[0]
    np.testing.assert_allclose(grid.point_data["displacement"], results[1].displacement["ball"])
    assert grid.cell_data["stress"].shape == (grid.n_cells, 6)


def test_summary_round_trips_and_is_deterministic(tmp_path):
    out, results = write_run(tmp_path / "a")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["scene"] == {"name": "unit", "frames": [0.0, 0.5], "path": str(out / "x.toml")}
    assert summary["versions"] == versions()
    assert {"python", "numpy", "scipy", "meshio", "pyvista", "pytetwild", "libigl"} <= set(
        summary["versions"]
    )
    assert summary["versions"]["grasp-contact"] != "not installed"
    assert summary["all_converged"] and summary["all_realistic"]
    assert summary["pictures"] == "off"
    assert summary["files"]["pvd"] == {"ball": "ball.pvd", "hand": "hand.pvd"}
    frames = summary["frames"]
    assert [f["time"] for f in frames] == [0.0, 0.5]
    f1, r1 = frames[1], results[1]
    assert f1["converged"] is True and f1["stop_reason"] == "converged"
    assert f1["iterations"] == 3 and len(f1["history"]) == 3
    assert f1["history"][1]["max_change"] == r1.history[1].max_change
    assert f1["history"][0]["total_force"] == [0.0, 0.0, 3.5]
    assert f1["max_penetration"] == r1.max_penetration
    assert f1["contact_force"]["ball"] == {"force": [0.0, 0.0, 4.0], "magnitude": 4.0}
    assert f1["obstacle_forces"]["plate"] == {"force": [0.0, 0.0, -7.0], "magnitude": 7.0}
    assert f1["bone_forces"]["thumb_distal"] == {
        "body": "hand",
        "force": [0.0, 0.0, 4.0],
        "magnitude": 4.0,
    }
    assert f1["bone_forces"]["index_distal"]["magnitude"] == pytest.approx(5**0.5)
    assert f1["contacts"] == {"total": 3, "per_pair": {"ball-plate": 2, "hand-ball": 1}}
    assert f1["verdict"] == verdict(r1)
    assert f1["files"]["vtu"] == {"ball": "ball_0001.vtu", "hand": "hand_0001.vtu"}
    assert f1["timings"]["solve"] == 0.25 and f1["timings"]["write"] > 0
    assert f1["max_von_mises"]["ball"] == pytest.approx(2 * lame(SOFT.E, SOFT.nu)[1] * 2 * STRAIN)
    # the same input again: the same summary, timings aside
    out_b, _ = write_run(tmp_path / "b")
    again = json.loads((out_b / "summary.json").read_text())
    again["scene"]["path"] = summary["scene"]["path"]
    assert strip_timings(again) == strip_timings(summary)
    assert (out / "convergence.png").stat().st_size > 1000


def test_add_frame_returns_the_entry_with_extra(tmp_path):
    bodies = scene_bodies()
    res = frame_result(
        {k: b.mesh for k, b in bodies.items()}, converged=False, stop_reason="iteration limit"
    )
    with ResultsWriter(tmp_path / "r", pictures=False) as w:
        entry = w.add_frame(7, 1.25, res, bodies, extra={"angles": {"index_mcp": np.float64(0.5)}})
        assert entry["angles"] == {"index_mcp": 0.5}
        assert entry["verdict"] == {"realistic": False, "reason": "not converged: iteration limit"}
        json.dumps(entry, allow_nan=False)
        with pytest.raises(ValueError, match="already added"):
            w.add_frame(7, 1.5, res, bodies)
        with pytest.raises(ValueError, match="repeats keys"):
            w.add_frame(8, 1.5, res, bodies, extra={"time": 3})
        with pytest.raises(ValueError, match="no displacement"):
            w.add_frame(9, 1.5, res, {"pad": bodies["ball"]})
        with pytest.raises(ValueError, match="shape"):
            w.add_frame(9, 1.5, res, {"ball": bodies["hand"]})
        out = w.finish({})
    summary = json.loads((out / "summary.json").read_text())
    assert [f["index"] for f in summary["frames"]] == [7]
    assert summary["all_converged"] is False and summary["all_realistic"] is False
    assert (out / "ball_0007.vtu").is_file()


# --- the folder swap ----------------------------------------------------------------------


def old_results(path: Path) -> Path:
    path.mkdir()
    (path / "summary.json").write_text('{"old": true}')
    (path / "sentinel.txt").write_text("old run")
    (path / MARKER).write_text('{"kind": "results", "files": ["summary.json", "sentinel.txt"]}')
    return path


def siblings(path: Path) -> list[str]:
    return sorted(p.name for p in path.parent.iterdir())


def test_existing_results_replaced_completely(tmp_path):
    d = old_results(tmp_path / "res")
    out, _ = write_run(d)
    assert out == d
    assert not (d / "sentinel.txt").exists()
    assert "old" not in json.loads((d / "summary.json").read_text())
    assert siblings(d) == ["res"]  # no staging or old folder left
    assert not [p for p in d.rglob("*") if p.name.startswith(".") and p.name != MARKER]


def test_abort_and_errors_leave_existing_results_untouched(tmp_path):
    d = old_results(tmp_path / "res")
    before = {p.name: p.read_bytes() for p in d.iterdir()}
    bodies = scene_bodies()
    res = frame_result({k: b.mesh for k, b in bodies.items()})
    # the CLI's way: abort() on an error
    w = ResultsWriter(d, pictures=False)
    w.add_frame(0, 0.0, res, bodies)
    assert len(siblings(d)) == 3  # the staging folder and its lock, beside
    w.abort()
    w.abort()  # idempotent
    with pytest.raises(RuntimeError, match="aborted"):
        w.add_frame(1, 0.0, res, bodies)
    # an exception inside the with block
    with pytest.raises(ZeroDivisionError):
        with ResultsWriter(d, pictures=False) as w2:
            w2.add_frame(0, 0.0, res, bodies)
            raise ZeroDivisionError
    # a failure inside finish (the scene cannot be echoed... the summary cannot be written)
    w3 = ResultsWriter(d, pictures=False)
    w3.add_frame(0, 0.0, res, bodies)
    (w3.staging / "summary.json").mkdir()  # os.replace onto a folder fails
    with pytest.raises(OutputError, match="res"):
        w3.finish({})
    assert {p.name: p.read_bytes() for p in d.iterdir()} == before
    assert siblings(d) == ["res"]


def test_unwritable_or_foreign_folders_are_refused(tmp_path):
    foreign = tmp_path / "home"
    foreign.mkdir()
    (foreign / "thesis.tex").write_text("precious")
    with pytest.raises(OutputError, match="not a results folder") as info:
        ResultsWriter(foreign)
    assert isinstance(info.value, OSError) and isinstance(info.value, ContactError)
    afile = tmp_path / "file"
    afile.write_text("x")
    with pytest.raises(OutputError, match="not a folder"):
        ResultsWriter(afile)
    with pytest.raises(OutputError, match=str(afile / "res")):
        ResultsWriter(afile / "res")  # parent is a file
    assert (foreign / "thesis.tex").read_text() == "precious"
    empty = tmp_path / "empty"
    empty.mkdir()
    out, _ = write_run(empty, n=1)
    assert (out / "summary.json").is_file()


def test_pictures_skipped_without_rendering(tmp_path, monkeypatch, caplog):
    import contact.output.rendering

    rendering = contact.output.rendering
    monkeypatch.setattr(rendering, "rendering_available", lambda: (False, "no OpenGL"))
    bodies = scene_bodies()
    res = frame_result({k: b.mesh for k, b in bodies.items()})
    with ResultsWriter(tmp_path / "r") as w:
        w.add_frame(0, 0.0, res, bodies)
        out = w.finish({})
    summary = json.loads((out / "summary.json").read_text())
    assert summary["pictures"] == "skipped: no OpenGL"
    assert "gif" not in summary["files"]
    assert not (out / "frames").exists() and not (out / "grasp.gif").exists()
    assert (out / "convergence.png").is_file()
    assert "pictures skipped: no OpenGL" in caplog.text


# --- a real solve, with pictures ------------------------------------------------------------


def ball_on_pad(depth: float):
    """tests/test_contact_frame.py's scene, coarse: a ball pressed by a plate onto a pad."""
    r, e_pad = 0.02, 1.0e5
    ball = ElasticBody(
        "ball",
        fem.ball_mesh(r, divisions=4, layers=4, center=(0, 0, r)),
        fem.LinearElastic(e_pad, 0.3),
    )
    side, h = 3 * r, r
    pad_mesh = fem.box_mesh((side, side, h), (6, 6, 3), (-side / 2, -side / 2, -h))
    bottom = np.flatnonzero(np.isclose(pad_mesh.points[:, 2], -h))
    pad = ElasticBody(
        "pad",
        pad_mesh,
        fem.LinearElastic(e_pad, 0.3),
        prescribed=fem.node_dofs(bottom),
        supports={"base": bottom},
    )
    plate = Plane([0, 0, 2 * r], [0, 0, -1], motion=[0, 0, -depth * r], name="plate")
    pairs = [ContactPair(ball, plate), ContactPair(ball, pad), ContactPair(pad, ball)]
    return [ball, pad], pairs, [plate]


def test_real_frames_with_pictures_gif_and_convergence(tmp_path):
    ok, reason = rendering_available()
    if not ok:
        pytest.skip(f"no off-screen rendering on this machine: {reason}")
    d = tmp_path / "res"
    with ResultsWriter(d, window_size=(320, 240)) as w:
        for i, depth in enumerate((0.02, 0.05)):
            bodies, pairs, planes = ball_on_pad(depth)
            res = solve_frame(bodies, pairs, planes)
            assert res.converged
            entry = w.add_frame(
                i,
                0.1 * i,
                res,
                {b.name: BodyFrame(b.mesh, b.materials) for b in bodies},
                planes=[(p.name, p.point + p.motion, p.normal) for p in planes],
            )
            assert entry["verdict"]["realistic"]
            assert entry["bone_forces"]["base"]["force"][2] > 0
        assert {p.held for p in w._pictures} == {"ball"}  # one held body for the run
        out = w.finish({"name": "ball on pad"})
    summary = json.loads((out / "summary.json").read_text())
    assert summary["pictures"] == "written"
    pngs = sorted((out / "frames").glob("frame_*.png"))
    assert [p.name for p in pngs] == ["frame_0000.png", "frame_0001.png"]
    # the ball is pressed on the pad in both: its contact pressure pictured
    pressed = sorted(p.name for p in (out / "frames").glob("pressure_*.png"))
    assert pressed == ["pressure_0000.png", "pressure_0001.png"]
    assert all(p.stat().st_size > 1000 for p in pngs)
    from PIL import Image

    img = np.asarray(Image.open(pngs[1]).convert("RGB"))
    assert img.shape == (240, 320, 3) and np.ptp(img) > 100  # not blank
    for png in pngs:  # every frame's side views drawn, after a pressure picture too
        side = np.asarray(Image.open(png).convert("RGB"))[:, 230:].astype(float)
        assert side.std() > 30, png.name
    with Image.open(out / "grasp.gif") as gif:
        assert gif.n_frames == 2
    assert (out / "convergence.png").stat().st_size > 1000
    _, pdata, _ = fem.read_mesh_data(out / "ball_0001.vtu")
    np.testing.assert_array_equal(pdata["displacement"], res.displacement["ball"])


@pytest.mark.parametrize("egl", [True, False])
def test_headless_linux_asks_vtk_for_egl_where_it_renders(monkeypatch, egl):
    """No display: EGL is probed first and chosen where it renders, else VTK chooses."""
    import contact.output.rendering as out

    calls = []

    def probe(env):
        calls.append(dict(env))
        return (egl, "ok" if egl else "no EGL") if env else (True, "ok")

    monkeypatch.setattr(out, "_probe", probe)
    monkeypatch.setattr(out.sys, "platform", "linux")
    for var in ("DISPLAY", "WAYLAND_DISPLAY", "VTK_DEFAULT_OPENGL_WINDOW"):
        monkeypatch.setenv(var, "")  # recorded, so that what the call sets is undone
        monkeypatch.delenv(var)
    assert out.rendering_available.__wrapped__() == (True, "ok")
    assert calls[0] == {"VTK_DEFAULT_OPENGL_WINDOW": "vtkEGLRenderWindow"}
    if egl:
        assert len(calls) == 1
        assert out.os.environ["VTK_DEFAULT_OPENGL_WINDOW"] == "vtkEGLRenderWindow"
    else:
        assert calls[1:] == [{}]
        assert "VTK_DEFAULT_OPENGL_WINDOW" not in out.os.environ
    # the user's own choice, or a display: VTK chooses, one probe
    calls.clear()
    monkeypatch.setenv("VTK_DEFAULT_OPENGL_WINDOW", "vtkOSOpenGLRenderWindow")
    out.rendering_available.__wrapped__()
    assert calls == [{}]
    assert out.os.environ["VTK_DEFAULT_OPENGL_WINDOW"] == "vtkOSOpenGLRenderWindow"
    calls.clear()
    monkeypatch.delenv("VTK_DEFAULT_OPENGL_WINDOW")
    monkeypatch.setenv("DISPLAY", ":0")
    out.rendering_available.__wrapped__()
    assert calls == [{}]


def test_hand_picture_without_rendering_is_a_clear_error(monkeypatch, tmp_path):
    import contact.output.rendering
    from contact.hand.plot import render_hand

    rendering = contact.output.rendering
    monkeypatch.setattr(rendering, "rendering_available", lambda: (False, "no OpenGL"))
    with pytest.raises(ContactError, match=r"cannot render .*hand\.png: no OpenGL"):
        render_hand(tmp_path / "hand.png", {})
    assert not (tmp_path / "hand.png").exists()


def test_verdict_of_a_scene_without_bones_says_nothing_of_bones():
    from types import SimpleNamespace

    frame = SimpleNamespace(over_limit={}, converged=True, held=True, support_forces={})
    assert verdict(frame) == {"realistic": True, "reason": "converged; held"}
    frame = SimpleNamespace(over_limit={}, converged=True, held=None, support_forces={"b": {}})
    assert verdict(frame) == {"realistic": True, "reason": "converged"}
