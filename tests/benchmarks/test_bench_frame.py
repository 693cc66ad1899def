"""The frame study's quick mode: a contact frame against one factorisation and solve."""

import csv

from benchmarks import frame


def test_frame_study_quick(tmp_path):
    rows = frame.run(quick=True, out=tmp_path)
    assert {r["scene"] for r in rows} == {"Hertz sphere on block", "hand cup"}
    for r in rows:
        assert r["converged"] == "yes"
        # the contact zone is marked: the rows' compliances come from partial solves
        assert r["marked"] > 0 and r["partial_solves"] > 0
        assert r["back_solves"] <= 12  # a free ball's six modes at most, per body
        parts = r["geometry_s"] + r["contact_s"] + r["factor_s"] + r["other_s"]
        assert abs(parts - r["frame_s"]) < 1e-9 + 0.01 * r["frame_s"]
        assert r["ratio"] == r["frame_s"] / r["plain_s"] > 0
    saved = list(csv.DictReader((tmp_path / "frame.csv").open()))
    assert len(saved) == len(rows)
    assert "frame / (factor + solve)" in (tmp_path / "frame.md").read_text()
    assert (tmp_path / "frame.png").stat().st_size > 1000
