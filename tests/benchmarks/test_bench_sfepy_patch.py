"""The SfePy comparison on graded tetrahedral octants: its rules without SfePy, quick mode with."""

import csv
from types import SimpleNamespace

import pytest

import benchmarks.sfepy_patch as sp

# SfePy's own use of pyparsing's old names
pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")


def _ours(r=-0.5, p=-0.3, t=1.0):
    return {
        "code": "ours",
        "fine_size": 0.01,
        "depth": 0.01,
        "dofs": 1000,
        "radius_err_pct": r,
        "pressure_err_pct": p,
        "total_s": t,
        "converged": "yes",
        "runs": 1,
        "load": "0",
    }


def _theirs(k, r, p, t, conv="yes", ours=None, its=10):
    row = {
        "code": "SfePy",
        "fine_size": 0.01,
        "depth": 0.01,
        "dofs": 1000,
        "penalty": k,
        "radius_err_pct": r,
        "pressure_err_pct": p,
        "total_s": t,
        "converged": conv,
        "runs": 1,
        "iterations": its,
        "force_vs_ours_pct": 0.0,
    }
    row["same_accuracy"] = "yes" if sp.same_accuracy(row, ours or _ours()) else "no"
    return row


def test_same_accuracy_is_ours_plus_half_a_point_and_converged():
    ours = _ours(-0.5, -0.3)
    assert sp.same_accuracy(_theirs(1e3, +0.99, -0.79, 1.0), ours)
    assert not sp.same_accuracy(_theirs(1e3, -1.01, 0.0, 1.0), ours)
    assert not sp.same_accuracy(_theirs(1e3, 0.0, +0.81, 1.0), ours)
    assert not sp.same_accuracy(_theirs(1e3, 0.0, 0.0, 1.0, conv="no"), ours)


def test_verdict_takes_the_fastest_run_at_the_same_accuracy():
    ours = _ours(t=1.0)
    rows = [
        ours,
        _theirs(1e3, -2.0, 0.0, 5.0),
        _theirs(1e4, -0.5, -0.3, 20.0),
        _theirs(1e5, -0.5, -0.3, 12.0),
    ]
    lines, met = sp.verdicts(rows)
    assert met is True and len(lines) == 1
    assert "= 0.083" in lines[0] and "k = 1e+05" in lines[0] and "missed" not in lines[0]
    assert sp.verdicts([ours, _theirs(1e5, -0.5, -0.3, 8.0)])[1] is False


def test_verdict_without_a_run_at_the_same_accuracy_takes_the_most_accurate():
    rows = [
        _ours(t=1.0),
        _theirs(1e3, -3.0, 0.0, 5.0),
        _theirs(1e4, -1.5, 0.0, 20.0),
        _theirs(1e5, -0.5, 0.0, 30.0, conv="no"),
    ]
    lines, met = sp.verdicts(rows)
    assert "no SfePy run reaches" in lines[0] and "k = 1e+04" in lines[0]
    assert met is True  # 1 / 20


def test_largest_mesh_sweep_starts_soft_stops_at_the_first_match_and_keeps_the_budget(
    monkeypatch,
):
    ours = _ours()
    calls = []
    # 1e3 had the same accuracy on the mesh before, in 10 steps; 3e3 in 14, 1e4 in 40
    before = [
        ours,
        _theirs(1e3, -0.5, -0.3, 5.0, its=10),
        _theirs(3e3, -0.5, -0.3, 7.0, its=14),
        _theirs(1e4, -0.5, -0.3, 20.0, its=40),
    ]
    # on the largest: 1e3 misses, 3e3 has it
    results = {
        1e3: (-0.5, -1.5, 100.0, 10),
        3e3: (-0.5, -0.4, 140.0, 14),
        1e4: (-0.5, -0.3, 400.0, 40),
    }

    def theirs(mesh, body, plane, o, k):
        calls.append(k)
        r, p, t, its = results[k]
        return _theirs(k, r, p, t, ours=o, its=its)

    monkeypatch.setattr(sp, "_ours", lambda mesh, h, d: (None, None, dict(ours)))
    monkeypatch.setattr(sp, "_theirs", theirs)
    monkeypatch.setattr(sp, "_ours_again", lambda mesh, row: None)
    monkeypatch.setattr(sp, "_theirs_again", lambda *a: calls.append("again"))
    mesh = SimpleNamespace(n_dofs=4000)
    rows, notes = sp._press_both(mesh, 0.005, 0.01, True, before, 3)
    assert [r["penalty"] for r in rows[1:]] == [1e3, 3e3]
    assert calls == [1e3, 3e3]  # not 1e4: 3e3 has the same accuracy
    assert notes and "repeat" in notes[0]  # 240 s spent + 140 s past the 360 s budget
    # with the budget nearly spent the second run is predicted past it and left out
    calls.clear()
    monkeypatch.setattr(sp, "LARGEST_BUDGET_S", 150.0)
    _rows, notes = sp._press_both(mesh, 0.005, 0.01, True, before, 3)
    assert calls == [1e3] and "k = 3e+03" in notes[0]
    # a mesh that is not the largest runs every penalty
    calls.clear()
    monkeypatch.setattr(sp, "PENALTIES", (1e3, 3e3, 1e4))
    sp._press_both(mesh, 0.005, 0.01, False, before, 1)
    assert calls == [1e3, 3e3, 1e4]


def test_sfepy_patch_skips_without_sfepy(tmp_path, monkeypatch):
    monkeypatch.setattr(sp, "sfepy_available", lambda: False)
    assert sp.run(quick=True, out=tmp_path) == []
    assert "not installed" in (tmp_path / "sfepy_patch.md").read_text()


@pytest.mark.slow
def test_sfepy_patch_quick(tmp_path):
    pytest.importorskip("sfepy")
    rows = sp.run(quick=True, out=tmp_path)
    ours = [r for r in rows if r["code"] == "ours"]
    theirs = [r for r in rows if r["code"] == "SfePy"]
    assert len(ours) == 1 and len(theirs) == len(sp.PENALTIES)
    for r in theirs:
        assert r["converged"] == "yes" and r["equilibrium"] < 1e-8
        # same mesh, same DOFs, same discrete model: the force within the penalty's sinking in
        assert abs(r["force_vs_ours_pct"]) < (2.0 if r["penalty"] < 1e4 else 0.2)
    saved = list(csv.DictReader((tmp_path / "sfepy_patch.csv").open()))
    assert len(saved) == len(rows)
    text = (tmp_path / "sfepy_patch.md").read_text()
    assert "| sfepy |" in text and "ours / SfePy's fastest run at the same accuracy" in text
