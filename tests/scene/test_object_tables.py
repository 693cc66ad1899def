"""``[[object]]`` tables: read, checked, placed, echoed; the pair friction between objects."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from contact.errors import SceneError
from contact.scene import ObjectScene, load_scene
from contact.scene.objects import rotation_matrix

ROOT = Path(__file__).resolve().parents[2]
CUBE = (ROOT / "meshes" / "objects" / "cube.stl").as_posix()

BASE = """\
{ball}
{objects}
[[plane]]
name = "table"
point = [0.0, 0.0, -0.05]
normal = [0.0, 0.0, 1.0]
{table}

[frames]
times = [0.0]
"""

BALL = """\
[ball]
radius = 0.02
mesh_size = 0.01
{ball}
"""


def scene(tmp_path: Path, objects: str, ball: str | None = None, table: str = "") -> Path:
    path = tmp_path / "scene.toml"
    text = BASE.format(
        ball="" if ball is None else BALL.format(ball=ball), objects=objects, table=table
    )
    path.write_text(text)
    return path


def obj(**keys: str) -> str:
    lines = ["[[object]]", f'mesh = "{CUBE}"']
    lines += [f"{k} = {v}" for k, v in keys.items()]
    return "\n".join(lines) + "\n"


def test_defaults_and_echo(tmp_path: Path) -> None:
    sc = load_scene(scene(tmp_path, obj()))
    assert sc.ball is None and len(sc.objects) == 1
    o = sc.objects[0]
    assert o.name == "cube" and o.mesh == Path(CUBE)
    assert o.mesh_size is None and o.center == (0.0, 0.0, 0.0) and o.rotation == (0.0, 0.0, 0.0)
    assert (o.material.E, o.material.nu, o.material.density) == (1.0e6, 0.45, 1100.0)
    assert not o.fixed and o.follow is None and o.friction is None
    assert sc.object_names == ["cube"] and sc.free_objects == ["cube"]
    echo = json.loads(json.dumps(sc.echo()))
    assert echo["ball"] is None and echo["object"][0]["name"] == "cube"
    assert echo["object"][0]["mesh"] == CUBE


def test_keys_read(tmp_path: Path) -> None:
    text = obj(
        name='"block"', mesh_size="0.01", center="[0.0, 0.01, 0.02]", rotation="[0, 90, 0]",
        material="{ E = 2e6, nu = 0.3 }", friction="0.4", fixed="true", kind='"solid"',
    )  # fmt: skip
    o = load_scene(scene(tmp_path, text, ball="")).objects[0]
    assert (o.name, o.mesh_size, o.center, o.rotation) == (
        "block", 0.01, (0.0, 0.01, 0.02), (0.0, 90.0, 0.0)
    )
    assert (o.material.E, o.material.nu, o.material.density) == (2e6, 0.3, 1100.0)
    assert o.friction == 0.4 and o.fixed
    tf = o.placement
    assert np.allclose(tf[:3, :3] @ [0, 0, 1], [1, 0, 0]) and np.allclose(tf[:3, 3], o.center)


def test_rotation_order_is_x_then_y_then_z() -> None:
    r = rotation_matrix((90.0, 90.0, 0.0))
    # x first: z -> -y; then y: -y stays -y
    assert np.allclose(r @ [0, 0, 1], [0, -1, 0])
    assert np.allclose(rotation_matrix((0, 0, 90)) @ [1, 0, 0], [0, 1, 0])
    assert np.allclose(np.linalg.det(rotation_matrix((10, 20, 30))), 1.0)


@pytest.mark.parametrize(
    ("text", "ball", "why"),
    [
        (obj(name='"hand"'), None, "object[0].name = 'hand': reserved for a body"),
        (obj(name='"table"'), None, "object[0].name = 'table': already names another body"),
        (obj() + obj(), None, "object[1].name = 'missing': the default name 'cube' is taken"),
        (obj(colour='"red"'), None, "object[0].colour: unknown key"),
        (obj(kind='"hollow"'), None, "object[0].kind = 'hollow'"),
        (obj(mesh_size="0"), None, "object[0].mesh_size = 0"),
        (obj(rotation="[0, 400, 0]"), None, "object[0].rotation[1] = 400"),
        (obj(friction="-1"), None, "object[0].friction = -1"),
        (obj(center="[0, 0]"), None, "object[0].center"),
        (obj(follow='{ joint = "wrist", start = 0, stop = 1 }'), None,
         "object[0].follow.joint = 'wrist': an object can follow a joint only with a [hand]"),
        ('[[object]]\nmesh = "nowhere.stl"\n', None, "object[0].mesh"),
        ("", None, "a scene needs a [ball] table or [[object]] tables"),
    ],
)  # fmt: skip
def test_bad_tables_one_line(tmp_path: Path, text: str, ball: str | None, why: str) -> None:
    path = scene(tmp_path, text, ball=ball)
    with pytest.raises(SceneError) as err:
        load_scene(path)
    assert why in str(err.value) and "\n" not in str(err.value)
    assert str(path) in str(err.value)


def test_fixed_and_follow_refused() -> None:
    with pytest.raises(SceneError, match="a fixed object cannot also follow"):
        from contact.scene.model import Follow

        ObjectScene("x", Path(CUBE), fixed=True, follow=Follow("wrist", 0.0, 1.0))


@pytest.mark.parametrize(
    ("ball", "first", "second", "expected"),
    [
        ("", "", "", 0.0),
        ("friction = 0.3", "", "", 0.3),  # the ball first: its own
        ("friction = 0.3", 'friction = 0.7', "", 0.3),
        ("", "friction = 0.7", "", 0.7),  # the ball gives none: the object's
        (None, "friction = 0.2", "friction = 0.9", 0.2),  # the first object's
        (None, "", "friction = 0.9", 0.9),  # the first gives none: the second's
    ],
)  # fmt: skip
def test_the_pair_between_objects_takes_the_first_s_else_the_other_s(
    tmp_path: Path, ball: str | None, first: str, second: str, expected: float
) -> None:
    text = obj(name='"a"', **dict([first.split(" = ")]) if first else {})
    if ball is None:
        text += obj(name='"b"', **dict([second.split(" = ")]) if second else {})
        names = ("a", "b")
    else:
        names = ("ball", "a")
    sc = load_scene(scene(tmp_path, text, ball=ball))
    assert sc.friction(names[1], names[0]) == sc.friction(names[0], names[1]) == expected
    assert sc.frictional == (expected > 0)


def test_a_plane_takes_its_own_else_the_object_s(tmp_path: Path) -> None:
    sc = load_scene(scene(tmp_path, obj(friction="0.4")))
    assert sc.friction("table", "cube") == 0.4
    sc = load_scene(scene(tmp_path, obj(friction="0.4"), table="friction = 0.1"))
    assert sc.friction("table", "cube") == 0.1
    with pytest.raises(KeyError):
        sc.friction("table", "nothing")
