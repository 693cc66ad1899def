"""The Hertz comparison with SfePy (optional `benchmarks` extra): quick mode, real numbers."""

import csv

import pytest

import benchmarks.sfepy_hertz as sh

# SfePy's own use of pyparsing's old names
pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")


def test_sfepy_hertz_quick(tmp_path):
    pytest.importorskip("sfepy")
    rows = sh.run(quick=True, out=tmp_path)
    ours = [r for r in rows if r["code"] == "ours"]
    theirs = [r for r in rows if r["code"] == "SfePy"]
    assert len(ours) == len(sh.SIZES[True])
    assert len(theirs) == len(sh.SIZES[True]) * len(sh.PENALTIES[True])
    for r in theirs:
        assert r["converged"] == "yes"
        assert r["total_s"] > 0 and r["iterations"] >= 1
        assert r["equilibrium"] < 1e-8  # K u of the contact nodes = the penalty forces
        # same advance, same mesh: SfePy's force within a few % of ours, more so when stiff
        assert abs(r["force_vs_ours_pct"]) < (0.5 if r["penalty"] >= 1e4 else 3.0)
        o = next(x for x in ours if x["fine_size"] == r["fine_size"])
        assert abs(r["radius_err_pct"] - o["radius_err_pct"]) < 1.0
        assert abs(r["pressure_err_pct"] - o["pressure_err_pct"]) < 2.0
    saved = list(csv.DictReader((tmp_path / "sfepy_hertz.csv").open()))
    assert len(saved) == len(rows)
    text = (tmp_path / "sfepy_hertz.md").read_text()
    assert "| sfepy |" in text and "## Goal" in text
    assert (tmp_path / "sfepy_hertz.png").stat().st_size > 1000


def test_sfepy_hertz_skips_without_sfepy(tmp_path, monkeypatch):
    monkeypatch.setattr(sh, "sfepy_available", lambda: False)
    assert sh.run(quick=True, out=tmp_path) == []
    assert "not installed" in (tmp_path / "sfepy_hertz.md").read_text()
