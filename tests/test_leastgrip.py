"""``--least-grip``: the search on mock trials, the scene's scaling, the CLI, the pads' proof."""

from __future__ import annotations

import json
import random
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import contact.grasp
from contact.app.report import LEAST_GRIP_KEYS, least_grip_line, parse_line
from contact.errors import SceneError
from contact.grasp import main
from contact.holding.leastgrip import (
    BOUND,
    MAX_TRIALS,
    LeastGrip,
    Trial,
    judge,
    least_grip,
    measure,
)
from contact.holding.leastgrip import search as grip_search
from contact.run import GraspRun
from contact.scene.read import load_scene
from tests.helpers import example

PADS = """
[scene]
name = "pads"
{gravity}

[ball]
radius = 0.02
kind = "solid"
element = "hex"
mesh_size = {h}
center = [0.0, 0.0, 0.0]
material = {{ E = 1.0e6, nu = 0.45, density = 1100.0 }}
friction = {mu}

[[plane]]
name = "left_pad"
point = [-0.02, 0.0, 0.0]
normal = [1.0, 0.0, 0.0]
{left}

[[plane]]
name = "right_pad"
point = [0.02, 0.0, 0.0]
normal = [-1.0, 0.0, 0.0]
{right}

[frames]
times = [1.0]

[solver]
algorithm = "contact-space"
max_iterations = 30
gaps = "{gaps}"

[output]
directory = "{out}"
pictures = false
"""

FORCE = "force = [[0.0, 1.0], [2.0, 2.0]]"
OFFSETS = "offsets = [[0.0, 0.0, 0.0, 0.0], [1.0, 0.001, 0.0, 0.0]]"
GRAVITY = "gravity = [0.0, 0.0, -9.81]"


def pads(
    tmp_path: Path, *, left=FORCE, right=FORCE, mu=0.5, gravity=GRAVITY, gaps="nodal", h=0.006
) -> Path:
    path = tmp_path / "pads.toml"
    out = (tmp_path / "results").as_posix()
    text = PADS.format(left=left, right=right, mu=mu, gravity=gravity, out=out, gaps=gaps, h=h)
    path.write_text(text)
    return path


def threshold(t: float, *, h=True, noise=0.0, offset=0.0, seed=0, other=None):
    """A mock trial: holds from scale ``t`` (times 1 +- ``noise``), ``h`` affine in s."""
    rng = random.Random(seed)
    calls: list[float] = []

    def trial(s: float) -> Trial:
        calls.append(s)
        holds = s >= t * (1 + noise * rng.uniform(-1, 1))
        if other is not None and not holds and abs(s / t - 1) < other:
            return Trial(s, False, None, 1, 1.0, "iteration limit")
        m = (s / t) * (1 + offset) - offset if h else None
        return Trial(s, holds, m, 1, None if holds else 1.0, "held" if holds else "not held: x")

    trial.calls = calls  # type: ignore[attr-defined]
    return trial


def check_bracket(out: LeastGrip, tol: float = 0.01) -> None:
    """Both ends were run: ``hi`` held, ``lo`` did not, within ``tol``."""
    ran = {t.scale: t.holds for t in out.trials}
    assert out.found and ran[out.hi] and not ran[out.lo]
    assert (out.hi - out.lo) / out.hi <= tol
    assert out.scale == out.hi and out.margin == pytest.approx(1 / out.hi)
    assert out.steps == len(out.trials)


# --- the search ---------------------------------------------------------------------


@pytest.mark.parametrize("t", [0.02, 0.362, 0.9, 1.0, 1.7, 7.3, 50.0])
def test_finds_the_threshold_to_one_percent_in_few_steps(t: float) -> None:
    out = grip_search(threshold(t))
    check_bracket(out)
    assert out.lo < t <= out.hi
    assert out.steps <= 4  # the measure proportional to the grip: two trials past the first


@pytest.mark.parametrize("offset", [-0.3, 0.3])
def test_a_measure_not_proportional_still_converges_fast(offset: float) -> None:
    out = grip_search(threshold(0.362, offset=offset))
    check_bracket(out)
    assert out.steps <= 7


@pytest.mark.parametrize("t", [0.362, 1.7, 7.3])
def test_without_a_measure_bisection_brackets_it(t: float) -> None:
    out = grip_search(threshold(t, h=False))
    check_bracket(out)
    assert out.lo < t <= out.hi
    assert out.steps <= 16


def test_the_scene_grip_slips_the_search_goes_up() -> None:
    out = grip_search(threshold(3.7))
    check_bracket(out)
    assert not out.trials[0].holds and out.scale > 1
    assert out.margin < 1  # the scene's own grip is short of the least


def test_nothing_holds_up_to_the_bound() -> None:
    trial = threshold(1000.0, h=False)
    out = grip_search(trial)
    assert out.scale is None and out.margin is None and not out.found
    assert out.note == f"no grip up to {BOUND:g}x holds"
    assert out.lo == BOUND and max(trial.calls) == BOUND
    assert out.steps == 7  # 1, 2, 4, ..., 64


def test_held_down_to_the_floor() -> None:
    out = grip_search(threshold(1e-4))
    assert out.scale == pytest.approx(1 / BOUND) and out.lo == 0.0 and not out.found
    assert "below" in out.note


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("h", [True, False])
def test_noise_near_the_threshold_does_not_loop(seed: int, h: bool) -> None:
    out = grip_search(threshold(0.8, noise=0.05, h=h, seed=seed))
    check_bracket(out)
    assert out.steps <= MAX_TRIALS
    assert 0.8 * 0.94 < out.scale < 0.8 * 1.06


def test_max_trials_stops_it() -> None:
    out = grip_search(threshold(0.8, h=False), max_trials=3)
    assert out.steps == 3 and not out.found and "stopped after 3" in out.note


def test_a_trial_that_did_not_settle_never_brackets_the_answer() -> None:
    # below the threshold, within 30 % of it, every trial stops on a solver limit
    out = grip_search(threshold(0.5, other=0.3, h=False))
    assert out.scale >= 0.5 and not out.found and out.limit == "solver"
    assert out.lo <= 0.5 * 0.7  # only a trial that slipped brackets it
    unsettled = [t for t in out.trials if t.kind == "solver"]
    assert unsettled and all(0.35 <= t.scale < 0.5 for t in unsettled)
    assert "did not settle" in out.note
    # with the cones full at the answer, friction is the limit all the same
    full = grip_search(threshold(0.5, other=0.3))
    assert full.found and full.limit == "friction"


def test_the_answer_names_its_limit() -> None:
    assert grip_search(threshold(0.362)).limit == "friction"

    def turns(s: float) -> Trial:
        if s >= 0.362:
            return Trial(s, True, s / 0.362, 1, hardest=1.0)
        return Trial(s, False, None, 1, 1.0, "ball turned 8 deg, past the 5.73 deg ...")

    assert grip_search(turns).limit == "rotation"

    def bone(s: float) -> Trial:
        return Trial(s, s >= 0.362, s / 0.362, 1, None if s >= 0.362 else 1.0,
                     "held" if s >= 0.362 else "not held: x", bone=True)

    assert grip_search(bone).limit == "bone"


def test_first_trial_is_reused() -> None:
    trial = threshold(0.362)
    first = Trial(1.0, True, 1 / 0.362, 0)
    out = grip_search(trial, first=first)
    assert out.trials[0] is first and 1.0 not in trial.calls
    assert out.solves == out.steps - 1


# --- what a trial measures ------------------------------------------------------------


def fake(
    stop="converged", held=True, converged=True, friction=None, contacts=None, slip=None,
    below_grip=False,
):  # fmt: skip
    return SimpleNamespace(
        stop_reason=stop, held=held, converged=converged, friction=friction, contacts=contacts,
        slip=slip, over_limit={}, below_grip=below_grip,
    )


def test_measure_of_a_slip_and_a_hold(tmp_path: Path) -> None:
    scene = load_scene(pads(tmp_path))
    stop = (
        "not held: ball slips along (0.000, 0.000, -1.000): 0.1 N of its load is not "
        "carried by its contacts (friction available sum mu N = 0.3 N)"
    )
    slip = {"direction": [0.0, 0.0, -1.0], "not_carried": 0.1, "available": 0.3}
    assert measure(fake(stop, False, False, slip=slip), scene) == pytest.approx(0.75)
    # a moment left (it turns): the moment its cones had, sum mu N r, against it (N m)
    turns = {"direction": [0.0, 0.0, 1.0], "not_carried": 0.001, "available": 0.004,
             "turns": True}
    assert measure(fake("not held: ball turns", False, False, slip=turns), scene) == (
        pytest.approx(0.8)
    )
    friction = SimpleNamespace(
        tangential_force={
            "ball/left_pad": np.array([0.0, 0.0, 0.2]),
            "ball/right_pad": np.array([0.0, 0.0, 0.2]),
            "left_pad": np.array([0.0, 0.0, -0.2]),
        }
    )
    contacts = {"pair": np.array(["ball/left_pad", "ball/right_pad"]), "force": np.ones(2)}
    # sum mu N = 0.5 * 2 over the tangential 0.4 (the plane's own entry not counted twice)
    assert measure(fake(friction=friction, contacts=contacts), scene) == pytest.approx(2.5)
    assert measure(fake("iteration limit", held=None, converged=False), scene) is None


def test_judge_a_bone_limit_holds_other_stops_do_not(tmp_path: Path) -> None:
    scene = load_scene(pads(tmp_path))
    bone = fake("converged", held=True, converged=True)  # a bone over its limit: converged
    assert judge(1.0, [bone], [1.0], scene).holds
    stuck = fake("iteration limit", held=None, converged=False)
    tr = judge(2.0, [fake(), stuck], [0.5, 1.0], scene)
    assert not tr.holds and not tr.slipped and tr.time == 1.0 and tr.solves == 2
    unconverged_held = fake("cycling", held=True, converged=False)
    assert not judge(1.0, [unconverged_held], [1.0], scene).holds


def test_judge_held_below_the_forces_asked_holds(tmp_path: Path) -> None:
    # a finger's force jumps over its target as a node enters the contact: the frame
    # solved and held at the force below it holds at the larger one asked
    scene = load_scene(pads(tmp_path))
    jump = "finger force not reached: index_pip: its finger's force jumps"
    below = fake(jump, held=True, converged=False, below_grip=True)
    assert judge(1.0, [fake(), below], [0.5, 1.0], scene).holds
    # above the force asked, or not solved: it says nothing of the grip asked
    above = fake(jump, held=True, converged=False, below_grip=False)
    assert not judge(1.0, [above], [1.0], scene).holds
    unsolved = fake(f"iteration limit; {jump}", held=None, converged=False, below_grip=False)
    assert not judge(1.0, [unsolved], [1.0], scene).holds


# --- the scene's grip -------------------------------------------------------------------


def test_grip_scaled_scales_only_force_driven_planes(tmp_path: Path) -> None:
    scene = load_scene(pads(tmp_path, right=OFFSETS))
    assert scene.grip == {"left_pad": 2.0}
    scaled = scene.grip_scaled(0.25)
    left, right = scaled.planes
    assert left.force == ((0.0, 0.25), (2.0, 0.5))
    assert right == scene.planes[1]
    assert scaled.grip == {"left_pad": 0.5}
    assert scaled.ball == scene.ball and scaled.frames == scene.frames
    assert scene.planes[0].force == ((0.0, 1.0), (2.0, 2.0))  # the original is untouched


def test_a_fingers_force_at_a_frame_is_its_flexion_s_there(tmp_path: Path) -> None:
    # the pinch's index presses 0.3 N at t = 0.5 and 0.6 N at t = 1 (two flexions)
    path = tmp_path / "pinch.toml"
    path.write_text(example("pinch"))
    scene = load_scene(path)
    assert scene.grip == {"index_pip": 0.6}
    assert scene.grip_at(0.5) == {"index_pip": 0.3}
    assert scene.grip_at(1.0) == {"index_pip": 0.6}
    assert scene.grip_at(0.75) == {"index_pip": 0.0}


@pytest.mark.parametrize(
    ("kw", "why"),
    [
        ({"left": OFFSETS, "right": OFFSETS}, "nothing force-driven"),
        ({"gravity": ""}, "nothing to hold"),
        ({"mu": 0.0}, "no friction"),
    ],
)
def test_grip_refuses_what_it_cannot_scale_or_hold(tmp_path: Path, kw: dict, why: str) -> None:
    scene = load_scene(pads(tmp_path, **kw))
    for call in (lambda: scene.grip, lambda: scene.grip_scaled(2.0)):
        with pytest.raises(SceneError, match=why) as exc:
            call()
        assert "\n" not in str(exc.value)


def test_grip_scaled_refuses_a_bad_scale_or_too_much_force(tmp_path: Path) -> None:
    scene = load_scene(pads(tmp_path))
    with pytest.raises(SceneError, match="scale"):
        scene.grip_scaled(0.0)
    with pytest.raises(SceneError, match=r"plane\[0\] \(left_pad\) scaled by 1e\+06"):
        scene.grip_scaled(1e6)


# --- the command line ------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kw", "args", "why"),
    [
        ({"left": OFFSETS, "right": OFFSETS}, [], "nothing force-driven"),
        ({"mu": 0.0}, [], "no friction"),
        ({}, ["--frames", "0"], "takes no --frames"),
        ({}, ["--pose-only"], "takes no --pose-only"),
    ],
)
def test_cli_refusals_exit_2_with_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture, kw: dict, args: list, why: str
) -> None:
    path = pads(tmp_path, **kw)
    assert main([str(path), "--least-grip", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:") and why in err and "\n" not in err
    assert not (tmp_path / "results").exists()


def test_cli_writes_and_prints_the_least_grip(
    tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The plumbing, with the search itself mocked (the real one: the pads' proof)."""
    seen = {}

    def mock(run, times, *, first, on_trial):
        seen.update(times=times, first=first)
        on_trial(1, first)
        trial = Trial(0.5, True, 1.01, 1)
        on_trial(2, trial)
        return LeastGrip(0.5, {"left_pad": 1.0}, 2.0, 2, 1, 0.49, 0.5, 0.1, True, "ok",
                         (first, trial))  # fmt: skip

    monkeypatch.setattr(contact.grasp, "least_grip", mock)
    path = pads(tmp_path, right=OFFSETS)
    main([str(path), "--least-grip", "--no-pictures"])
    summary = json.loads((tmp_path / "results" / "summary.json").read_text())
    lg = summary["least_grip"]
    assert lg["scale"] == 0.5 and lg["bracket"] == [0.49, 0.5] and lg["forces"] == {"left_pad": 1.0}
    assert {"margin", "steps", "solves", "seconds"} <= set(lg)
    assert "frames" in summary and "scene" in summary  # the file's structure is kept
    assert seen["times"] == [1.0] and seen["first"].scale == 1.0 and seen["first"].solves == 0
    out, err = capsys.readouterr()
    line = parse_line(out.strip().splitlines()[-1])
    assert list(line) == list(LEAST_GRIP_KEYS)
    assert line["least_grip"] == "0.5" and line["forces_N"] == "left_pad:1"
    assert "least_grip_trial=2 scale=0.5 held=yes" in err


def test_cli_quiet_prints_nothing(tmp_path: Path, capsys, monkeypatch) -> None:
    def mock(run, times, *, first, on_trial):
        on_trial(1, first)
        return LeastGrip(None, {}, None, 1, 0, 64.0, None, 0.0, False, "no grip up to 64x holds")

    monkeypatch.setattr(contact.grasp, "least_grip", mock)
    main([str(pads(tmp_path, right=OFFSETS)), "--least-grip", "--quiet", "--no-pictures"])
    out, err = capsys.readouterr()
    assert out == "" and err == ""
    lg = json.loads((tmp_path / "results" / "summary.json").read_text())["least_grip"]
    assert lg["scale"] is None and lg["note"] == "no grip up to 64x holds"


def test_least_grip_line_when_none_held() -> None:
    rec = LeastGrip(None, {}, None, 7, 7, 64.0, None, 1.0, False, "no grip up to 64x holds")
    line = parse_line(least_grip_line(rec.record()))
    assert line["least_grip"] == "none" and line["bracket"] == "64..-"
    assert line["note"] == "no grip up to 64x holds"


# --- the proof: two force-driven pads, gravity along them ----------------------------


def test_pads_least_grip_is_m_g_over_2_mu(tmp_path: Path) -> None:
    mu = 0.5
    constant = "force = [[0.0, 1.0]]"  # 1 N on each pad
    scene = load_scene(pads(tmp_path, mu=mu, left=constant, right=constant))
    run = GraspRun(scene)
    weight = -float(run.ball_body(1.0).loads.reshape(-1, 3).sum(axis=0)[2])  # the mesh's
    out = least_grip(run, [1.0])
    check_bracket(out)
    exact = weight / (2 * mu)  # each pad's least force (N)
    for name in ("left_pad", "right_pad"):
        assert out.forces[name] == pytest.approx(exact, rel=0.01)
    assert out.solves <= 12
    above = run.restart(scene.grip_scaled(1.02 * exact)).frame(1.0)[0]
    assert above.held is True and above.converged
    below = run.restart(scene.grip_scaled(0.98 * exact)).frame(1.0)[0]
    assert below.held is False
    stop = below.stop_reason
    assert stop.startswith("not held") and "slips along" in stop
    z = float(stop.split("slips along (")[1].split(")")[0].split(",")[2])
    assert z < 0


def test_pads_of_unequal_friction_hold_by_the_lesser(tmp_path: Path) -> None:
    # the two friction forces act at the ends of a diameter: the ball's balance of moments
    # makes them equal, W / 2 each, so the pad of the lesser mu limits the grip,
    # N = W / (2 mu_min), not W / (mu_1 + mu_2). By weighted gaps on 4 mm bricks 4 %
    # under it; node rows hold the ball at W / (mu_1 + mu_2), 11 % under: their patch of
    # stuck nodes carries the moment
    constant = "force = [[0.0, 1.0]]"
    left, right = constant + "\nfriction = 0.4", constant + "\nfriction = 0.5"
    scene = load_scene(pads(tmp_path, left=left, right=right, gaps="weighted", h=0.004))
    run = GraspRun(scene)
    weight = -float(run.ball_body(1.0).loads.reshape(-1, 3).sum(axis=0)[2])
    out = least_grip(run, [1.0])
    check_bracket(out)
    assert out.limit == "friction"
    for name in ("left_pad", "right_pad"):
        assert out.forces[name] == pytest.approx(weight / (2 * 0.4), rel=0.05)
        assert out.forces[name] > 1.05 * weight / (0.4 + 0.5)


def test_pads_least_grip_names_friction_and_the_frame_that_limits_it(tmp_path: Path) -> None:
    # the grip ramps from 1 N at t = 1 to 4 N at t = 2: the first frame limits it, where
    # each pad needs m g / (2 mu); the peak force is four times that
    mu = 0.5
    ramp = "force = [[1.0, 1.0], [2.0, 4.0]]"
    scene = load_scene(pads(tmp_path, mu=mu, left=ramp, right=ramp))
    run = GraspRun(scene)
    weight = -float(run.ball_body(1.0).loads.reshape(-1, 3).sum(axis=0)[2])
    out = least_grip(run, [1.0, 2.0])
    check_bracket(out)
    assert out.limit == "friction" and out.frame == 1.0
    exact = weight / (2 * mu)
    for name in ("left_pad", "right_pad"):
        assert out.frame_forces[name] == pytest.approx(exact, rel=0.01)
        assert out.forces[name] == pytest.approx(4 * exact, rel=0.01)
    rec = out.record()
    assert rec["limit"] == "friction" and rec["limiting_frame"]["time"] == 1.0
