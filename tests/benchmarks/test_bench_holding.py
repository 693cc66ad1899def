"""The holding study's quick mode: the pads' least grip against m g / (2 mu), files written."""

import csv

from benchmarks import holding


def test_quick_pads(tmp_path):
    rows = holding.run(quick=True, out=tmp_path)
    assert [r["scene"] for r in rows] == ["pads"]
    pads = rows[0]
    assert pads["found"] and pads["error"] <= 0.01
    assert pads["trials"] >= 2 and pads["contact_solves"] >= pads["frame_solves"] >= 1
    saved = list(csv.DictReader((tmp_path / "holding.csv").open()))
    assert len(saved) == 1
    md = (tmp_path / "holding.md").read_text()
    assert md.startswith("# The least grip that holds") and "goal 1 %): met" in md
