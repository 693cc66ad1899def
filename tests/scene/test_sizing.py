"""A scene's size before allocation, physical bounds, frame times, window size, one-line input."""

from __future__ import annotations

import logging
import math
import time
import warnings
from pathlib import Path

import meshio
import numpy as np
import pytest

import fem
from contact.grasp import main
from contact.objects.ball import BallSpec, make_ball
from contact.scene import SceneError, load_scene, sizing
from contact.scene.bounds import FRAME_TIME_TOL, frame_time

SCENE = """\
[scene]
gravity = {gravity}

[ball]
radius = {radius}
element = "{element}"
mesh_size = {mesh_size}
center = [0.0, 0.0, 0.02]
material = {{ E = {E} }}

[[plane]]
name = "table"
point = [0.0, 0.0, 0.0]
normal = {normal}

[frames]
count = {count}

[output]
directory = "out"
pictures = false
{output}
"""
DEFAULTS = dict(
    gravity="[0.0, 0.0, -9.81]", radius=0.02, element="hex", mesh_size=0.006, E=1.0e6,
    normal="[0.0, 0.0, 1.0]", count=2, output="",
)  # fmt: skip


@pytest.fixture
def scene(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    """Write a hand-free scene with some keys changed; the working directory is tmp_path."""
    monkeypatch.chdir(tmp_path)

    def write(**changes: object) -> Path:
        path = tmp_path / "scene.toml"
        path.write_text(SCENE.format(**{**DEFAULTS, **changes}))
        return path

    return write


# ----------------------------------------------------------------------------- estimates


@pytest.mark.parametrize(
    "kind, radius, size",
    [("solid", 0.02, 0.006), ("solid", 0.03, 0.004), ("hollow", 0.035, 0.004)],
)
def test_brick_counts_are_exact(kind: str, radius: float, size: float) -> None:
    extra = {"thickness": 0.006} if kind == "hollow" else {}
    spec = BallSpec(radius=radius, kind=kind, element="hex", mesh_size=size, **extra)
    mesh = make_ball(spec).mesh
    nodes, elements = sizing.ball_size(spec)
    assert (nodes, elements) == (mesh.n_points, sum(len(c) for c in mesh.cells.values()))


def test_tet_counts_are_an_upper_bound() -> None:
    spec = BallSpec(radius=0.02, element="tet", mesh_size=0.006)
    mesh = make_ball(spec).mesh
    nodes, elements = sizing.ball_size(spec)
    real = sum(len(c) for c in mesh.cells.values())
    assert real <= elements <= 2.5 * real
    assert mesh.n_points <= nodes <= 2.5 * mesh.n_points


def test_hand_size_matches_the_shipped_meshes() -> None:
    from contact.hand.shipped import HAND_DIR

    for res, (nodes, elements) in sizing.HAND_SIZE.items():
        m = fem.read_mesh(HAND_DIR / f"flesh_{res}.vtu")
        assert (m.n_points, sum(len(c) for c in m.cells.values())) == (nodes, elements)


def test_memory_grows_faster_than_the_dofs() -> None:
    small = sizing.estimate(BallSpec(radius=0.02, element="hex", mesh_size=0.002), None, 1)
    big = sizing.estimate(BallSpec(radius=0.02, element="hex", mesh_size=0.0005), None, 1)
    assert big.memory - sizing.BASE_BYTES > 64 * (small.memory - sizing.BASE_BYTES)
    assert small.memory < 2e9  # what runs here today stays well within a laptop


# --------------------------------------------------------------- the oversize cases


@pytest.mark.parametrize(
    "changes, key",
    [
        ({"mesh_size": 1e-4}, "ball.mesh_size"),
        ({"mesh_size": 1e-6, "element": "tet"}, "ball.mesh_size"),
        ({"mesh_size": 1e-6}, "ball.mesh_size"),
        ({"mesh_size": 1e-300}, "ball.mesh_size"),
        ({"count": 10**9}, "frames.count"),
    ],
)
def test_oversize_scene_refused_fast(scene, capsys, changes: dict, key: str) -> None:
    path = scene(**changes)
    start = time.perf_counter()
    assert main([str(path), "--quiet"]) == 2
    assert time.perf_counter() - start < 1.0
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and key in err
    assert "of memory" in err and "available" in err
    assert not Path("out").exists()


def test_refused_against_the_machine(scene, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sizing, "available_memory", lambda: 1e8)
    with pytest.raises(SceneError, match=r"ball\.mesh_size = 0\.006: too big.*100 MB available"):
        load_scene(scene())
    monkeypatch.setattr(sizing, "available_memory", lambda: None)  # unknown: not refused
    load_scene(scene())


def test_big_scene_warns(scene, monkeypatch: pytest.MonkeyPatch, caplog) -> None:
    monkeypatch.setattr(sizing, "WARN_DOFS", 100)
    with caplog.at_level(logging.WARNING):
        load_scene(scene())
    (record,) = [r for r in caplog.records if "a big scene" in r.getMessage()]
    assert "\n" not in record.getMessage()
    caplog.clear()
    monkeypatch.setattr(sizing, "WARN_DOFS", 10**9)
    with caplog.at_level(logging.WARNING):
        load_scene(scene())
    assert not [r for r in caplog.records if "a big scene" in r.getMessage()]


# ------------------------------------------------------------------------- physical bounds


@pytest.mark.parametrize(
    "changes, key",
    [
        ({"radius": 1e308}, "ball.radius = 1e+308"),
        ({"E": 1e308}, "ball.material.E = 1e+308"),
        ({"E": 1e-300}, "ball.material.E = 1e-300"),
        ({"gravity": "[0.0, 0.0, -1e308]"}, "scene.gravity[2] = -1e+308"),
        ({"gravity": "[900.0, 900.0, 0.0]"}, "scene.gravity = [900.0, 900.0, 0.0]"),
        ({"output": "window_size = [100000, 600]"}, "output.window_size[0] = 100000"),
        ({"output": "window_size = [640, 8]"}, "output.window_size[1] = 8"),
    ],
)
def test_magnitudes_outside_bounds_refused(scene, capsys, changes: dict, key: str) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no numpy warning before the error
        assert main([str(scene(**changes)), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and key in err, err


def test_huge_plane_normal_is_normalised(scene) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        s = load_scene(scene(normal="[1e200, 0.0, 1e200]"))
    assert np.allclose(s.planes[0].normal, [math.sqrt(0.5), 0.0, math.sqrt(0.5)])


def test_window_size_within_bounds_loads(scene) -> None:
    assert load_scene(scene(output="window_size = [64, 4096]")).output.window_size == (64, 4096)


# ------------------------------------------------------------------------------- frame times


HAND = """\
[ball]
radius = 0.03
kind = "hollow"
thickness = 0.003
element = "hex"
mesh_size = 0.006
center = [0.0, 0.09, -0.06]

[hand]
[[hand.keyframe]]
time = 0.0
angles = {{}}
{more_keys}
[[hand.auto_flexion]]
joint = "index_pip"
point = "index"
times = [{auto}]

[frames]
{frames}
"""


def test_auto_flexion_time_stored_as_the_frame_time(tmp_path: Path) -> None:
    p = tmp_path / "s.toml"
    key = "[[hand.keyframe]]\ntime = 1.0\nangles = {}\n"
    near = 0.3 + 0.5e-9
    p.write_text(HAND.format(more_keys=key, auto=repr(near), frames="times = [0.0, 0.3, 1.0]"))
    (af,) = load_scene(p).hand.auto_flexion
    assert af.times == (0.3,)  # the frame time itself: the run's exact match holds
    far = 0.3 + 3 * FRAME_TIME_TOL
    p.write_text(HAND.format(more_keys=key, auto=repr(far), frames="times = [0.0, 0.3, 1.0]"))
    with pytest.raises(SceneError, match=r"times\[0\] = 0\.3.*not one of the frame times"):
        load_scene(p)
    assert frame_time(1.0 + 1e-10, (0.0, 1.0)) == 1.0 and frame_time(0.5, (0.0, 1.0)) is None


def test_count_over_one_keyframe_refused(tmp_path: Path) -> None:
    p = tmp_path / "s.toml"
    p.write_text(HAND.format(more_keys="", auto="0.0", frames="count = 3"))
    with pytest.raises(SceneError, match=r"frames\.count = 3: the keyframes span no time"):
        load_scene(p)
    p.write_text(HAND.format(more_keys="", auto="0.0", frames="count = 1"))
    assert load_scene(p).frames == (0.0,)


# ------------------------------------------------------------------ one line on bad input


def test_surface_files_read_without_warnings(tmp_path: Path) -> None:
    pts, tri = fem.sphere_surface(0.02, (0.0, 0.0, 0.0), 2)
    meshio.write(tmp_path / "s.stl", meshio.Mesh(pts, [("triangle", tri)]))
    meshio.write(tmp_path / "s.vtu", meshio.Mesh(pts, [("triangle", tri)]))
    from fem.meshing import _load_surface

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(fem.NoVolumeCellsError):
            fem.read_mesh(tmp_path / "s.stl")
        _, t, _ = _load_surface(tmp_path / "s.vtu")
    assert len(t) == len(tri)
