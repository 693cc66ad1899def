"""The patch study by both gaps: its quick mode (fTetWild: slow) and its goal line."""

import csv

import pytest

from benchmarks.patch_gaps import GOAL, _goal, run


@pytest.mark.slow
def test_files_are_written(tmp_path):
    rows = run(quick=True, out=tmp_path)
    assert {r["gaps"] for r in rows} == {"nodal", "weighted"}
    assert all(r["converged"] and r["rows"] > 0 for r in rows)
    assert all(r["over_nodal"] == 1.0 for r in rows if r["gaps"] == "nodal")
    table = list(csv.DictReader((tmp_path / "patch_gaps.csv").open()))
    assert len(table) == len(rows)
    assert "goal" in (tmp_path / "patch_gaps.md").read_text()


def test_the_goal_names_each_press_past_it_or_not_converged():
    row = {"dofs": 5064, "depth": 0.01, "gaps": "weighted", "converged": True}
    ok = [dict(row, over_nodal=1.2), dict(row, gaps="nodal", over_nodal=1.0)]
    assert "**met** (largest x1.20)" in _goal(ok)
    slow = [*ok, dict(row, depth=0.02, over_nodal=GOAL + 0.01)]
    assert "**missed**" in _goal(slow) and "5,064 DOFs d/R 0.02: x1.51" in _goal(slow)
    stuck = [*ok, dict(row, depth=0.005, over_nodal=1.0, converged=False)]
    assert "d/R 0.005: x1.00 (not converged)" in _goal(stuck)
