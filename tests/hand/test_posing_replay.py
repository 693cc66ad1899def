"""The paired replay of posing frames reproduces the warm chain it recorded, bit for bit."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from benchmarks.posing_replay import compare, main, record, replay


def test_replay_reproduces_the_recorded_chain(tmp_path):
    (path,) = record(tmp_path, fraction=1.0, seeds=[3], sequences=1, resolution="coarse")
    rec = np.load(path)
    assert rec["has_start"].sum() == len(rec["ids"]) - 1  # every frame but the first
    assert rec["newton_steps"].sum() > 0  # the full limits fold the coarse hand too
    rows = replay([path])
    assert [r["frame"] for r in rows] == list(range(len(rec["ids"])))
    # the same problems, the same code: the same Newton steps and qualities exactly
    np.testing.assert_array_equal([r["newton_steps"] for r in rows], rec["newton_steps"])
    np.testing.assert_array_equal([r["min_quality"] for r in rows], rec["min_quality"])
    assert "lower on 0 frames, higher on 0" in compare(rows, rows)


def test_command_line_writes_and_pairs_csv(tmp_path, capsys):
    folder = tmp_path / "rec"
    record(folder, fraction=0.5, seeds=[0], sequences=1, resolution="coarse")
    out = tmp_path / "a.csv"
    main(["replay", str(folder), "--csv", str(out)])
    main(["replay", str(folder), "--against", str(out)])
    text = capsys.readouterr().out
    assert "49 frames" in text and "lower on 0 frames, higher on 0" in text
    with out.open() as f:
        assert len(list(csv.DictReader(f))) == 49


def test_replay_of_nothing_or_other_frames_is_an_error(tmp_path):
    with pytest.raises(ValueError, match="no recorded files"):
        replay([])
    row = {"seed": 0, "sequence": 0, "frame": 0, "seconds": 1.0, "newton_steps": 0}
    with pytest.raises(ValueError, match="not of the same frames"):
        compare([row], [dict(row, frame=1)])
