"""The scaling study's quick mode: cubes to ~20k DOFs and one traced frame of the example."""

from __future__ import annotations

import csv
import itertools

import pytest

from benchmarks import scaling


@pytest.fixture(scope="module")
def quick(tmp_path_factory: pytest.TempPathFactory):
    out = tmp_path_factory.mktemp("scaling")
    rows = scaling.run(quick=True, out=out)
    return out, rows


def test_files_written(quick):
    out, _ = quick
    rows = list(csv.DictReader((out / "scaling.csv").open()))
    assert {r["kind"] for r in rows} == {"cube", "example", "fit"}
    md = (out / "scaling.md").read_text()
    assert md.startswith("# Scaling") and "| machine | |" in md.splitlines()[2]
    assert "fits in 24 GiB" in md and "<= 60 s" in md
    assert (out / "scaling.png").stat().st_size > 10_000


def test_cubes_measured(quick):
    _, rows = quick
    cubes = [r for r in rows if r["kind"] == "cube"]
    for label in scaling.ELEMENTS.values():
        series = sorted((r for r in cubes if r["element"] == label), key=lambda r: r["dofs"])
        assert len(series) >= 3
        assert all(not r.get("note") for r in series), series
        assert max(r["dofs"] for r in series) <= scaling.QUICK_MAX_DOFS * 1.05
        for r in series:
            assert r["backend"] == "pardiso" or r["backend"] == "superlu"
            assert r["balance"] < 1e-8  # the reactions carry the load
            assert all(r[f"{p}_s"] > 0 for p in scaling.PHASES)
            # the best whole run is no faster than the phases' best times together
            assert r["whole_s"] >= sum(r[f"{p}_s"] for p in scaling.PHASES) * (1 - 1e-12)
            assert r["whole_peak_mib"] >= r["whole_inc_mib"] > 0
        peaks = [r["whole_peak_mib"] for r in series]
        incs = [r["whole_inc_mib"] for r in series]
        assert peaks == sorted(peaks) and peaks[-1] > peaks[0]
        assert incs == sorted(incs) and incs[-1] > 2 * incs[0]


def test_slopes(quick):
    _, rows = quick
    fits = {(r["element"], r["quantity"]): r for r in rows if r["kind"] == "fit"}
    for label in scaling.ELEMENTS.values():
        # assembly time grows with the DOFs; its slope (about 1) is measured by the study,
        # not asserted here: seconds on small sizes on a shared machine give 0.6 to 1.7
        assert 0.0 < fits[label, "assembly_s"]["slope"] < 3.0
        assert fits[label, "whole_inc_mib"]["slope"] > 0.5
        assert fits[label, "assembly_s"]["fit_over"] == "all sizes"  # none >= 50k in quick


def test_example_traced(quick):
    _, rows = quick
    (ex,) = [r for r in rows if r["kind"] == "example"]
    assert ex["exit_status"] in (0, 1) and not ex.get("note")
    assert ex["frames"] == 1
    assert 0 < ex["wall_s"] < 120 and ex["child_peak_mib"] > 50
    stages = [ex[f"{s}_s"] for s in scaling.STAGES]
    assert all(v >= 0 for v in stages)
    assert ex["contact_s"] > 0 and ex["assemble_factor_s"] > 0
    # the stages add up to the child's wall time
    assert sum(stages) == pytest.approx(ex["wall_s"], rel=1e-6)


def test_cap():
    assert scaling.max_dofs_cap(None, quick=True) <= scaling.QUICK_MAX_DOFS
    assert scaling.max_dofs_cap(300_000) == 300_000
    ns = scaling.cube_divisions(300_000)
    dofs = [3 * (n + 1) ** 3 for n in ns]
    assert dofs[-1] <= 300_000 * 1.03 and 9_000 < dofs[0] < 11_000
    assert all(1.5 < b / a < 2.6 for a, b in itertools.pairwise(dofs))
    assert scaling.fit_slope([1, 10, 100], [2, 200, 20_000]) == pytest.approx(2.0)
