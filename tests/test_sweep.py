"""Sweeps on an embedded Dask cluster: table rows equal single runs, failures, resume, refusals."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

pytest.importorskip("distributed")

from contact.grasp import run as grasp_run
from contact.sweep import _limit_threads, sweep
from contact.sweepspec import dump_toml, load_sweep, tomllib

PADS = Path(__file__).resolve().parents[1] / "examples" / "pads.toml"
SKIP = {"timings", "seconds", "versions"}


def _scene(tmp: Path, mesh_line: str = "mesh_size = 0.006") -> Path:
    text = PADS.read_text().replace("mesh_size = 0.004", mesh_line)
    path = tmp / "pads.toml"
    path.write_text(text)
    return path


def _sweep(tmp: Path, vary: str, name: str = "sweep.toml") -> Path:
    path = tmp / name
    path.write_text(f'[sweep]\nscene = "pads.toml"\n\n[vary]\n{vary}\n')
    return path


def _rows(out: Path) -> list[dict]:
    with open(out / "sweep.csv") as fh:
        return list(csv.DictReader(fh))


def _strip(d):
    if isinstance(d, dict):
        return {k: _strip(v) for k, v in d.items() if k not in SKIP}
    if isinstance(d, list):
        return [_strip(v) for v in d]
    return d


def _same(a, b):
    if isinstance(a, dict):
        assert set(a) == set(b)
        for k in a:
            _same(a[k], b[k])
    elif isinstance(a, list):
        assert len(a) == len(b)
        for x, y in zip(a, b):
            _same(x, y)
    elif isinstance(a, float):
        assert a == pytest.approx(b, rel=1e-9, abs=1e-12)
    else:
        assert a == b


def test_dump_toml_reads_back():
    doc = tomllib.loads(PADS.read_text())
    doc["hand"] = {"auto_flexion": [{"force": 2.0, "fingers": ["index"]}], "x y": "a\"b"}
    assert tomllib.loads(dump_toml(doc)) == doc


def test_four_runs_equal_single_runs_then_resume(tmp_path, capsys):
    _scene(tmp_path)
    # both pads' friction: every run a ball held by force-driven pads (a well-posed frame)
    sw = _sweep(tmp_path, '"plane[0].friction" = [0.5, 0.6]\n"plane[1].friction" = [0.5, 0.7]')
    out = tmp_path / "out"
    assert sweep(sw, out=out, workers=2, quiet=True) == 0
    rows = _rows(out)
    assert [r["run"] for r in rows] == ["0000", "0001", "0002", "0003"]
    assert all(r["status"] == "done" for r in rows)
    assert (out / "sweep.png").is_file()
    for r in rows:
        folder = out / "runs" / r["run"]
        scene = tomllib.loads((folder / "scene.toml").read_text())
        assert scene["plane"][0]["friction"] == float(r["plane[0].friction"])
        with _limit_threads(1):  # the worker's share of threads: the same sums
            status = grasp_run(folder / "scene.toml", out=tmp_path / "single", pictures=False,
                               quiet=True)  # fmt: skip
        assert status == int(r["exit_status"]) == 0
        mine = json.loads((folder / "results" / "summary.json").read_text())
        single = json.loads((tmp_path / "single" / "summary.json").read_text())
        _same(_strip(mine), _strip(single))  # to roundoff
        assert float(r["grip_force"]) == pytest.approx(single["frames"][-1]["grip_force"])
    stamps = {p: p.stat().st_mtime_ns for p in out.glob("runs/*/results/summary.json")}
    assert len(stamps) == 4
    assert sweep(sw, out=out, workers=2, quiet=True) == 0  # resumed: nothing redone
    assert {p: p.stat().st_mtime_ns for p in stamps} == stamps
    assert len(_rows(out)) == 4


def test_a_failing_run_is_a_failed_row_and_the_others_finish(tmp_path):
    import meshio
    import numpy as np

    import fem

    mesh = fem.ball_mesh(0.02, divisions=2, layers=1)
    hexes = [("hexahedron", mesh.cells["hexahedron"])]
    meshio.write(tmp_path / "good.vtu", meshio.Mesh(mesh.points, hexes))
    pts = mesh.points.copy()
    pts[3, 1] = np.nan
    meshio.write(tmp_path / "bad.vtu", meshio.Mesh(pts, hexes))
    _scene(tmp_path, 'mesh = "good.vtu"')
    sw = _sweep(tmp_path, '"ball.mesh" = ["good.vtu", "bad.vtu"]')
    out = tmp_path / "out"
    assert sweep(sw, out=out, workers=2, quiet=True) == 1
    rows = _rows(out)
    assert rows[0]["status"] == "done"
    assert rows[1]["status"].startswith("failed: ") and "\n" not in rows[1]["status"]


@pytest.mark.parametrize(
    ("vary", "words"),
    [
        ('"ball.colour" = [1, 2]', "ball.colour"),
        ('"plane[5].friction" = [0.5]', "plane[5].friction"),
        ('"hand.friction" = [0.5]', "hand.friction"),
        ('"ball.radius" = []', "empty"),
        ('"ball.radius" = ["big"]', "ball.radius"),
    ],
)
def test_bad_sweep_files_exit_2_with_one_line_before_anything_runs(tmp_path, capsys, vary, words):
    _scene(tmp_path)
    sw = _sweep(tmp_path, vary)
    out = tmp_path / "out"
    assert sweep(sw, out=out, quiet=True) == 2
    err = capsys.readouterr().err.strip()
    assert words in err and "\n" not in err and "Traceback" not in err
    assert not (out / "sweep.csv").exists()


def test_ranges_zip_and_relative_paths(tmp_path):
    _scene(tmp_path)
    sw = _sweep(tmp_path, '"ball.material.E" = { start = 1e5, stop = 1e6, num = 3 }\n'
                '"scene.gravity" = [[0.0, 0.0, -9.81], [0.0, 0.0, -5.0], [0.0, 0.0, -1.0]]')
    text = sw.read_text().replace('scene = "pads.toml"', 'scene = "pads.toml"\nmode = "zip"')
    sw.write_text(text)
    s = load_sweep(sw)
    assert s.mode == "zip" and s.vary["ball.material.E"] == [1e5, 5.5e5, 1e6]


def test_a_generated_scene_that_does_not_load_names_the_run(tmp_path, capsys):
    _scene(tmp_path)
    sw = _sweep(tmp_path, '"ball.material.nu" = [0.3, 0.7]')
    assert sweep(sw, out=tmp_path / "out", quiet=True) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: run 0001 (ball.material.nu = 0.7)") and "\n" not in err


def test_a_scheduler_that_does_not_answer_exits_2(tmp_path, capsys, monkeypatch):
    import contact.sweep

    monkeypatch.setattr(contact.sweep, "SCHEDULER_TIMEOUT", 1.0)
    _scene(tmp_path)
    sw = _sweep(tmp_path, '"plane[0].friction" = [0.5]')
    assert sweep(sw, out=tmp_path / "out", scheduler="tcp://127.0.0.1:1", quiet=True) == 2
    err = capsys.readouterr().err.strip()
    assert "tcp://127.0.0.1:1" in err and "\n" not in err


@pytest.mark.slow  # it kills a worker mid-run: timing-dependent, run on demand
def test_a_worker_killed_during_a_run_is_resubmitted(tmp_path):
    import threading
    import time

    psutil = pytest.importorskip("psutil")
    _scene(tmp_path)
    sw = _sweep(tmp_path, '"plane[0].friction" = [0.5, 0.6]\n"plane[1].friction" = [0.5, 0.6]')
    out = tmp_path / "out"
    killed = []

    start = time.time() - 1.0

    def worker(k) -> bool:  # a process this sweep's cluster spawned, busy running
        try:
            spawned = k.create_time() >= start and "spawn_main" in " ".join(k.cmdline())
            return spawned and k.cpu_percent(interval=0.2) > 50
        except psutil.Error:
            return False

    def kill() -> None:  # a busy worker process, once a run is under way
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not killed:
            time.sleep(0.5)
            if not any((out / "runs").glob("*/scene.toml")):
                continue
            busy = [k for k in psutil.Process().children(recursive=True) if worker(k)]
            if busy:
                busy[0].kill()
                killed.append(busy[0].pid)

    t = threading.Thread(target=kill, daemon=True)
    t.start()
    assert sweep(sw, out=out, workers=2, quiet=True) == 0
    t.join(5)
    assert killed
    rows = _rows(out)
    assert len(rows) == 4 and all(r["status"] == "done" for r in rows)


def test_a_base_scene_that_does_not_exist_exits_2(tmp_path, capsys):
    sw = _sweep(tmp_path, '"ball.radius" = [0.02]')  # names pads.toml, never written
    out = tmp_path / "out"
    assert sweep(sw, out=out, quiet=True) == 2
    err = capsys.readouterr().err.strip()
    assert "pads.toml" in err and "\n" not in err and "Traceback" not in err
    assert not (out / "sweep.csv").exists()
