"""Friction in scenes: the ``friction`` keys, each interface's coefficient, the history.

The keys (``[[plane]]``, ``[hand]``, ``[ball]``) and their checks; the rule that gives a
pair its coefficient (its master's where the master's table gives one, else the ball's,
the same both ways); the seed loop refused with friction; the stick anchors carried from
frame to frame; ``--frames`` replaying the history before the frames it writes.
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import contact.grasp
import contact.run.grasprun
from contact.grasp import main
from contact.run import GraspRun
from contact.scene import HandScene, PlaneScene, Scene, SceneError, load_scene

ROOT = Path(__file__).resolve().parents[1]

#: A free ball pinched by two pads, gravity along them: tiny, so that it solves in seconds.
PINCH = """\
[scene]
gravity = [0.0, 0.0, -9.81]

[ball]
radius = 0.02
element = "hex"
mesh_size = 0.006
material = {{ E = 1.0e6, nu = 0.3 }}
{ball}

[[plane]]
name = "left"
point = [-0.02, 0.0, 0.0]
normal = [1.0, 0.0, 0.0]
offsets = [[0.0, 0.0, 0.0, 0.0], [1.0, 0.001, 0.0, 0.0]]
{left}

[[plane]]
name = "right"
point = [0.02, 0.0, 0.0]
normal = [-1.0, 0.0, 0.0]
offsets = [[0.0, 0.0, 0.0, 0.0], [1.0, -0.001, 0.0, 0.0]]
{right}

[frames]
times = [0.5, 0.75, 1.0]

[solver]
algorithm = "{algorithm}"

[output]
directory = "{out}"
pictures = false
"""

HAND = """\
[ball]
radius = 0.01
element = "hex"
mesh_size = 0.004
center = [0.0, 0.06, -0.1]
{ball}

[hand]
resolution = "coarse"
{hand}

[[hand.keyframe]]
time = 0.0
angles = {{}}

[[plane]]
name = "table"
point = [0.0, 0.0, -0.2]
normal = [0.0, 0.0, 1.0]
{left}

[frames]
times = [0.0]
"""


def pinch(
    tmp_path: Path,
    ball: str = "",
    left: str = "friction = 0.5",
    right: str = "friction = 0.5",
    algorithm: str = "contact-space",
    name: str = "pinch.toml",
) -> Path:
    """The pinch scene with the given ``friction`` lines, written to ``tmp_path``."""
    path = tmp_path / name
    out = (tmp_path / "results").as_posix()
    path.write_text(PINCH.format(ball=ball, left=left, right=right, algorithm=algorithm, out=out))
    return path


def hand_scene(tmp_path: Path, ball: str = "", hand: str = "", left: str = "") -> Path:
    path = tmp_path / "hand.toml"
    path.write_text(HAND.format(ball=ball, hand=hand, left=left))
    return path


# --- the keys ---------------------------------------------------------------------


def test_defaults_frictionless(tmp_path: Path) -> None:
    scene = load_scene(hand_scene(tmp_path))
    assert scene.ball_friction is None and Scene.ball_friction is None
    assert scene.hand.friction is None and HandScene.friction is None
    assert scene.planes[0].friction is None and PlaneScene.friction is None
    assert scene.friction("hand") == scene.friction("table") == 0.0
    assert not scene.frictional
    echo = scene.echo()
    assert echo["ball"]["friction"] is None
    assert echo["hand"]["friction"] is None and echo["plane"][0]["friction"] is None


def test_keys_read_and_echoed(tmp_path: Path) -> None:
    path = hand_scene(tmp_path, ball="friction = 0.3", hand="friction = 1", left="friction = 0")
    scene = load_scene(path)
    assert (scene.ball_friction, scene.hand.friction, scene.planes[0].friction) == (0.3, 1.0, 0.0)
    assert isinstance(scene.hand.friction, float)
    echo = json.loads(json.dumps(scene.echo()))
    assert echo["ball"]["friction"] == 0.3
    assert echo["hand"]["friction"] == 1.0 and echo["plane"][0]["friction"] == 0.0
    assert scene.frictional


@pytest.mark.parametrize(
    ("where", "value", "why"),
    [
        ("left", "-0.1", "plane[0].friction = -0.1: must be a finite number >= 0"),
        ("right", '"0.5"', "plane[1].friction = '0.5': must be a number"),
        ("right", "inf", "plane[1].friction = inf: must be finite"),
        ("left", "nan", "plane[0].friction = nan: must be finite"),
        ("left", "true", "plane[0].friction = True: must be a number"),
        ("ball", "-1", "ball.friction = -1.0: must be a finite number >= 0"),
        ("ball", "-inf", "ball.friction = -inf: must be finite"),
        ("ball", "[0.5]", "ball.friction = [0.5]: must be a number"),
    ],
)
def test_bad_values_one_line_naming_file_and_key(
    tmp_path: Path, where: str, value: str, why: str
) -> None:
    path = pinch(tmp_path, **{where: f"friction = {value}"})
    with pytest.raises(SceneError) as err:
        load_scene(path)
    text = str(err.value)
    assert text == f"{path}: {why}"
    assert "\n" not in text


@pytest.mark.parametrize(
    ("hand", "why"),
    [
        ("friction = -2", "hand.friction = -2.0: must be a finite number >= 0"),
        ('friction = "high"', "hand.friction = 'high': must be a number"),
    ],
)
def test_bad_hand_friction(tmp_path: Path, hand: str, why: str) -> None:
    path = hand_scene(tmp_path, hand=hand)
    with pytest.raises(SceneError, match="^" + str(path).replace("\\", "\\\\") + ": "):
        load_scene(path)
    with pytest.raises(SceneError) as err:
        load_scene(path)
    assert str(err.value).endswith(why)


def test_unknown_friction_key_has_a_hint(tmp_path: Path) -> None:
    path = pinch(tmp_path, left="frictin = 0.5")
    with pytest.raises(SceneError, match=r"plane\[0\]\.frictin: unknown key; did you mean"):
        load_scene(path)


def test_dataclasses_check_on_their_own() -> None:
    with pytest.raises(SceneError, match=r"^friction = -0\.5: must be a finite number >= 0$"):
        PlaneScene("p", (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), friction=-0.5)
    with pytest.raises(SceneError, match=r"^friction = inf: must be a finite number >= 0$"):
        PlaneScene("p", (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), friction=float("inf"))


# --- the pair rule ----------------------------------------------------------------


@pytest.mark.parametrize(
    ("ball", "left", "right", "expected"),
    [
        ("", "", "", (0.0, 0.0)),
        ("friction = 0.4", "", "", (0.4, 0.4)),
        ("friction = 0.4", "friction = 0.7", "", (0.7, 0.4)),
        ("friction = 0.4", "friction = 0", "friction = 1.5", (0.0, 1.5)),
        ("", "friction = 0.2", "", (0.2, 0.0)),
    ],
)
def test_a_plane_pair_takes_the_plane_s_else_the_ball_s(
    tmp_path: Path, ball: str, left: str, right: str, expected: tuple[float, float]
) -> None:
    scene = load_scene(pinch(tmp_path, ball=ball, left=left, right=right))
    assert (scene.friction("left"), scene.friction("right")) == expected
    keys = [key for _, key, _ in scene.interfaces()]
    assert keys == [
        "plane[0].friction" if left else "ball.friction",
        "plane[1].friction" if right else "ball.friction",
    ]
    with pytest.raises(KeyError, match="nowhere"):
        scene.friction("nowhere")


def test_the_hand_s_else_the_ball_s(tmp_path: Path) -> None:
    scene = load_scene(hand_scene(tmp_path, ball="friction = 0.4"))
    assert scene.friction("hand") == 0.4
    scene = load_scene(hand_scene(tmp_path, ball="friction = 0.4", hand="friction = 0.9"))
    assert scene.friction("hand") == 0.9 and scene.friction("table") == 0.4


class _Solved(Exception):
    """Raised by the stand-in solver once it has seen what it is given."""


def _record(monkeypatch: pytest.MonkeyPatch) -> list[dict]:
    """Replace ``solve_frame`` in :mod:`contact.run.grasprun`: record its pairs and anchors."""
    calls: list[dict] = []

    def fake(bodies, pairs, planes, settings, *, callback=None, anchors=None):
        token = object()
        calls.append(
            {"pairs": {p.name: p.friction for p in pairs}, "anchors": anchors, "token": token}
        )
        # a frame that stopped, the ball where it was: nothing to place anew
        u = {b.name: np.zeros((b.mesh.n_points, 3)) for b in bodies}
        return SimpleNamespace(
            timings={}, anchors=token, converged=False, stop_reason="", displacement=u,
            held=None,
        )

    monkeypatch.setattr(contact.run.grasprun, "solve_frame", fake)
    return calls


def test_the_run_builds_each_pair_with_its_coefficient(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls = _record(monkeypatch)
    run = GraspRun(load_scene(pinch(tmp_path, ball="friction = 0.25", right="")))
    run.frame(0.5)
    assert calls[0]["pairs"] == {"ball/left": 0.5, "ball/right": 0.25}


def test_both_ways_across_the_hand(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    calls = _record(monkeypatch)
    path = hand_scene(tmp_path, ball="friction = 0.4", hand="friction = 0.8", left="friction = 0")
    GraspRun(load_scene(path)).frame(0.0)
    assert calls[0]["pairs"] == {"ball/table": 0.0, "ball/hand": 0.8, "hand/ball": 0.8}


def test_anchors_are_carried_from_frame_to_frame(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls = _record(monkeypatch)
    run = GraspRun(load_scene(pinch(tmp_path)))
    assert run.anchors is None
    for t in (0.5, 0.75, 1.0):
        run.frame(t)
    assert calls[0]["anchors"] is None
    assert calls[1]["anchors"] is calls[0]["token"]
    assert calls[2]["anchors"] is calls[1]["token"]
    assert run.anchors is calls[2]["token"]


def test_substeps_solve_the_steps_between_frames(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls = _record(monkeypatch)
    moves: list[float] = []
    fake = contact.run.grasprun.solve_frame

    def spy(bodies, pairs, planes, settings, **kw):
        moves.append(float(planes[0].motion[0]))  # the left pad moves 1 mm per unit time
        return fake(bodies, pairs, planes, settings, **kw)

    monkeypatch.setattr(contact.run.grasprun, "solve_frame", spy)
    path = pinch(tmp_path)
    path.write_text(path.read_text().replace("[solver]\n", "[solver]\nsubsteps = 4\n"))
    run = GraspRun(load_scene(path))
    run.frame(0.5)  # the first frame: one step from rest
    run.frame(1.0)  # four steps from 0.5
    assert np.allclose(np.array(moves) / 1e-3, [0.5, 0.625, 0.75, 0.875, 1.0])
    for before, after in itertools.pairwise(calls):
        assert after["anchors"] is before["token"]
    # without friction nothing is sub-stepped
    calls.clear()
    moves.clear()
    frictionless = pinch(tmp_path, left="", right="", name="plain.toml")
    frictionless.write_text(
        frictionless.read_text().replace("[solver]\n", "[solver]\nsubsteps = 4\n")
    )
    run = GraspRun(load_scene(frictionless))
    run.frame(0.5)
    run.frame(1.0)
    assert len(moves) == 2


# --- the seed loop ----------------------------------------------------------------


def test_seed_with_friction_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    path = pinch(tmp_path, left="", algorithm="seed")
    with pytest.raises(SceneError) as err:
        load_scene(path)
    assert str(err.value) == (
        f"{path}: solver.algorithm = 'seed': the seed loop takes no friction "
        '(plane[1].friction = 0.5): use "contact-space" or set every friction to 0'
    )
    assert main([str(path), "--quiet"]) == 2
    line = capsys.readouterr().err.strip()
    assert "\n" not in line and "solver.algorithm" in line and str(path) in line
    assert not (tmp_path / "results").exists()


def test_seed_refused_for_the_ball_s_coefficient(tmp_path: Path) -> None:
    path = pinch(tmp_path, ball="friction = 0.3", left="", right="", algorithm="seed")
    with pytest.raises(SceneError, match=r"\(ball\.friction = 0\.3\)"):
        load_scene(path)


def test_seed_without_effective_friction_is_fine(tmp_path: Path) -> None:
    # the ball gives 0.3, but each plane says 0: no interface has friction
    path = pinch(tmp_path, ball="friction = 0.3", left="friction = 0", right="friction = 0.0")
    text = path.read_text().replace('"contact-space"', '"seed"')
    path.write_text(text)
    scene = load_scene(path)
    assert scene.solver.contact.algorithm == "seed" and not scene.frictional


# --- the history: --frames ----------------------------------------------------------


def _count_frames(monkeypatch: pytest.MonkeyPatch) -> list[float]:
    """Wrap :meth:`GraspRun.frame`: the times solved, in order."""
    solved: list[float] = []
    frame = GraspRun.frame

    def counted(self, t, callback=None):
        solved.append(t)
        return frame(self, t, callback)

    monkeypatch.setattr(GraspRun, "frame", counted)
    return solved


def test_frames_replays_the_history_with_friction(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = pinch(tmp_path)
    assert main([str(path), "--quiet", "--out", str(tmp_path / "all")]) in (0, 1)
    every = json.loads((tmp_path / "all" / "summary.json").read_text())["frames"]
    solved = _count_frames(monkeypatch)
    assert main([str(path), "--quiet", "--out", str(tmp_path / "two"), "--frames", "2"]) in (0, 1)
    assert solved == [0.5, 0.75, 1.0]  # every frame up to the one asked for, in order
    (last,) = json.loads((tmp_path / "two" / "summary.json").read_text())["frames"]
    assert last["time"] == 1.0
    assert not (tmp_path / "two" / "ball_0000.vtu").exists()
    assert (tmp_path / "two" / "ball_0002.vtu").is_file()
    # the replayed history gives the frame the whole run gave it
    for name in ("left", "right"):
        ours = last["obstacle_forces"][name]["force"]
        theirs = every[2]["obstacle_forces"][name]["force"]
        assert ours == pytest.approx(theirs, rel=1e-9, abs=1e-12)
    assert last["friction"] == every[2]["friction"] or last["friction"] is None


@pytest.fixture
def written(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Stand in for the results writer: the frame indices written, in order."""
    indices: list[int] = []

    def add_frame(self, index, time, result, bodies, planes=(), extra=None) -> dict:
        indices.append(index)
        return {"verdict": {"realistic": True, "reason": "converged"}}

    monkeypatch.setattr(contact.grasp.ResultsWriter, "add_frame", add_frame)
    monkeypatch.setattr(contact.grasp.ResultsWriter, "finish", lambda self, *a, **k: None)
    # the stand-in solves carry no forces to sum for the summary's figures
    monkeypatch.setattr(contact.grasp, "_figures", lambda *a, **k: {})
    return indices


def test_frames_written_once_in_time_order_with_friction(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, written: list[int]
) -> None:
    calls = _record(monkeypatch)
    assert main([str(pinch(tmp_path)), "--quiet", "--frames", "1", "0"]) == 0
    assert len(calls) == 2 and written == [0, 1]
    assert calls[1]["anchors"] is calls[0]["token"]


def test_frames_without_friction_solves_only_those(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, written: list[int]
) -> None:
    calls = _record(monkeypatch)
    path = pinch(tmp_path, left="", right="")
    assert main([str(path), "--quiet", "--frames", "2", "0"]) == 0
    assert len(calls) == 2 and written == [2, 0]  # as asked, as before friction


def test_help_says_frames_replay() -> None:
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), pytest.raises(SystemExit):
        main(["--help"])
    text = " ".join(buf.getvalue().split())
    assert "with friction every frame up to the last of them is solved in order" in text


def test_docs_say_the_history_rule() -> None:
    text = " ".join((ROOT / "docs" / "scene.md").read_text().split())
    assert "`--frames` replays the history" in text
    assert "`solver.substeps = n` solves each frame after the first in `n` equal steps" in text


def test_pads_example_reads() -> None:
    scene = load_scene(ROOT / "examples" / "pads.toml")
    assert scene.hand is None and len(scene.planes) == 2
    assert [scene.friction(p.name) for p in scene.planes] == [0.5, 0.5]
    assert scene.gravity is not None and scene.frictional
    n0, n1 = (p.normal for p in scene.planes)
    assert sum(a * b for a, b in zip(n0, n1, strict=True)) == -1.0  # facing each other
    assert sum(a * b for a, b in zip(n0, scene.gravity, strict=True)) == 0.0  # along the pads
    assert scene.output.pictures
    assert all(p.driven for p in scene.planes)
