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


def test_posing_sequences_start_at_rest_and_move_at_once():
    """Every angle is keyed at rest at time 0: the sequence leaves rest from the first frame.

    (An empty first key keys nothing: the first random key would be held from time 0.)
    """
    import numpy as np

    from benchmarks.posing import SEQ_FPS, sequence_keys
    from contact.hand.keyframes import Keyframes
    from contact.hand.shipped import load_hand

    sk = load_hand("coarse").skeleton
    keys = sequence_keys(sk.limits, 1.0, np.random.default_rng(0))
    frames = Keyframes(sk, keys)
    start, next_ = frames.pose(0.0), frames.pose(1.0 / SEQ_FPS)
    assert set(start) == set(sk.limits)
    assert all(v == 0.0 for v in start.values())
    assert max(abs(v) for v in next_.values()) > 0.1  # degrees, moving already
    assert frames.pose(1.0) == keys[1]["angles"]
