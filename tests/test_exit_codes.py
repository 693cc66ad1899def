"""Exit statuses of ``python -m contact.grasp``: 0, 1, 2, 3, 4, 130, 143, and what stderr says."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import contact.app.cli
import contact.grasp
from contact.errors import OutputError
from contact.grasp import main
from tests.helpers import plates_scene

ROOT = Path(__file__).resolve().parents[1]



def scene(tmp_path, iterations=30, times=(0.5, 1.0), out=None):
    out = out or tmp_path / "results"
    return plates_scene(tmp_path / "scene.toml", out, times=times, iterations=iterations), out


def one_line(err: str) -> str:
    err = err.strip()
    assert "\n" not in err and "Traceback" not in err, err
    return err


def test_exit_0_and_the_epilog_lists_every_status(tmp_path, capsys):
    path, _ = scene(tmp_path)
    assert main([str(path), "--quiet"]) == 0
    assert capsys.readouterr().err == ""
    for code in ("0 every", "1 a frame", "2 bad input", "3 an internal", "4 an I/O", "130", "143"):
        assert code in contact.grasp.EXIT_STATUS


def test_exit_1_names_the_frames_that_failed_and_the_folder(tmp_path, capsys, monkeypatch):
    import contact.solver.contactset

    monkeypatch.setattr(contact.solver.contactset, "NEAR", 0.0)
    path, out = scene(tmp_path, iterations=1)
    assert main([str(path)]) == 1
    lines = capsys.readouterr().err.strip().splitlines()
    summary = json.loads((out / "summary.json").read_text())
    failed = [f for f in summary["frames"] if not f["verdict"]["realistic"]]
    assert failed and len(lines) == len(failed) + 1
    for line, f in zip(lines, failed, strict=False):
        assert line.startswith(f"frame {f['index']} (t = ") and f["verdict"]["reason"] in line
    assert lines[-1] == f"results in {out}"
    assert main([str(path), "--quiet"]) == 1
    assert capsys.readouterr().err == ""


def test_exit_2_bad_input_and_a_frame_asked_twice(tmp_path, capsys):
    path, out = scene(tmp_path)
    path.write_text(path.read_text().replace("radius = 0.02", "radius = -0.02"))
    assert main([str(path), "--quiet"]) == 2
    assert "ball.radius" in one_line(capsys.readouterr().err)
    path, out = scene(tmp_path)
    assert main([str(path), "--quiet", "--frames", "0", "0"]) == 2
    assert "asked for twice" in one_line(capsys.readouterr().err)
    assert not out.exists()


def test_exit_2_leaves_no_parent_folder_it_created(tmp_path, capsys, monkeypatch):
    deep = tmp_path / "a" / "b" / "results"
    path, _ = scene(tmp_path, out=deep)

    def bad(*args, **kwargs):
        raise contact.grasp.SceneError("bad input found after start-up")

    monkeypatch.setattr(contact.grasp.GraspRun, "frame", bad)
    assert main([str(path), "--quiet"]) == 2
    assert "after start-up" in one_line(capsys.readouterr().err)
    assert not (tmp_path / "a").exists()


def test_exit_3_internal_error_one_line_and_a_log(tmp_path, capsys, monkeypatch):
    path, out = scene(tmp_path)

    def boom(*args, **kwargs):
        raise KeyError("a bug")

    monkeypatch.setattr(contact.grasp.GraspRun, "frame", boom)
    assert main([str(path), "--quiet"]) == 3
    err = one_line(capsys.readouterr().err)
    assert "internal error: KeyError" in err
    log = Path(err.split("traceback in ")[1].split(";")[0])
    try:
        assert "Traceback" in log.read_text() and "a bug" in log.read_text()
    finally:
        log.unlink()
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["scene.toml"]


@pytest.mark.parametrize("where", ["start", "swap"])
def test_exit_4_io_failure(tmp_path, capsys, monkeypatch, where):
    path, out = scene(tmp_path)
    assert main([str(path), "--quiet"]) == 0
    before = (out / "summary.json").read_bytes()
    import contact.output.staging as staging

    def full(*args, **kwargs):
        raise OSError(28, "No space left on device")

    if where == "start":
        monkeypatch.setattr(staging.Staging, "__init__", lambda self, *a: full())
    else:
        monkeypatch.setattr(staging.os, "rename", full)
    assert main([str(path), "--quiet"]) == 4
    err = one_line(capsys.readouterr().err)
    assert "No space left" in err or "results folder" in err
    assert (out / "summary.json").read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results", "scene.toml"]


def test_exit_4_output_error_is_an_io_failure_not_bad_input():
    from contact.errors import TargetError

    assert issubclass(TargetError, OutputError)


@pytest.mark.parametrize(("sig", "code"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_signal_leaves_the_previous_results(tmp_path, sig, code):
    path, out = scene(tmp_path)
    assert main([str(path), "--quiet"]) == 0
    before = (out / "summary.json").read_bytes()
    path, out = scene(tmp_path, times=[0.01 * (k + 1) for k in range(100)])
    proc = subprocess.Popen(
        [sys.executable, "-m", "contact.grasp", str(path), "--quiet"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 60
    while not list(tmp_path.glob(".results.staging-*")):  # the run has started writing
        assert proc.poll() is None and time.monotonic() < deadline
        time.sleep(0.05)
    time.sleep(0.3)
    os.kill(proc.pid, sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == code, err
    assert err.strip() == "interrupted; the previous results are untouched"
    assert (out / "summary.json").read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results", "scene.toml"]


def test_a_sigterm_whose_exception_was_swallowed_still_stops_the_run(
    tmp_path, capsys, monkeypatch
):
    # a SIGTERM that lands in a callback whose exceptions Python ignores (a weakref's) leaves
    # only its mark: the next frame stops the run all the same, the previous results kept
    from contact.run import GraspRun

    path, out = scene(tmp_path)
    assert main([str(path), "--quiet"]) == 0
    before = (out / "summary.json").read_bytes()
    frame = GraspRun.frame

    def frame_then_signal(self, *args, **kwargs):
        result = frame(self, *args, **kwargs)
        contact.app.cli.SIGNALLED.append(signal.SIGTERM)  # the handler ran; its raise was lost
        return result

    monkeypatch.setattr(GraspRun, "frame", frame_then_signal)
    assert main([str(path), "--quiet"]) == 143
    assert capsys.readouterr().err.strip() == "interrupted; the previous results are untouched"
    assert (out / "summary.json").read_bytes() == before
