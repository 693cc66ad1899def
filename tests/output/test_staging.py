"""The results folder's marker, refusals and the leftovers of dead runs."""

import json
import os
import subprocess
import sys

import pytest

from contact.errors import OutputError, TargetError
from contact.output.staging import MARKER, Staging, check_target, clean_leftovers, make_staging


def written(directory, files=("summary.json", "a_0000.vtu"), kind="results"):
    """A folder as a finished run leaves it (through a real staging and swap)."""
    stage = make_staging(directory, kind)
    for f in files:
        (stage.path / f).parent.mkdir(exist_ok=True)
        (stage.path / f).write_text(f"new {f}")
    stage.swap()
    return directory


def siblings(directory):
    return sorted(p.name for p in directory.parent.iterdir())


def test_marker_lists_what_was_written_and_the_folder_is_replaced(tmp_path):
    d = written(tmp_path / "res", ("summary.json", "frames/frame_0000.png"))
    doc = json.loads((d / MARKER).read_text())
    assert doc["program"] == "grasp-contact" and doc["kind"] == "results" and doc["version"]
    assert doc["files"] == ["frames/frame_0000.png", "summary.json"]
    written(d, ("summary.json",))
    assert sorted(p.name for p in d.iterdir()) == [MARKER, "summary.json"]
    assert siblings(d) == ["res"]


def test_a_user_file_inside_makes_the_folder_refused_and_kept(tmp_path):
    d = written(tmp_path / "res")
    (d / "notes.txt").write_text("precious")
    with pytest.raises(TargetError, match=r"notes\.txt.*move it out") as info:
        make_staging(d)
    assert "\n" not in str(info.value)
    assert (d / "notes.txt").read_text() == "precious" and (d / "summary.json").is_file()
    assert siblings(d) == ["res"]


def test_an_old_results_folder_without_marker_is_refused(tmp_path):
    d = tmp_path / "res"
    d.mkdir()
    (d / "summary.json").write_text("{}")
    (d / "scene.toml").write_text("kept")
    with pytest.raises(TargetError, match="older version"):
        check_target(d)
    other = tmp_path / "home"
    other.mkdir()
    (other / "thesis.tex").write_text("x")
    with pytest.raises(TargetError, match="not a results folder"):
        check_target(other)
    pose = written(tmp_path / "pose", ("pose.json",), kind="pose")
    with pytest.raises(TargetError, match="a pose folder"):
        check_target(pose, "results")
    assert (d / "scene.toml").read_text() == "kept"


def test_a_user_file_added_during_the_run_is_a_lost_race(tmp_path):
    d = written(tmp_path / "res")
    stage = make_staging(d)
    (stage.path / "summary.json").write_text("{}")
    (d / "notes.txt").write_text("precious")
    with pytest.raises(OutputError, match="changed during this run"):
        stage.swap()
    stage.discard()
    assert (d / "notes.txt").read_text() == "precious"
    assert siblings(d) == ["res"]


def test_stale_staging_is_cleaned_a_live_one_kept(tmp_path, caplog):
    d = written(tmp_path / "res")
    # a dead run: its staging folder and (unlocked) lock file
    (tmp_path / ".res.staging-dead").mkdir()
    (tmp_path / ".res.staging-dead" / "ball_0000.vtu").write_text("x")
    (tmp_path / ".res.lock-dead").write_text("123\n")
    # a dead run of an older version: no lock file
    (tmp_path / ".res.staging-older").mkdir()
    # a live run in another process: it holds its lock
    code = (
        "import sys, time; from pathlib import Path; from contact.output.staging import Staging;"
        f"s = Staging(Path({str(tmp_path / 'res')!r})); print(s.path.name, flush=True);"
        "sys.stdin.read()"
    )
    live = subprocess.Popen(
        [sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    try:
        name = live.stdout.readline().strip()
        done = clean_leftovers(d)
        assert sorted(done) == ["removed .res.staging-dead", "removed .res.staging-older"]
        assert "cleaned what an earlier run left" in caplog.text
        assert name in siblings(d) and f".res.lock-{name.rsplit('-', 1)[1]}" in siblings(d)
    finally:
        live.communicate("")
    assert (d / "summary.json").is_file()


def test_a_half_done_swap_is_restored_or_removed(tmp_path):
    d = written(tmp_path / "res")
    before = {p.name: p.read_bytes() for p in d.iterdir()}
    os.rename(d, tmp_path / ".res.old-abc")  # killed between the two renames
    assert clean_leftovers(d) == ["restored res from .res.old-abc"]
    assert {p.name: p.read_bytes() for p in d.iterdir()} == before
    # the new one was put in place too: the old one goes, and only its listed files
    old = written(tmp_path / ".res.old-def")
    (old / "notes.txt").write_text("kept")
    assert clean_leftovers(d) == []
    assert sorted(p.name for p in old.iterdir()) == ["notes.txt"]
    assert (d / "summary.json").is_file()


def test_discard_removes_the_parents_it_created(tmp_path):
    stage = Staging(tmp_path / "a" / "b" / "res")
    assert stage.path.is_dir()
    stage.discard()
    assert list(tmp_path.iterdir()) == []
