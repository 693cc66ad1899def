"""A renderer failure costs the pictures, not the results: the run writes them and exits 0."""

import json
import os

import pytest

import contact.output.pictures
import contact.rendering
from contact.grasp import main

SCENE = """
[ball]
radius = 0.02
kind = "solid"
element = "hex"
mesh_size = 0.006
center = [0.0, 0.0, 0.02]
material = {{ E = 1.0e6, nu = 0.3 }}

[[plane]]
name = "table"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]

[[plane]]
name = "plate"
point = [0.0, 0.0, 0.04]
normal = [0.0, 0.0, -1.0]
offsets = [[0.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, -0.002]]

[frames]
times = [0.5, 1.0]

[output]
directory = "{out}"
pictures = true
gif = true
"""


def _abort(*args):
    """The renderer's process dies as a VTK abort kills it."""
    os.abort()


def _raise(*args, **kwargs):
    raise RuntimeError("VTK exploded")


@pytest.mark.parametrize("how", ["raises", "dies"])
def test_a_renderer_failure_leaves_complete_results(tmp_path, monkeypatch, caplog, how):
    out = tmp_path / "results"
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE.format(out=out.as_posix()))
    monkeypatch.setattr(contact.rendering, "rendering_available", lambda: (True, "ok"))
    if how == "raises":
        monkeypatch.setattr(contact.rendering, "run_in_child", _raise)
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
