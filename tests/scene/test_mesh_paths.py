"""Scene paths that cannot be followed (a symlink loop): one line naming the key, exit 2."""

from __future__ import annotations

from pathlib import Path

import pytest

from contact.errors import SceneError
from contact.grasp import main
from contact.scene import load_scene

ROOT = Path(__file__).resolve().parents[2]
CUBE = (ROOT / "meshes" / "objects" / "cube.stl").as_posix()

TABLE = """
[[plane]]
name = "table"
point = [0.0, 0.0, -0.05]
normal = [0.0, 0.0, 1.0]

[frames]
times = [0.0]
"""

SCENES = {
    "ball.mesh": '[ball]\nradius = 0.02\nmesh = "loop"\n',
    "object[0].mesh": '[[object]]\nmesh = "loop"\n',
    "hand.directory": (
        f'[[object]]\nmesh = "{CUBE}"\n\n[hand]\ndirectory = "loop"\n\n'
        "[[hand.keyframe]]\ntime = 0.0\nangles = {}\n"
    ),
    "hand.rig": (
        f'[[object]]\nmesh = "{CUBE}"\n\n[hand]\nrig = "loop"\n\n'
        "[[hand.keyframe]]\ntime = 0.0\nangles = {}\n"
    ),
}


@pytest.mark.parametrize("key", sorted(SCENES))
def test_a_symlink_loop_is_named_by_its_key(tmp_path: Path, key: str) -> None:
    (tmp_path / "loop").symlink_to("loop")
    path = tmp_path / "scene.toml"
    path.write_text(SCENES[key] + TABLE)
    with pytest.raises(SceneError) as err:
        load_scene(path)
    assert str(err.value) == f"{path}: {key} = 'loop': a symlink loop"


def test_a_symlink_loop_exits_2_with_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "loop").symlink_to("loop")
    path = tmp_path / "scene.toml"
    path.write_text(SCENES["object[0].mesh"] + TABLE)
    assert main([str(path), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"error: {path}: object[0].mesh = 'loop': a symlink loop"
