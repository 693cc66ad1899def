"""Force-driven fingers: the 1-D search on each joint's angle, and a finger on the hand."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from contact.grasp import main
from contact.holding.fingerforce import MAX_STEPS, Target, drive
from contact.scene import SceneError, load_scene

ROOT = Path(__file__).resolve().parents[1]


def _hertz(contact: float, k: float = 2.0):
    """A finger force growing as the press to the power 3/2 past ``contact`` degrees."""

    def force(a: float) -> float:
        return k * max(a - contact, 0.0) ** 1.5

    return force


def test_one_joint_reaches_its_force_within_the_tolerance() -> None:
    f = _hertz(20.0)
    calls = []

    def solve(angles):
        calls.append(angles["j"])
        return "result", {"j": f(angles["j"])}, ""

    target = Target("j", 3.0, 0.01, 90.0)
    result, angles, drives = drive(solve, {"j": 20.0}, {"j": 20.2}, [target])
    d = drives["j"]
    assert result == "result" and d.converged
    assert abs(f(angles["j"]) - 3.0) <= 0.03
    assert angles["j"] == d.angle == calls[-1]  # the last solve is the returned pose
    assert len(calls) <= 8
    lo, hi = d.final
    exact = 20.0 + (3.0 / 2.0) ** (2 / 3)
    assert d.record()["steps"] == len(calls)
    assert lo is None or lo <= exact + 1e-9
    assert hi is None or hi >= exact - 1e-9


def test_two_joints_at_once_each_with_its_own_force() -> None:
    fa, fb = _hertz(10.0, 1.0), _hertz(30.0, 5.0)

    def solve(angles):
        return None, {"a": fa(angles["a"]), "b": fb(angles["b"])}, ""

    targets = [Target("a", 1.0, 0.01, 90.0), Target("b", 4.0, 0.02, 90.0)]
    _, angles, drives = drive(solve, {"a": 10.0, "b": 30.0}, {"a": 10.5, "b": 30.1}, targets)
    assert all(d.converged for d in drives.values())
    assert fa(angles["a"]) == pytest.approx(1.0, rel=0.01)
    assert fb(angles["b"]) == pytest.approx(4.0, rel=0.02)


def test_a_joint_at_its_limit_short_of_the_force_stops_and_says_so() -> None:
    f = _hertz(20.0, 0.01)

    def solve(angles):
        return None, {"j": f(angles["j"])}, ""

    _, angles, drives = drive(solve, {"j": 20.0}, {"j": 20.5}, [Target("j", 50.0, 0.01, 30.0)])
    d = drives["j"]
    assert not d.converged and angles["j"] == 30.0
    assert "reached its limit 30 deg" in d.reason


def test_noise_does_not_loop_past_the_step_budget() -> None:
    f = _hertz(20.0)

    def solve(angles):
        a = angles["j"]
        return None, {"j": f(a) * (1 + 0.05 * math.sin(1e4 * a))}, ""

    _, _, drives = drive(solve, {"j": 20.0}, {"j": 20.2}, [Target("j", 3.0, 0.001, 90.0)])
    assert len(drives["j"].trials) <= MAX_STEPS + 2


def test_a_finger_pressing_already_steps_back() -> None:
    f = _hertz(20.0)

    def solve(angles):
        return None, {"j": f(angles["j"])}, ""

    # the "touching" pose already presses (the ball moved since): forces above the target
    _, angles, drives = drive(solve, {"j": 24.0}, {"j": 24.5}, [Target("j", 3.0, 0.01, 90.0)])
    assert drives["j"].converged
    assert f(angles["j"]) == pytest.approx(3.0, rel=0.01)


FINGER = """\
[ball]
radius = 0.03
kind = "solid"
element = "hex"
mesh_size = 0.006
center = [-0.035, 0.15, -0.085]
material = {{ E = 5.0e5, nu = 0.45, density = 1100.0 }}

[hand]
resolution = "coarse"
flesh = {{ E = 5.0e4, nu = 0.45 }}

[[hand.keyframe]]
time = 0.0
angles = {{ index_pip = 30.0, index_dip = 20.0, middle_mcp = 70.0, middle_pip = 90.0, \
middle_dip = 60.0, ring_mcp = 70.0, ring_pip = 90.0, ring_dip = 60.0, little_mcp = 70.0, \
little_pip = 90.0, little_dip = 60.0, thumb_cmc = 20.0, thumb_mcp = 30.0, thumb_ip = 30.0 }}

[[hand.auto_flexion]]
joint = "index_mcp"
point = "index"
{drive}

[[plane]]
name = "table"
point = [0.0, 0.0, -0.1150]
normal = [0.0, 0.0, 1.0]

[[plane]]
name = "wall"
point = [-0.035, 0.12, 0.0]
normal = [0.0, 1.0, 0.0]

[frames]
times = [0.0]

[output]
directory = "{out}"
pictures = false
"""


def _finger(tmp_path: Path, drive_: str) -> Path:
    path = tmp_path / "finger.toml"
    path.write_text(FINGER.format(drive=drive_, out=(tmp_path / "out").as_posix()))
    return path


def test_a_force_driven_finger_on_the_hand(tmp_path: Path) -> None:
    assert main([str(_finger(tmp_path, "force = 1.5")), "--quiet"]) == 0
    frame = json.loads((tmp_path / "out" / "summary.json").read_text())["frames"][0]
    assert frame["converged"], frame["stop_reason"]
    rec = frame["auto_flexion"]["index_mcp"]
    assert rec["converged"] and rec["steps"] <= MAX_STEPS
    # the finger's force is the target within its tolerance, at the angle solved
    assert frame["fingers"]["index"]["normal"] == pytest.approx(1.5, rel=0.02)
    assert rec["reached"] == pytest.approx(frame["fingers"]["index"]["normal"], rel=1e-12)
    assert frame["angles"]["index_mcp"] == rec["angle"]
    lo, hi = rec["bracket"]
    assert (lo is None or lo <= rec["angle"]) and (hi is None or rec["angle"] <= hi)


def test_bad_force_flexion_keys(tmp_path: Path) -> None:
    cases = {
        "force = 1.0\npress = 0.001": "press or by force",
        "force = -1.0": "must lie in (0",
        "force = 1.0\nforce_tolerance = 0.0": "force_tolerance",
    }
    for text, words in cases.items():
        with pytest.raises(SceneError, match=r"hand\.auto_flexion\[0\]") as err:
            load_scene(_finger(tmp_path, text))
        assert words in str(err.value)


def test_a_force_that_jumps_over_the_target_is_said_so() -> None:
    def solve(angles):  # a step of the force at 21 deg, from 0.9 N to 1.2 N
        a = angles["j"]
        return None, {"j": 0.0 if a < 20 else (0.9 if a < 21.0 else 1.2)}, ""

    target = Target("j", 1.0, 0.02, 90.0)
    _, angles, drives = drive(solve, {"j": 20.0}, {"j": 20.5}, [target], max_steps=12)
    d = drives["j"]
    assert not d.converged
    assert "jumps from 0.9 N to 1.2 N" in d.reason
    lo, hi = d.final
    assert lo < 21.0 <= hi and hi - lo < 1e-2
    # the frame ends below the jump: the grip it holds with is no firmer than asked
    assert angles["j"] == lo == d.angle and d.reached == 0.9


def test_a_trial_not_held_counts_below_the_force_whatever_its_forces() -> None:
    # below 21 deg the ball is not held (its fingers' forces those of a ball on the move,
    # here wild); from 21 deg it is held with a force that grows from 0.5 N
    calls: list[float] = []

    def solve(angles):
        a = angles["j"]
        calls.append(a)
        held = a >= 21.0
        force = 0.5 + (a - 21.0) if held else 3.0 * (1.0 + math.sin(40 * a))
        return held, {"j": force}, ""

    lost = lambda held: not held  # noqa: E731
    target = Target("j", 1.0, 0.02, 90.0)
    result, angles, drives = drive(
        solve, {"j": 20.0}, {"j": 20.3}, [target], lost=lost, max_steps=12
    )
    d = drives["j"]
    assert result is True and d.converged and angles["j"] == pytest.approx(21.5, abs=0.01)
    assert d.lost and max(d.lost) < 21.0 and d.record()["not_held"] == sorted(d.lost)
    # asked less than the least force that holds: no angle holds with it, and the frame
    # ends not held, at the angle next below the one that holds
    target = Target("j", 0.3, 0.02, 90.0)
    result, angles, drives = drive(
        solve, {"j": 20.0}, {"j": 20.3}, [target], lost=lost, max_steps=12
    )
    d = drives["j"]
    assert result is False and not d.converged and d.reached == 0.0
    assert "no angle holds with 0.3 N" in d.reason
    lo, hi = d.final
    assert lo == angles["j"] < 21.0 <= hi and lo in d.lost
    # the held force's secant, extended down to where it is not held, stays above the
    # force asked (convex, it can only lie higher), or the bracket is 0.01 deg wide
    assert hi - lo < 1e-2 or 0.5 + (hi - 21.0) - (hi - lo) > 0.3 * 1.02
    # the solves run out before the edge of holding is found: not a verdict on the force
    # asked, the frame ends where it held nearest, above that force
    result, angles, drives = drive(
        solve, {"j": 20.0}, {"j": 20.3}, [target], lost=lost, max_steps=4
    )
    d = drives["j"]
    assert result is True and not d.converged and d.reached > 0.3 and angles["j"] >= 21.0


def _pinch_edge(a: float) -> tuple[bool, float]:
    """A ball held from 37.3 deg, its finger's force flat above the 1 N asked, then Hertzian.

    The shape of a pinch's index force about its edge of holding, the ball moved since
    first contact (39 deg): less flexion loses the ball, the least that holds presses more.
    """
    if a < 37.3:
        return False, 3.0 * (1.0 + math.sin(40 * a))
    return True, 1.1 + 1e-3 * (a - 37.3) + 0.5 * max(a - 39.0, 0.0) ** 1.5


def test_a_flat_force_above_the_target_finds_the_edge_of_holding_in_the_budget() -> None:
    def solve(angles):
        held, force = _pinch_edge(angles["j"])
        return held, {"j": force}, ""

    target = Target("j", 1.0, 0.02, 90.0)
    result, angles, drives = drive(
        solve, {"j": 39.0}, {"j": 40.1}, [target], lost=lambda held: not held
    )
    d = drives["j"]
    assert result is False and "no angle holds with 1 N" in d.reason
    lo, hi = d.final
    assert lo == angles["j"] < 37.3 <= hi and hi < 39.0 and lo in d.lost
    assert "at least 1.099 N where it holds between" in d.reason
    # a round-off change of the forces and the first contact leaves the verdict
    for eps in (1e-15, -1e-15):

        def twin(angles, e=eps):
            held, force = _pinch_edge(angles["j"])
            return held, {"j": force * (1 + e)}, ""

        again, _, drives = drive(
            twin, {"j": 39.0 * (1 + eps)}, {"j": 40.1}, [target], lost=lambda held: not held
        )
        assert again is False and drives["j"].reason.split(" deg")[0] == d.reason.split(" deg")[0]


def test_a_frame_solved_again_starts_where_it_ended_below_first_contact() -> None:
    from contact.holding.fingertargets import guess

    # the last search ended at 38 deg with 1.1 N, below first contact at 39 deg (the ball
    # had moved): no press past it to scale, so the next starts there
    memory = {(0.5, "j"): (39.0, 38.0, 1.1)}
    target = Target("j", 1.0, 0.02, 90.0)
    start = guess(memory, 0.5, {"j": 39.0}, {"j": 40.1}, [target])
    assert start == {"j": 38.0}
    calls = []

    def solve(angles):
        calls.append(angles["j"])
        held, force = _pinch_edge(angles["j"])
        return held, {"j": force}, ""

    result, _, drives = drive(solve, {"j": 39.0}, start, [target], lost=lambda h: not h)
    assert result is False and "no angle holds with 1 N" in drives["j"].reason
    assert len(calls) <= 4
    # past first contact, the press scales as a Hertz contact's: 8 times the force, 4 times
    # the press
    memory = {(0.5, "j"): (39.0, 40.0, 1.0)}
    assert guess(memory, 0.5, {"j": 39.0}, {"j": 39.1}, [Target("j", 8.0, 0.02, 90.0)]) == {
        "j": pytest.approx(43.0)
    }


def test_substeps_take_the_flexions_of_the_frame_they_lead_to(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import contact.run.grasprun
    from contact.run import GraspRun

    text = FINGER.format(drive="press = 0.0005\ntimes = [1.0]", out=(tmp_path / "o").as_posix())
    text = text.replace("times = [0.0]", "times = [0.0, 1.0]")
    key = "[[hand.keyframe]]\ntime = 1.0\nangles = {}\n\n[[hand.auto_flexion]]"
    text = text.replace("[[hand.auto_flexion]]", key)
    text = text.replace('resolution = "coarse"', 'resolution = "coarse"\nfriction = 0.5')
    text += "\n[solver]\nsubsteps = 2\n"
    path = tmp_path / "steps.toml"
    path.write_text(text)
    run = GraspRun(load_scene(path))
    seen = []
    solve = contact.run.grasprun.solve_rolled

    def spy(run_, t, angles, callback):
        seen.append((t, angles["index_mcp"]))
        return solve(run_, t, angles, callback)

    monkeypatch.setattr(contact.run.grasprun, "solve_rolled", spy)
    run.frame(0.0)
    run.frame(1.0)
    assert [t for t, _ in seen] == [0.0, 0.5, 1.0]
    assert seen[0][1] == 0.0 and seen[1][1] > 0.0 and seen[2][1] > 0.0


def test_two_fingers_squeezing_one_free_ball_share_one_force() -> None:
    # a pinch: the ball between them carries one force, set by how far both have closed
    def solve(angles):
        f = 2.0 * max(angles["index"] + angles["thumb"] - 40.0, 0.0) ** 1.5
        return None, {"index": f, "thumb": f}, ""

    targets = [Target("index", 1.0, 0.02, 90.0), Target("thumb", 1.0, 0.02, 90.0)]
    _, angles, drives = drive(
        solve, {"index": 20.0, "thumb": 20.0}, {"index": 20.3, "thumb": 20.3}, targets
    )
    assert all(d.converged for d in drives.values())
    assert 2.0 * (angles["index"] + angles["thumb"] - 40.0) ** 1.5 == pytest.approx(1.0, rel=0.02)
    solves = len(drives["index"].trials) - 1
    assert solves <= 6


def test_a_trial_that_did_not_settle_never_brackets_the_force() -> None:
    # frames between 21.0 and 21.3 deg stop short with a force far above the truth (a
    # solver's give-up): the search steps back past them and reaches the force below
    f = _hertz(20.0)
    calls = []

    def solve(angles):
        a = angles["j"]
        calls.append(a)
        if 21.0 <= a < 21.3:
            return None, {"j": 10.0}, "Newton stalled"
        return None, {"j": f(a)}, ""

    target = Target("j", 1.5, 0.01, 90.0)
    _, angles, drives = drive(solve, {"j": 20.0}, {"j": 21.1}, [target], max_steps=12)
    d = drives["j"]
    assert d.converged and f(angles["j"]) == pytest.approx(1.5, rel=0.01)
    assert 21.1 in d.unsettled and d.unsettled[21.1] == "Newton stalled"
    lo, hi = d.final
    assert all(not (21.0 <= a < 21.3) for a in (lo, hi) if a is not None)
    assert d.record()["unsettled"] == [[a, "Newton stalled"] for a in d.unsettled]


def test_a_force_only_unsettled_frames_reach_is_the_solvers_limit() -> None:
    # every frame past 20.9 deg stops short: the force asked lies there, unreached, and
    # the search says the solver stopped it, never that the finger got its force
    f = _hertz(20.0)

    def solve(angles):
        a = angles["j"]
        return None, {"j": f(a)}, ("friction did not settle" if a > 20.9 else "")

    target = Target("j", 3.0, 0.01, 90.0)
    _, _, drives = drive(solve, {"j": 20.0}, {"j": 20.2}, [target], max_steps=20)
    d = drives["j"]
    assert not d.converged
    assert "did not settle" in d.reason and "solver's limit" in d.reason
    assert max(a for a, _ in d.settled()) <= 20.9


def test_a_search_guided_by_unsettled_trials_alone_never_asks_for_one_again() -> None:
    # a pinch at a light grip: first contact, then every frame past it stops short with a
    # force above the target (the ball turned, friction did not settle); the secant of
    # those trials points back, and the search neither repeats an angle nor calls the
    # force reached
    f = _hertz(39.0)
    calls: list[float] = []

    def solve(angles):
        a = angles["j"]
        calls.append(a)
        if a > 39.05:  # stopped short with a force past the truth
            return None, {"j": f(a) + 0.05}, "friction did not settle"
        return None, {"j": f(a)}, ""

    target = Target("j", 0.04, 0.02, 90.0)
    _, _, drives = drive(solve, {"j": 39.0}, {"j": 40.1}, [target], max_steps=12)
    d = drives["j"]
    assert not d.converged and "solver's limit" in d.reason
    assert len(calls) == len(set(calls)) and len(calls) <= 12
