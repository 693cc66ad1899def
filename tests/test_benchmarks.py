"""The benchmarks' quick mode runs in the default suite, so that they never rot."""

import csv
import importlib
from pathlib import Path

from benchmarks import BENCHMARKS
from benchmarks.__main__ import main

#: Studies whose quick mode runs here; the others have their own test_bench_NAME.py.
HERE = ("assembly", "linear_solve", "queries", "hertz", "hertz_bodies", "posing", "lcp")


def test_every_study_runs_and_has_a_quick_test():
    tests = Path(__file__).parent
    for name in BENCHMARKS:
        assert callable(importlib.import_module(f"benchmarks.{name}").run), name
        assert name in HERE or (tests / f"test_bench_{name}.py").exists(), name


def test_benchmarks_quick(tmp_path):
    main([*HERE, "--quick", "--out", str(tmp_path)])
    for name in ("assembly", "linear_solve", "queries", "hertz", "hertz_bodies", "posing"):
        rows = list(csv.DictReader((tmp_path / f"{name}.csv").open()))
        assert rows, name
        assert (tmp_path / f"{name}.md").read_text().strip()
        assert (tmp_path / f"{name}.png").stat().st_size > 1000
    rows = list(csv.DictReader((tmp_path / "assembly.csv").open()))
    assert all(float(r["rel_diff"]) < 1e-12 for r in rows if r.get("rel_diff"))
    rows = list(csv.DictReader((tmp_path / "lcp.csv").open()))
    assert all(r["solved"] == "True" and r["same"] == "True" for r in rows)
    assert all(abs(float(r["force_err_pct"])) < 3.0 for r in rows)
    rows = list(csv.DictReader((tmp_path / "posing.csv").open()))
    assert all(r["inverted_poses"] == "0" and float(r["min_quality"]) > 0 for r in rows)
