"""The plates benchmark's quick mode: files written, real numbers in them, its goals read."""

import csv

import pytest

from benchmarks import plates


def test_hertz_is_each_contact_s_half_of_the_approach():
    # F = 4/3 E* sqrt(R) (d/2)^(3/2), E* = E / (1 - nu^2)
    e_star = plates.E / (1 - plates.NU**2)
    assert plates.hertz(1e-3) == pytest.approx(4 / 3 * e_star * 0.02**0.5 * 0.5e-3**1.5)


def test_quick_run_writes_its_table_and_goals(tmp_path):
    rows = plates.run(quick=True, out=tmp_path)
    table = list(csv.DictReader((tmp_path / "plates.csv").open()))
    assert len(table) == len(rows) == 2 * len(plates.PRESSES)
    md = (tmp_path / "plates.md").read_text()
    assert (tmp_path / "plates.png").stat().st_size > 10_000
    assert "| bricks 6 mm: within 15 % of Hertz at 1.0 mm |" in md
    assert "the force monotone in the approach (weighted)" in md
    for r in rows:
        assert r["frame_s"] > 0 and r["hertz"] > 0
    # 6 mm bricks, 1 mm: node rows 51 % under, weighted gaps within 15 %
    last = {r["gaps"]: r for r in rows if r["press_mm"] == pytest.approx(1.0)}
    assert abs(last["weighted"]["error"]) < 15 < abs(last["nodal"]["error"])
