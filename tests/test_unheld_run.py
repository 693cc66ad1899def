"""A run whose free body is not held stops there: exit 1, everything written, the rest not solved.

A free ball pinched by two force-driven pads (2 N each, mu 0.5: they carry 2 N along z)
is held at t = 0 under its weight alone, not at t = 0.5 once its load passes what the pads
carry; the frame at t = 1 is not solved, and ``summary.json``, stdout and stderr say why.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import contact.run
from contact.app.report import SUMMARY_KEYS, parse_line
from contact.app.unheld import NOT_SOLVED_KEYS, closing_line, not_solved, not_solved_message
from contact.grasp import main

PADS = """\
[scene]
gravity = [0.0, 0.0, -9.81]

[ball]
radius = 0.02
element = "hex"
mesh_size = 0.006
material = {{ E = 1.0e6, nu = 0.3, density = 1100.0 }}
load = [[0.0, 0, 0, 0, 0, 0, 0], [1.0, 0, 0, -4.0, 0, 0, 0]]

[[plane]]
name = "left"
point = [-0.0205, 0.0, 0.0]
normal = [1.0, 0.0, 0.0]
force = [[0.0, 2.0]]
friction = 0.5

[[plane]]
name = "right"
point = [0.0205, 0.0, 0.0]
normal = [-1.0, 0.0, 0.0]
force = [[0.0, 2.0]]
friction = 0.5

[frames]
times = [0.0, 0.5, 1.0]

[output]
directory = "{out}"
pictures = false
"""


@pytest.fixture
def solved_times(monkeypatch: pytest.MonkeyPatch) -> list[float]:
    """The times :meth:`GraspRun.frame` is asked to solve, in order."""
    times: list[float] = []
    frame = contact.run.GraspRun.frame

    def spy(self, t, callback=None):
        times.append(t)
        return frame(self, t, callback)

    monkeypatch.setattr(contact.run.GraspRun, "frame", spy)
    return times


def scene(tmp_path: Path) -> tuple[Path, Path]:
    out = tmp_path / "results"
    path = tmp_path / "pads.toml"
    path.write_text(PADS.format(out=out.as_posix()))
    return path, out


def test_the_run_stops_at_the_first_frame_not_held(tmp_path, capsys, solved_times):
    path, out = scene(tmp_path)
    assert main([str(path), "--no-pictures"]) == 1
    assert solved_times == [0.0, 0.5]  # nothing set up from where the lost ball was left
    summary = json.loads((out / "summary.json").read_text())
    assert [f["index"] for f in summary["frames"]] == [0, 1]
    assert [f["held"] for f in summary["frames"]] == [True, False]
    assert not summary["all_realistic"] and not summary["all_converged"]
    (rec,) = summary["not_solved"]
    assert (rec["index"], rec["time"]) == (2, 1.0)
    assert rec["reason"].startswith("not solved: the body was lost at frame 1 (t = 0.5)")
    assert "not held: ball slips along (" in rec["reason"]
    std = capsys.readouterr()
    lines = std.out.strip().splitlines()
    assert len(lines) == 4  # two frames, the frames not solved, the closing line
    line = parse_line(lines[2])
    assert tuple(line) == NOT_SOLVED_KEYS
    assert (line["not_solved"], line["t"], line["why"]) == ("2", "1", rec["reason"])
    end = parse_line(lines[3])
    assert (end["frames"], end["verdict"]) == ("2", "unrealistic")
    err = std.err.strip().splitlines()
    assert f"frame 2 (t = 1): {rec['reason']}" in err and err[-1] == f"results in {out}"


def test_a_replayed_frame_not_held_stops_the_frames_asked_for_after_it(
    tmp_path, capsys, solved_times
):
    # with friction --frames 0 2 replays frame 1, which loses the ball: frame 2 not solved
    path, out = scene(tmp_path)
    assert main([str(path), "--no-pictures", "--frames", "0", "2"]) == 1
    assert solved_times == [0.0, 0.5]
    summary = json.loads((out / "summary.json").read_text())
    assert [f["index"] for f in summary["frames"]] == [0]
    assert summary["frames"][0]["verdict"]["realistic"]
    assert not summary["all_realistic"]
    assert [r["index"] for r in summary["not_solved"]] == [2]
    lines = capsys.readouterr().out.strip().splitlines()
    assert parse_line(lines[-1])["verdict"] == "unrealistic"


def test_the_records_and_lines_of_frames_not_solved():
    class Lost:
        stop_reason = "not held: egg slips along (0.000, 0.000, -1.000): 0.2 N ..."
        held = False

    recs = not_solved(1, 0.5, Lost(), [(2, 1.0), (3, 1.5)])  # type: ignore[arg-type]
    assert [(r["index"], r["time"]) for r in recs] == [(2, 1.0), (3, 1.5)]
    assert recs[0]["reason"] == (
        "not solved: the body was lost at frame 1 (t = 0.5), where the run stopped: "
        + Lost.stop_reason
    )
    assert not_solved_message(recs).startswith("frames 2, 3 (t = 1, 1.5): not solved: ")
    entry = {"converged": True, "held": True, "verdict": {"realistic": True}}
    assert parse_line(closing_line([entry], "out dir", []))["verdict"] == "realistic"
    end = parse_line(closing_line([entry], "out dir", recs))
    assert tuple(end) == SUMMARY_KEYS
    assert (end["verdict"], end["results"], end["frames"]) == ("unrealistic", "out dir", "1")


def test_a_later_frame_that_cannot_be_set_up_keeps_the_frames_before(
    tmp_path, capsys, monkeypatch
):
    # the motion brings the run where a frame cannot be set up (a bone the keyframes close
    # through where the ball went): exit 2, what was solved is written, the rest not solved
    from contact.errors import InputError

    frame = contact.run.GraspRun.frame

    def closing_through(self, t, callback=None):
        if t == 0.5:
            raise InputError("frame t = 0.5: the ball starts inside bone index_distal")
        return frame(self, t, callback)

    monkeypatch.setattr(contact.run.GraspRun, "frame", closing_through)
    path, out = scene(tmp_path)
    assert main([str(path), "--no-pictures"]) == 2
    summary = json.loads((out / "summary.json").read_text())
    assert [f["index"] for f in summary["frames"]] == [0]
    assert not summary["all_converged"] and not summary["all_realistic"]
    assert [(r["index"], r["time"]) for r in summary["not_solved"]] == [(1, 0.5), (2, 1.0)]
    why = summary["not_solved"][0]["reason"]
    assert why.startswith("not solved: the frame at t = 0.5 could not be set up: ")
    std = capsys.readouterr()
    assert parse_line(std.out.strip().splitlines()[-1])["verdict"] == "unrealistic"
    err = std.err.strip().splitlines()
    assert err[0] == f"error: {path}: frame t = 0.5: the ball starts inside bone index_distal"
    assert "Traceback" not in std.err and err[-1] == f"results in {out}"
    # at the first frame it is the scene's own bad input: nothing written
    monkeypatch.setattr(
        contact.run.GraspRun, "frame", lambda self, t, callback=None: closing_through(self, 0.5)
    )
    out.rename(tmp_path / "kept")
    assert main([str(path), "--no-pictures"]) == 2
    assert not out.exists()
