"""docs/results.md's sample report is what a run of the shipped example prints."""

from pathlib import Path

from contact.app.report import parse_line

ROOT = Path(__file__).resolve().parents[1]


def _sample() -> list[dict[str, str]]:
    """The indented block that follows the document's pointer to this test."""
    text = (ROOT / "docs" / "results.md").read_text().splitlines()
    start = next(i for i, ln in enumerate(text) if "test_report_sample.py" in ln) + 1
    while not text[start].startswith("    "):
        start += 1
    block = []
    for ln in text[start:]:
        if not ln.startswith("    "):
            break
        block.append(parse_line(ln.strip()))
    return block


def test_the_sample_report_is_a_run_of_finger_press(finger_press) -> None:
    sample = _sample()
    assert len(sample) >= 2
    code, lines, _, _, _ = finger_press  # a run of examples/finger_press.toml (conftest)
    assert code == 0
    run = [parse_line(ln) for ln in lines if ln]
    by_key = {(r.get("frame"), r.get("frames")): r for r in run}
    for line in sample:
        got = by_key[(line.get("frame"), line.get("frames"))]
        assert list(got) == list(line)
        for key, value in line.items():
            if key not in ("s", "results"):  # the time taken and the folder are the run's
                assert got[key] == value, (key, got[key], value)
