"""The finite-strain benchmark's quick mode: files written and real numbers in them."""

import csv

import pytest

from benchmarks import finite


@pytest.mark.slow
def test_quick_run_writes_its_table_and_goals(tmp_path):
    rows = finite.run(quick=True, out=tmp_path)
    table = list(csv.DictReader((tmp_path / "finite.csv").open()))
    assert len(table) == len(rows) == len(finite.SIZES[True])
    md = (tmp_path / "finite.md").read_text()
    assert md.startswith("# Finite strain") and "| cpu |" in md
    assert "| met |" in md or "| MISSED |" in md
    for r in rows:
        assert r["steps_max"] >= 2 and r["time_ratio"] > 0
        # the finite squeeze is softer than the linear one at d/R 0.2 (the contact widens)
        assert 0 < r["force_finite"] and 0 < r["force_linear"]


def test_the_readme_example_is_made_neo_hookean_in_its_ball_and_flesh_only():
    from benchmarks.finite_example import EXAMPLE, _neo_hookean

    text = _neo_hookean(EXAMPLE.read_text())
    lines = [line for line in text.splitlines() if 'model = "neo-hookean"' in line]
    assert [line.split("=")[0].strip() for line in lines] == ["material", "flesh"]
    assert all(line.rstrip().endswith("}") or "#" in line for line in lines)
    with pytest.raises(RuntimeError, match="material and flesh"):
        _neo_hookean("[ball]\nradius = 0.03\n")
    flesh = _neo_hookean(EXAMPLE.read_text(), ("flesh",))
    lines = [line for line in flesh.splitlines() if 'model = "neo-hookean"' in line]
    assert [line.split("=")[0].strip() for line in lines] == ["flesh"]
