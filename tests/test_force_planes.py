"""Force-driven planes: a rigid plane that moves along its normal until it takes its force.

Each such plane is one more rigid mode of the contact-space system, solved with the
contact forces: its force is reached to round-off, its position is the one at which a
displacement-driven plane takes the same force, and two force-driven frictional pads
hold a ball by exactly ``2 mu N`` against its weight.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from contact.grasp import main
from contact.run import GraspRun
from contact.scene import SceneError, load_scene

#: A free ball squeezed by two pads along x, gravity along -z.
PADS = """\
[scene]
gravity = [0.0, 0.0, -9.81]

[ball]
radius = 0.02
element = "hex"
mesh_size = 0.006
material = {{ E = 1.0e6, nu = 0.3, density = 1000.0 }}

[[plane]]
name = "left"
point = [-0.021, 0.0, 0.0]
normal = [1.0, 0.0, 0.0]
{left}

[[plane]]
name = "right"
point = [0.021, 0.0, 0.0]
normal = [-1.0, 0.0, 0.0]
{right}

[frames]
times = {times}

[solver]
algorithm = "{algorithm}"

[output]
directory = "{out}"
pictures = false
"""

#: A ball resting on a table, pressed from above: no free mode besides the top plane's.
PRESS = """\
[ball]
radius = 0.02
element = "hex"
mesh_size = 0.006
material = {{ E = 1.0e6, nu = 0.3, density = 1000.0 }}

[[plane]]
name = "table"
point = [0.0, 0.0, -0.02]
normal = [0.0, 0.0, 1.0]

[[plane]]
name = "top"
point = [0.0, 0.0, 0.0205]
normal = [0.0, 0.0, -1.0]
{top}

[frames]
times = [1.0]

[output]
directory = "{out}"
pictures = false
"""


def _pads(
    tmp_path: Path, left: str, right: str, times: str = "[1.0]", algorithm: str = "contact-space"
) -> Path:
    path = tmp_path / "pads.toml"
    out = (tmp_path / "results").as_posix()
    path.write_text(PADS.format(left=left, right=right, times=times, algorithm=algorithm, out=out))
    return path


def _press(tmp_path: Path, top: str, name: str = "press.toml") -> Path:
    path = tmp_path / name
    path.write_text(PRESS.format(top=top, out=(tmp_path / name).with_suffix("").as_posix()))
    return path


def _weight(run: GraspRun) -> float:
    return float(-run.ball_body(1.0).loads.reshape(-1, 3).sum(axis=0)[2])


def test_force_plane_reaches_its_force_and_matches_a_displaced_plane(tmp_path: Path) -> None:
    # the top plane starts 0.5 mm off the ball and presses with 3 N
    run = GraspRun(load_scene(_press(tmp_path, "force = [[0.0, 3.0]]")))
    res, _, planes, _ = run.frame(1.0)
    assert res.converged, res.stop_reason
    top = res.obstacle_forces["top"]
    assert top[2] == pytest.approx(3.0, rel=1e-9)
    assert np.abs(top[:2]).max() < 1e-9
    assert res.obstacle_forces["table"][2] == pytest.approx(-3.0, rel=1e-9)
    move = res.plane_positions["top"]
    assert move[2] < -0.0005 and np.abs(move[:2]).max() == 0.0  # in past the gap
    assert planes[1].motion == pytest.approx(move)
    # the same plane driven to that position takes the same force
    dz = float(move[2])
    fixed = _press(tmp_path, f"offsets = [[0.0, 0.0, 0.0, {dz!r}]]", "fixed.toml")
    again, _, _, _ = GraspRun(load_scene(fixed)).frame(1.0)
    assert again.converged, again.stop_reason
    assert again.obstacle_forces["top"][2] == pytest.approx(3.0, rel=1e-6)
    np.testing.assert_allclose(
        again.displacement["ball"], res.displacement["ball"], atol=1e-9 * 0.02
    )


@pytest.mark.parametrize("factor", [1.03, 0.97])
def test_pads_hold_by_twice_mu_n(tmp_path: Path, factor: float) -> None:
    mu = 0.5
    run = GraspRun(load_scene(_pads(tmp_path, "force = [[0.0, 1.0]]", "force = [[0.0, 1.0]]")))
    n = factor * _weight(run) / (2 * mu)
    pad = f"force = [[0.0, {n!r}]]\nfriction = {mu}"
    run = GraspRun(load_scene(_pads(tmp_path, pad, pad)))
    res, _, _, _ = run.frame(1.0)
    # held: the force to round-off; not held: the state of a soft spring that holds it
    tol = 1e-9 if factor > 1 else 1e-3
    assert res.obstacle_forces["left"][0] == pytest.approx(-n, rel=tol)
    assert res.obstacle_forces["right"][0] == pytest.approx(n, rel=tol)
    if factor > 1:
        assert res.converged and res.held, res.stop_reason
        # the pads carry the weight, half each; the ball stays between them
        assert res.obstacle_forces["left"][2] == pytest.approx(-_weight(run) / 2, rel=1e-6)
        left, right = res.plane_positions["left"][0], res.plane_positions["right"][0]
        assert left == pytest.approx(-right, rel=1e-6)
    else:
        assert res.held is False
        assert res.stop_reason.startswith("not held: ball slips along (")
        way = [float(x) for x in res.stop_reason.split("(")[1].split(")")[0].split(",")]
        assert way[2] < -0.999


def test_force_table_in_time_and_zero_force_stays(tmp_path: Path) -> None:
    force = "force = [[0.0, 0.0], [1.0, 2.0]]\nfriction = 0.8"
    run = GraspRun(load_scene(_pads(tmp_path, force, force, times="[0.0, 0.5, 1.0]")))
    forces = []
    for t in (0.0, 0.5, 1.0):
        res, _, _, _ = run.frame(t)
        forces.append(-res.obstacle_forces["left"][0])
        if t == 0.0:  # no force: the pads stay where they are, the ball falls
            assert res.held is False
            assert res.plane_positions["left"] == pytest.approx(np.zeros(3))
        else:
            assert res.converged and res.held, res.stop_reason
    assert forces[1:] == pytest.approx([1.0, 2.0], rel=1e-9)


def test_bad_force_keys(tmp_path: Path) -> None:
    both = "force = [[0.0, 1.0]]\noffsets = [[0.0, 0.001, 0.0, 0.0]]"
    cases = {
        both: "not both",
        "force = [[0.0, -1.0]]": "force[0]",
        "force = [[1.0, 1.0], [0.5, 2.0]]": "times must increase",
        "force = [1.0, 2.0]": "force[0]",
        "force = 3.0": "list of [time, N]",
    }
    for left, words in cases.items():
        with pytest.raises(SceneError, match=r"plane\[0\]\.") as err:
            load_scene(_pads(tmp_path, left, ""))
        assert words in str(err.value)


def test_seed_loop_refuses_force_planes(tmp_path: Path, capsys) -> None:
    path = _pads(tmp_path, "force = [[0.0, 1.0]]", "", algorithm="seed")
    assert main([str(path), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "force" in err[0] and "contact-space" in err[0]


def test_summary_says_which_way_and_how_much_slips(tmp_path: Path) -> None:
    mu, n = 0.5, 0.15  # 2 mu N = 0.15 N against a weight of about 0.35 N
    pad = f"force = [[0.0, {n}]]\nfriction = {mu}"
    path = _pads(tmp_path, pad, pad)
    weight = _weight(GraspRun(load_scene(path)))
    assert main([str(path), "--quiet"]) == 1
    frame = json.loads((tmp_path / "results" / "summary.json").read_text())["frames"][0]
    assert frame["held"] is False
    slip = frame["slip"]
    assert slip["direction"] == pytest.approx([0.0, 0.0, -1.0], abs=1e-3)
    assert slip["available"] == pytest.approx(2 * mu * n, rel=1e-3)
    assert slip["not_carried"] == pytest.approx(weight - 2 * mu * n, rel=1e-2)
    assert slip["largest_increment"] is not None
    assert frame["plane_positions"]["left"][0] > 0 > frame["plane_positions"]["right"][0]
