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


def test_the_readme_example_gets_the_models_asked_on_its_ball_and_flesh_only():
    from benchmarks.finite_example import EXAMPLE, _models

    for ball, flesh in (("linear", "linear"), ("linear", "neo-hookean"), ("neo-hookean",) * 2):
        text = _models(EXAMPLE.read_text(), ball, flesh)
        lines = [line.split("#")[0] for line in text.splitlines() if "model = " in line]
        assert [line.split("=")[0].strip() for line in lines] == ["material", "flesh"]
        assert [line.count("model = ") for line in lines] == [1, 1]
        assert f'model = "{ball}" }}' in lines[0] and f'model = "{flesh}" }}' in lines[1]
    with pytest.raises(RuntimeError, match="material table"):
        _models("[ball]\nradius = 0.03\n", "linear", "linear")


def test_a_readme_row_not_run_to_its_frame_says_why(tmp_path, monkeypatch):
    from benchmarks import finite_example
    from contact.errors import InputError

    def refused(self, t, callback=None):
        raise InputError(f"frame t = {t:g}: the ball starts inside bone little_distal")

    monkeypatch.setattr(finite_example.GraspRun, "frame", refused)
    text = finite_example._models(finite_example.EXAMPLE.read_text(), "linear", "linear")
    row = finite_example._closing_frame(text, tmp_path, "neo-hookean flesh and ball")
    assert row["frame_s"] is None and row["converged"] is False
    assert row["error"] == "frame t = 0: the ball starts inside bone little_distal"
    line = finite_example.example_section([{"frame_s": 1.0}, row])
    assert "neo-hookean flesh and ball: not run to t = 1 (frame t = 0: the ball" in line
