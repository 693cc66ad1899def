"""The contact-patch study's quick mode: one coarse graded octant, one press (fTetWild: slow)."""

import csv

import pytest

from benchmarks.patch import run


@pytest.mark.slow
def test_files_are_written(tmp_path):
    rows = run(quick=True, out=tmp_path)
    assert rows and all(r["updates"] >= 1 and r["rows"] > 0 for r in rows)
    table = list(csv.DictReader((tmp_path / "patch.csv").open()))
    assert len(table) == len(rows)
    assert "goal" in (tmp_path / "patch.md").read_text()
