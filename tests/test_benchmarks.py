"""The benchmarks' quick mode runs in the default suite, so that they never rot."""

import csv

from benchmarks.__main__ import main


def test_benchmarks_quick(tmp_path):
    main(["all", "--quick", "--out", str(tmp_path)])
    for name in ("assembly", "linear_solve", "queries", "hertz", "hertz_bodies", "posing"):
        rows = list(csv.DictReader((tmp_path / f"{name}.csv").open()))
        assert rows, name
        assert (tmp_path / f"{name}.md").read_text().strip()
        assert (tmp_path / f"{name}.png").stat().st_size > 1000
    rows = list(csv.DictReader((tmp_path / "assembly.csv").open()))
    assert all(float(r["rel_diff"]) < 1e-12 for r in rows if r.get("rel_diff"))
    rows = list(csv.DictReader((tmp_path / "posing.csv").open()))
    assert all(r["inverted_poses"] == "0" and float(r["min_quality"]) > 0 for r in rows)
