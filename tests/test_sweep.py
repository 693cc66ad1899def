"""Sweeps on an embedded Dask cluster: rows equal single runs, failures, killed workers, resume,
refusals, Parquet, thread counts."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("distributed")

from contact.grasp import run as grasp_run
from contact.sweep.command import TEST_KILL_ONCE, _limit_threads, main, sweep
from contact.sweep.spec import dump_toml, load_sweep, tomllib

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


def _equal_to_single_runs(out: Path, rows: list[dict], tmp: Path) -> None:
    """Each row's results folder equals a plain run of its scene (timings aside)."""
    for r in rows:
        folder = out / "runs" / r["run"]
        with _limit_threads(1):  # the worker's share of threads: the same sums
            status = grasp_run(folder / "scene.toml", out=tmp / "single", pictures=False,
                               quiet=True)  # fmt: skip
        assert status == int(r["exit_status"]) == 0
        mine = json.loads((folder / "results" / "summary.json").read_text())
        single = json.loads((tmp / "single" / "summary.json").read_text())
        _same(_strip(mine), _strip(single))  # to roundoff
        assert float(r["grip_force"]) == pytest.approx(single["frames"][-1]["grip_force"])


def _parquet_equals_csv(out: Path, pq):
    """``sweep.parquet`` holds the CSV's columns and values (nulls where a cell is empty)."""
    table = pq.read_table(out / "sweep.parquet")
    with open(out / "sweep.csv") as fh:
        header = next(csv.reader(fh))
    rows = _rows(out)
    assert table.column_names == header and table.num_rows == len(rows)
    for got, want in zip(table.to_pylist(), rows):
        for c in header:
            v = got[c]
            if v is None:
                assert want[c] == "", c
            elif isinstance(v, float):
                assert float(want[c]) == v, c
            else:
                assert str(v) == want[c], c
    return table


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
    try:
        import pyarrow.parquet as pq
    except ImportError:
        assert not (out / "sweep.parquet").exists()
    else:
        _parquet_equals_csv(out, pq)
    for r in rows:
        scene = tomllib.loads((out / "runs" / r["run"] / "scene.toml").read_text())
        assert scene["plane"][0]["friction"] == float(r["plane[0].friction"])
    _equal_to_single_runs(out, rows, tmp_path)
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
    if (out / "sweep.parquet").exists():  # a failed row's empty figures are nulls there
        _parquet_equals_csv(out, pytest.importorskip("pyarrow.parquet"))


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
    import contact.sweep.cluster

    monkeypatch.setattr(contact.sweep.cluster, "SCHEDULER_TIMEOUT", 1.0)
    _scene(tmp_path)
    sw = _sweep(tmp_path, '"plane[0].friction" = [0.5]')
    assert sweep(sw, out=tmp_path / "out", scheduler="tcp://127.0.0.1:1", quiet=True) == 2
    err = capsys.readouterr().err.strip()
    assert "tcp://127.0.0.1:1" in err and "\n" not in err


def test_a_worker_killed_during_a_run_is_resubmitted(tmp_path, monkeypatch):
    psutil = pytest.importorskip("psutil")
    me = psutil.Process()
    before = {k.pid for k in me.children(recursive=True)}
    _scene(tmp_path)
    sw = _sweep(tmp_path, '"plane[0].friction" = [0.5, 0.6]')
    out = tmp_path / "out"
    marker = tmp_path / "killed"  # the first run to create it kills its worker (SIGKILL)
    monkeypatch.setenv(TEST_KILL_ONCE, str(marker))
    assert sweep(sw, out=out, workers=2, quiet=True) == 0
    pid = int(marker.read_text())
    assert pid not in before and pid != me.pid and not psutil.pid_exists(pid)
    rows = _rows(out)
    assert len(rows) == 2 and all(r["status"] == "done" for r in rows)
    _equal_to_single_runs(out, rows, tmp_path)
    # nothing left running: the cluster's processes are gone (the multiprocessing resource
    # tracker, started once per interpreter, is not the sweep's)
    left = [k for k in me.children(recursive=True) if k.pid not in before]
    _, alive = psutil.wait_procs(left, timeout=10)
    alive = [k for k in alive if "resource_tracker" not in " ".join(k.cmdline())]
    assert not alive, [k.cmdline() for k in alive]


@pytest.mark.slow  # the worker's death and resubmission: test_a_worker_killed_during_a_run
def test_a_run_whose_worker_dies_past_the_allowed_failures_is_a_failed_row(tmp_path, monkeypatch):
    import contact.sweep.cluster

    monkeypatch.setattr(contact.sweep.cluster, "ALLOWED_FAILURES", 0)  # one death is too many
    monkeypatch.setenv(TEST_KILL_ONCE, str(tmp_path / "killed"))
    _scene(tmp_path)
    sw = _sweep(tmp_path, '"plane[0].friction" = [0.5]')
    out = tmp_path / "out"
    assert sweep(sw, out=out, workers=1, quiet=True) == 1
    (row,) = _rows(out)
    assert row["status"].startswith("failed: KilledWorker: ") and "\n" not in row["status"]


def test_the_parquet_table_reads_back_equal_to_the_csv(tmp_path):
    pq = pytest.importorskip("pyarrow.parquet")
    from contact.sweep.table import columns, write_table

    keys = ["ball.material.E", "scene.gravity", "ball.mesh"]
    done = {"status": "done", "exit_status": 0, "converged": True, "realistic": True,
            "held": True, "least_grip_scale": 0.75, "max_bone_force": 1.5, "max_bone": "",
            "grip_force": 2.25, "iterations": 12, "seconds": 0.0}  # fmt: skip
    rows = [
        {"run": "0000", "ball.material.E": 1e5, "scene.gravity": [0.0, 0.0, -9.81],
         "ball.mesh": "a.vtu", **done},
        {"run": "0001", "ball.material.E": 2e5, "scene.gravity": [0.0, 0.0, -5.0],
         "ball.mesh": 7, **done, "max_bone": "index_distal", "held": False},
        {"run": "0002", "ball.material.E": 3e5, "scene.gravity": [0.0, 0.0, -1.0],
         "ball.mesh": "c.vtu", "status": "failed: ValueError: bad", "exit_status": 3,
         "seconds": 0.5},  # a failed run: no figures
    ]  # fmt: skip
    header = columns(keys, least=True)
    written = write_table(rows, header, tmp_path)
    assert written == [tmp_path / "sweep.csv", tmp_path / "sweep.parquet"]
    table = _parquet_equals_csv(tmp_path, pq)
    assert table.column_names == header and table.num_rows == 3
    assert str(table.schema.field("grip_force").type) == "double"
    assert str(table.schema.field("iterations").type) == "int64"
    assert str(table.schema.field("held").type) == "bool"


@pytest.mark.parametrize("argv", [["--threads", "0"], ["--threads", "two"],
                                  ["--threads", "-1"], ["--threads", "1.5"],
                                  ["--workers", "0"]])  # fmt: skip
def test_bad_thread_and_worker_counts_exit_2_with_one_line(tmp_path, capsys, argv):
    _scene(tmp_path)
    sw = _sweep(tmp_path, '"plane[0].friction" = [0.5]')
    out = tmp_path / "out"
    assert main([str(sw), "--out", str(out), "--quiet", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"error: {argv[0]} must be a positive integer") and argv[1] in err
    assert "\n" not in err and not out.exists()


@pytest.mark.parametrize("threads", [0, -2, 1.5, True])
def test_sweep_refuses_a_bad_thread_count(tmp_path, capsys, threads):
    _scene(tmp_path)
    sw = _sweep(tmp_path, '"plane[0].friction" = [0.5]')
    assert sweep(sw, out=tmp_path / "out", threads=threads, quiet=True) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: threads must be a positive integer") and "\n" not in err


def test_a_base_scene_that_does_not_exist_exits_2(tmp_path, capsys):
    sw = _sweep(tmp_path, '"ball.radius" = [0.02]')  # names pads.toml, never written
    out = tmp_path / "out"
    assert sweep(sw, out=out, quiet=True) == 2
    err = capsys.readouterr().err.strip()
    assert "pads.toml" in err and "\n" not in err and "Traceback" not in err
    assert not (out / "sweep.csv").exists()


def test_a_script_without_a_main_guard_still_sweeps(tmp_path):
    # the embedded cluster's worker processes import the script again: there sweep() must
    # return at once instead of starting clusters of its own
    _scene(tmp_path)
    sw = _sweep(tmp_path, '"plane[0].friction" = [0.5]')
    script = tmp_path / "unguarded.py"
    script.write_text(
        "from contact.sweep import sweep\n"
        f"print('rc', sweep({str(sw)!r}, out={str(tmp_path / 'out')!r}, workers=1, quiet=True))\n"
    )
    proc = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=300,
        cwd=Path(__file__).resolve().parents[1],
    )  # fmt: skip
    lines = proc.stdout.split()
    assert proc.returncode == 0 and lines[-2:] == ["rc", "0"], (proc.stdout, proc.stderr)
    assert "Traceback" not in proc.stderr and "error" not in proc.stderr
    assert [r["status"] for r in _rows(tmp_path / "out")] == ["done"]
