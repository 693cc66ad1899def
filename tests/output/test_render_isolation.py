"""A renderer failure costs the pictures, not the results: the run writes them and exits 0."""

import json
import os

import pytest

import contact.output.pictures
import contact.output.rendering
from contact.grasp import main
from tests.helpers import plates_scene


def _abort(*args):
    """The renderer's process dies as a VTK abort kills it."""
    os.abort()


def _raise(*args, **kwargs):
    raise RuntimeError("VTK exploded")


@pytest.mark.parametrize("how", ["raises", "dies"])
def test_a_renderer_failure_leaves_complete_results(tmp_path, monkeypatch, caplog, how):
    out = tmp_path / "results"
    scene = plates_scene(tmp_path / "scene.toml", out, pictures=True)
    monkeypatch.setattr(contact.output.rendering, "rendering_available", lambda: (True, "ok"))
    if how == "raises":
        monkeypatch.setattr(contact.output.rendering, "run_in_child", _raise)
    else:  # a child that dies: the function it runs aborts
        monkeypatch.setattr(contact.output.pictures, "_render_all", _abort)
    assert main([str(scene), "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["pictures"].startswith("skipped: rendering failed: ")
    assert len(summary["frames"]) == 2 and "gif" not in summary["files"]
    for name in ("ball_0000.vtu", "ball_0001.vtu", "ball.pvd", "forces.png", "convergence.png"):
        assert (out / name).is_file()
    assert not (out / "frames").exists()
    lines = [r.getMessage() for r in caplog.records if "pictures" in r.getMessage()]
    assert len(lines) == 1 and lines[0].startswith("pictures not written: ")
    assert ("VTK exploded" if how == "raises" else "SIGABRT") in lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results", "scene.toml"]
