"""Input that reads but no grasp has: friction above measure warned of, a deep start refused.

A friction coefficient above 2 (skin on common materials measures 0.2 to 2) is one
``WARNING:`` line naming its key; an object that starts inside a plane deeper than 10 % of
its smallest extent is bad input (exit status 2, one line naming the pair and the depth,
nothing written), a shallower overlap stays a warning, as does the hand posed into it.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest

import fem
from contact.errors import InputError
from contact.grasp import main
from contact.run.startchecks import OVERLAP_REFUSED, check_overlaps, smallest_extent
from contact.scene import load_scene
from contact.scene.plausible import MAX_FRICTION, friction_keys
from contact.solver.body import ElasticBody
from tests.helpers import plates_scene


def plates(tmp_path: Path, old: str = "", new: str = "") -> tuple[Path, Path]:
    out = tmp_path / "results"
    path = plates_scene(tmp_path / "scene.toml", out, times=(0.5,))
    path.write_text(path.read_text().replace(old, new))
    return path, out


def test_friction_above_measure_is_warned_of_by_key(tmp_path, caplog):
    path, _ = plates(tmp_path, 'name = "plate"', 'name = "plate"\nfriction = 5.0')
    text = path.read_text().replace('name = "table"', 'name = "table"\nfriction = 2.0')
    path.write_text(text.replace("[ball]", "[ball]\nfriction = 2.5"))
    with caplog.at_level(logging.WARNING, logger="contact.scene"):
        scene = load_scene(path)
    assert friction_keys(scene) == [
        ("ball.friction", 2.5), ("plane[0].friction", 2.0), ("plane[1].friction", 5.0),
    ]  # fmt: skip
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 2  # 2.0 is within what is measured
    assert lines[0].startswith(f"{path}: ball.friction = 2.5: above {MAX_FRICTION:g}")
    assert lines[1].startswith(f"{path}: plane[1].friction = 5: above 2, past the ")


def warnings_of(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]


def test_the_command_line_warns_of_friction_above_measure(tmp_path, caplog):
    path, out = plates(tmp_path, 'name = "plate"', 'name = "plate"\nfriction = 5.0')
    assert main([str(path), "--no-pictures", "--quiet"]) == 0
    assert f"{path}: plane[1].friction = 5: above 2, past the coefficients measured for " \
        "skin on common materials (0.2 to 2)" in warnings_of(caplog)
    assert (out / "summary.json").is_file()


def test_a_start_deep_inside_a_plane_is_bad_input(tmp_path, capsys):
    # the ball (40 mm across) 6 mm into the table: past 10 % of its smallest extent
    path, out = plates(tmp_path, "center = [0.0, 0.0, 0.02]", "center = [0.0, 0.0, 0.014]")
    assert main([str(path), "--no-pictures"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err, err
    assert "frame t = 0.5: ball/table overlap at the start: node " in err
    assert " of ball is 6 mm inside table, deeper than 10 % of the smallest extent of " in err
    assert "the ball (4 mm): place them apart" in err
    assert not out.exists()


def test_a_shallow_start_overlap_is_still_only_warned_of(tmp_path, caplog):
    path, out = plates(tmp_path, "center = [0.0, 0.0, 0.02]", "center = [0.0, 0.0, 0.0175]")
    assert main([str(path), "--no-pictures"]) in (0, 1)  # solved: a verdict, not bad input
    (line,) = [w for w in warnings_of(caplog) if "overlap" in w]
    assert line.startswith("t = 0.5: ball/table overlap at the start: node ")
    assert " of ball is 2.5 mm inside table" in line
    assert (out / "summary.json").is_file()


def test_the_smallest_extent_is_across_the_thinnest_direction():
    box = fem.box_mesh((0.03, 0.02, 0.004), (6, 4, 2)).points + 0.1
    turn, _ = np.linalg.qr(np.random.default_rng(0).normal(size=(3, 3)))
    assert smallest_extent(box @ turn.T) == pytest.approx(0.004, rel=1e-9)
    assert OVERLAP_REFUSED == 0.1


def _box(name: str, size: tuple[float, float, float], z: float) -> ElasticBody:
    mesh = fem.box_mesh(size, (4, 4, 2))
    mesh = fem.Mesh(mesh.points + np.array([0.0, 0.0, z]), mesh.cells, mesh.regions)
    return ElasticBody(name, mesh, fem.LinearElastic(1.0e6, 0.3))


def test_two_objects_deep_in_each_other_are_refused_the_hand_posed_into_one_is_not(caplog):
    # a 10 mm block 3 mm into a slab: past 10 % of the thinner's extent (1 mm)
    block = _box("block", (0.04, 0.04, 0.01), 0.0)
    with pytest.raises(InputError, match=(
        r"^frame t = 0: block/slab overlap at the start: node \d+ of block is 3 mm inside "
        r"slab, deeper than 10 % of the smallest extent of object 'block' \(1 mm\): place "
        r"them apart$"
    )):  # fmt: skip
        check_overlaps(0.0, [block, _box("slab", (0.04, 0.04, 0.02), 0.007)], [], 1e-3)
    # the hand 5 mm into it: posed to press it, warned of only
    with caplog.at_level(logging.WARNING, logger="contact.run.startchecks"):
        check_overlaps(0.0, [block, _box("hand", (0.04, 0.04, 0.02), 0.005)], [], 1e-3)
    said = warnings_of(caplog)
    assert len(said) == 2 and " of block is 5 mm inside hand " in said[0]


@pytest.mark.parametrize("resolution, gaps, warned", [
    ("coarse", "weighted", True), ("fine", "weighted", False), ("coarse", "nodal", False),
])  # fmt: skip
def test_weighted_gaps_on_the_coarse_hand_are_warned_of(
    tmp_path, caplog, resolution, gaps, warned
):
    text = (Path(__file__).resolve().parents[2] / "examples" / "finger_press.toml").read_text()
    text = text.replace('resolution = "coarse"', f'resolution = "{resolution}"')
    path = tmp_path / "press.toml"
    path.write_text(text.replace("[solver]", f'[solver]\ngaps = "{gaps}"'))
    with caplog.at_level(logging.WARNING, logger="contact.scene"):
        load_scene(path)
    lines = [w for w in warnings_of(caplog) if "weighted" in w]
    assert lines == ([
        f'{path}: solver.gaps = "weighted" with hand.resolution = "coarse": the coarse '
        "fingertip's nodes are wider than a press's patch, and its weighted gaps close "
        'only about 1 mm past first touch; use hand.resolution = "fingertips" or "fine"'
    ] if warned else [])  # fmt: skip
