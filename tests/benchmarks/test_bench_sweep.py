"""The sweep study's quick mode: 4 runs on one and two local workers, the files written."""

import csv

import pytest

from benchmarks import sweep


@pytest.mark.slow  # two embedded clusters and a plain run: about a minute on 2 cores
def test_quick_sweep(tmp_path):
    rows = sweep.run(quick=True, out=tmp_path)
    assert [r["runs"] for r in rows] == [4, 4]
    assert all(r["status"] == 0 and r["per_second"] > 0 for r in rows)
    saved = list(csv.DictReader((tmp_path / "sweep.csv").open()))
    assert len(saved) == 2
    md = (tmp_path / "sweep.md").read_text()
    assert md.startswith("# Sweeps on Dask") and "Two local workers over one" in md
