"""The friction study's quick mode: files written, every frame solved, the figures sound."""

import csv
import math

import pytest

from benchmarks import friction


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    out = tmp_path_factory.mktemp("friction")
    return out, friction.run(quick=True, out=out)


def test_files_are_written(quick):
    out, rows = quick
    saved = list(csv.DictReader((out / "friction.csv").open()))
    assert len(saved) == len(rows) > 0
    assert {r["study"] for r in saved} == {"cost", "mu", "ratio", "refinement"}
    md = (out / "friction.md").read_text()
    assert md.startswith("# Coulomb friction")
    assert "| cpu |" in md and "| date |" in md
    assert "friction / frictionless" in md and "Refinement goal" in md
    assert (out / "friction.png").stat().st_size > 1000


def test_every_row_solved(quick):
    _, rows = quick
    for r in rows:
        assert r["solved"] and r["converged"], (r["scene"], r["stop_reason"])
        assert 1 <= r["newton"] and 1 <= r["updates"]
        assert r["residual"] <= 1e-9
        assert r["stick"] + r["slip"] > 0


def test_cost_rows_compare_the_same_frame(quick):
    _, rows = quick
    cost = [r for r in rows if r["study"] == "cost"]
    assert {r["scene"] for r in cost} == {"hand cup", "two-pad pinch"}
    for r in cost:
        assert r["free_converged"] and r["free_frame_s"] > 0 and r["frame_s"] > 0
        assert r["ratio"] == r["frame_s"] / r["free_frame_s"]
        assert r["met"] in ("met", "**missed**")
        # the split covers the frame
        parts = sum(r[k] for k in friction.PARTS)
        assert math.isclose(parts, r["frame_s"], rel_tol=0.01, abs_tol=1e-6)
