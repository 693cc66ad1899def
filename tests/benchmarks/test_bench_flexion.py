"""The flexion benchmark's quick mode and its figures: files written, a jump seen as one."""

import csv

import numpy as np
import pytest

from benchmarks import flexion


def _steps(forces):
    return [{"angle": 20 + flexion.STEP * k, "force": f, "rows": 1, "frame_s": 0.1,
             "stop": "converged" if f else "not held: ball touches nothing"}
            for k, f in enumerate(forces)]  # fmt: skip


def test_a_steady_force_meets_the_goal_and_a_jump_shows():
    steady = flexion.summary(_steps([0, 0] + [0.1 * k for k in range(1, 25)]), 20.05)
    assert steady["first"] == pytest.approx(20.1) and steady["end_force"] == pytest.approx(2.4)
    assert steady["largest"] == pytest.approx(100 * 0.1 / 2.4) and steady["met"] == "met"
    assert steady["jump"] == pytest.approx(1.0) and steady["unsettled"] == 2
    jumped = flexion.summary(_steps([0, 0.1, 0.2, 0.7, 0.8, 0.9]), 20.0)
    assert jumped["jump"] == pytest.approx(5.0) and jumped["met"] == "MISSED"
    assert np.isnan(flexion.summary(_steps([0, 0, 0]), 20.0)["largest"])


def test_quick_run_writes_its_sweep(tmp_path):
    rows = flexion.run(quick=True, out=tmp_path)
    assert [(r["scene"], r["gaps"]) for r in rows] == [("pinch", "nodal"), ("pinch", "weighted")]
    curves = list(csv.DictReader((tmp_path / "flexion.csv").open()))
    assert len(curves) == 2 * (flexion.BEFORE + flexion.STEPS[True] + 1)
    assert (tmp_path / "flexion.png").stat().st_size > 10_000
    assert "| pinch | coarse | weighted |" in (tmp_path / "flexion.md").read_text()
    for r in rows:  # the ball held in place: the index presses it from first touch on
        assert r["end_force"] > 0 and r["first"] <= r["touch"] + 2 * flexion.STEP
