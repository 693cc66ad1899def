"""The holding study's quick mode: the pads' least grip against m g / (2 mu), files written."""

import csv
from pathlib import Path

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


def test_with_models_sets_the_flesh_and_the_ball_asked_only():
    from benchmarks._common import with_models
    from contact.scene.read import load_scene

    scene = load_scene(Path(__file__).resolve().parents[2] / "examples" / "pinch.toml")
    assert scene.hand.flesh.model == scene.ball.model == "neo-hookean"
    flesh = with_models(scene, "linear")
    assert flesh.hand.flesh.model == "linear" and flesh.ball.model == "neo-hookean"
    both = with_models(scene, "linear", ball="linear")
    assert both.hand.flesh.model == both.ball.model == "linear"
    assert both.hand.flesh.E == scene.hand.flesh.E and both.ball.density == scene.ball.density
