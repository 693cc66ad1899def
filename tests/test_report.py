"""The terminal report and the grasp's figures in ``summary.json`` (grip, parts, strain)."""

import json
from pathlib import Path

import numpy as np
import pytest

import contact.output.summary
from contact.app.report import FRAME_KEYS, SUMMARY_KEYS, frame_line, parse_line, summary_line
from contact.grasp import main

ROOT = Path(__file__).resolve().parents[1]
PARTS = ["palm", "thumb", "index", "middle", "ring", "little"]


def test_one_line_a_frame_then_the_closing_line(finger_press):
    code, lines, _, summary, out = finger_press
    frames = summary["frames"]
    assert len(lines) == len(frames) + 1
    for line, entry in zip(lines, frames, strict=False):
        rec = parse_line(line)
        assert tuple(rec) == FRAME_KEYS
        assert int(rec["frame"]) == entry["index"] and float(rec["t"]) == entry["time"]
        assert float(rec["grip_N"]) == pytest.approx(entry["grip_force"], rel=5e-3, abs=1e-12)
        assert int(rec["updates"]) == entry["iterations"]
        assert rec["verdict"] == ("realistic" if entry["verdict"]["realistic"] else "unrealistic")
        assert (rec["status"] == "converged") == entry["converged"]
        assert rec["held"] in ("yes", "no", "-")
        fingers = dict(p.split(":") for p in rec["fingers_N"].split(","))
        assert list(fingers) == ["P", "T", "I", "M", "R", "L"]
        for letter, name in zip(fingers, PARTS, strict=True):
            assert float(fingers[letter]) == pytest.approx(
                entry["fingers"][name]["normal"], rel=5e-3, abs=1e-12
            )
        bones = entry["bone_forces"]
        top = max(bones, key=lambda b: bones[b]["magnitude"])
        if bones[top]["magnitude"] > 0:
            assert rec["bone"] == top
            assert float(rec["bone_N"]) == pytest.approx(bones[top]["magnitude"], rel=5e-3)
        assert float(rec["s"]) > 0
    # the index presses at t = 0.5 and 1, harder at 1; its distal bone carries the most
    last = parse_line(lines[-2])
    assert float(last["grip_N"]) > float(parse_line(lines[-3])["grip_N"]) > 0
    assert last["bone"] == "index_distal"
    end = parse_line(lines[-1])
    assert tuple(end) == SUMMARY_KEYS
    assert int(end["frames"]) == len(frames)
    assert int(end["converged"]) == sum(f["converged"] for f in frames)
    assert int(end["realistic"]) == sum(f["verdict"]["realistic"] for f in frames)
    assert (end["verdict"] == "realistic") == summary["all_realistic"] == (code == 0)
    assert Path(end["results"]) == out


def test_grip_force_and_the_hand_parts_in_the_summary(finger_press):
    _, _, _, summary, _ = finger_press
    for entry in summary["frames"]:
        parts = entry["fingers"]
        assert list(parts) == PARTS
        for rec in parts.values():
            keys = {"normal", "tangential", "contact_area", "peak_pressure", "max_cone_use"}
            assert set(rec) == keys
            assert all(v >= 0 for v in rec.values())
        # only the index touches; the parts add up to the grip (to the few per cent that
        # the skin's share of rows where ball nodes press into it, spread on a facet's
        # nodes, loses in magnitude)
        total = sum(p["normal"] for p in parts.values())
        assert total == pytest.approx(entry["grip_force"], rel=2e-2, abs=1e-12)
        assert all(parts[n]["normal"] == 0 for n in PARTS if n != "index")
        index = parts["index"]
        if index["normal"] > 0:
            # a few fingertip nodes of 1 to 10 mm^2 each; the mean pressure under the peak
            assert 1e-6 < index["contact_area"] < 1e-3
            assert index["peak_pressure"] >= index["normal"] / index["contact_area"]
        assert set(entry["max_strain"]) == {"ball", "hand"}
    pressed = [f for f in summary["frames"] if f["time"] > 0]
    assert 0 < pressed[0]["grip_force"] < pressed[1]["grip_force"]
    assert pressed[0]["max_strain"]["hand"] < pressed[1]["max_strain"]["hand"]


def test_a_strain_past_the_bound_is_warned_of_on_a_linear_body_only(finger_press):
    # the shipped flesh is neo-Hookean: strained past the bound, it is not warned of; the
    # linear ball would be
    _, _, messages, summary, _ = finger_press
    bound = contact.output.summary.SMALL_STRAIN
    frames = summary["frames"]
    assert max(f["max_strain"]["hand"] for f in frames) > bound
    past = [
        (f["time"], body)
        for f in frames
        for body, e in f["max_strain"].items()
        if e > bound and body != "hand"
    ]
    warned = [m for m in messages if "largest strain" in m]
    assert len(warned) == len(past)


def test_the_bound_is_read_at_use_time(tmp_path, monkeypatch, caplog):
    from tests.test_grasp import write

    monkeypatch.setattr(contact.output.summary, "SMALL_STRAIN", 1e-9)
    scene, _ = write(tmp_path)
    assert main([str(scene), "--no-pictures"]) == 0
    warned = [r.getMessage() for r in caplog.records if "largest strain" in r.getMessage()]
    assert len(warned) == 2 and all("the ball's" in m for m in warned)
    for m in warned:
        assert m.startswith("t = ") and "beyond small-strain linear elasticity" in m


def test_without_a_hand_the_grip_is_the_planes_and_no_parts(tmp_path, capsys):
    from tests.test_grasp import write

    scene, out = write(tmp_path)
    assert main([str(scene)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    for entry in summary["frames"]:
        assert entry["fingers"] is None
        # frictionless: the planes' normal forces are their whole forces
        planes = sum(p["magnitude"] for p in entry["obstacle_forces"].values())
        assert entry["grip_force"] == pytest.approx(planes, rel=1e-9)
        # Hertz: the strain under the plates is of order a / R, the contact radius over
        # the ball's: some 10 % at 1 mm of approach on each side
        assert 0 < entry["max_strain"]["ball"] < 0.5
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 3
    rec = parse_line(lines[0])
    assert rec["fingers_N"] == "-" and rec["bone"] == "-" and float(rec["bone_N"]) == 0
    # the ball is free: held between the plates
    assert rec["held"] == "yes" and summary["frames"][0]["held"] is True
    assert parse_line(lines[-1])["held"] == "2"


def test_quiet_prints_nothing(tmp_path, capsys):
    from tests.test_grasp import write

    scene, _ = write(tmp_path)
    assert main([str(scene), "--quiet", "--frames", "0"]) == 0
    assert capsys.readouterr().out == ""


def _entry(**change):
    entry = {
        "index": 4,
        "time": 0.25,
        "converged": True,
        "stop_reason": "converged",
        "verdict": {"realistic": True, "reason": "converged; every bone under its limit"},
        "held": True,
        "iterations": 7,
        "grip_force": 1.23456,
        "fingers": {n: {"normal": float(i)} for i, n in enumerate(PARTS)},
        "bone_forces": {
            "index_distal": {"magnitude": 0.5},
            "thumb_distal": {"magnitude": 0.75},
        },
    }
    entry.update(change)
    return entry


def test_frame_line_layout():
    rec = parse_line(frame_line(_entry(), 1.234))
    assert rec == {
        "frame": "4",
        "t": "0.25",
        "status": "converged",
        "held": "yes",
        "verdict": "realistic",
        "grip_N": "1.23",
        "fingers_N": "P:0,T:1,I:2,M:3,R:4,L:5",
        "bone": "thumb_distal",
        "bone_N": "0.75",
        "updates": "7",
        "s": "1.23",
    }
    stopped = _entry(
        converged=False,
        stop_reason="not held: ball slides 3 mm along -z",
        verdict={"realistic": False, "reason": "not held"},
        held=False,
        bone_forces={},
    )
    rec = parse_line(frame_line(stopped, 0.5))
    assert rec["status"] == "not-held" and rec["held"] == "no"
    assert rec["verdict"] == "unrealistic" and rec["bone"] == "-"
    left = _entry(converged=False, stop_reason="penetration left: node 3 of pair ball/hand")
    assert parse_line(frame_line(left, 0.5))["status"] == "penetration-left"


def test_summary_line_quotes_a_path_with_spaces():
    entries = [_entry(), _entry(held=None, verdict={"realistic": False, "reason": "x"})]
    line = summary_line(entries, "/tmp/my results/run 1")
    rec = parse_line(line)
    assert rec == {
        "frames": "2",
        "converged": "2",
        "held": "1",
        "realistic": "1",
        "verdict": "unrealistic",
        "results": "/tmp/my results/run 1",
    }
    with pytest.raises(ValueError, match="not a report line"):
        parse_line("frame=1 oops")


def test_max_strain_is_the_largest_principal_strain_in_magnitude():
    import fem
    from contact.output.summary import max_strain

    mesh = fem.box_mesh((1.0, 1.0, 1.0), (2, 2, 2))
    u = np.zeros_like(mesh.points)
    u[:, 0] = 0.2 * mesh.points[:, 0]  # 20 % stretch along x
    u[:, 1] = -0.3 * mesh.points[:, 1]  # 30 % shortening along y
    assert max_strain(mesh, u, bbar=False) == pytest.approx(0.3, rel=1e-12)
    assert max_strain(mesh, u) == pytest.approx(0.3, rel=1e-12)  # uniform: B-bar alike
    assert max_strain(mesh, np.zeros_like(u)) == 0.0
