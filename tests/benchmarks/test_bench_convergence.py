"""The mesh-convergence study's quick mode: files written, rates that mean something."""

import csv
import math

import numpy as np
import pytest

from benchmarks import convergence, convergence_rates


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    out = tmp_path_factory.mktemp("convergence")
    rows = convergence.run(quick=True, out=out)
    return out, rows, convergence.rate_rows(rows)


def rate(rates, series, error):
    (row,) = [r for r in rates if r["series"] == series and r["error"] == error]
    return row


def test_files_written(quick):
    out, rows, _ = quick
    csv_rows = list(csv.DictReader((out / "convergence.csv").open()))
    assert len(csv_rows) == len(rows)
    levels = convergence.LAME_LEVELS[True]
    n_lame = len(convergence.LAME_NU) * sum(len(v) for v in levels.values())
    assert sum(r["study"] == "lame" for r in csv_rows) == n_lame
    assert sum(r["study"] == "hertz" for r in csv_rows) == len(convergence.HERTZ_SIZES[True])
    md = (out / "convergence.md").read_text()
    assert md.index("| machine |") < md.index("## Lame") < md.index("## Fitted rates")
    assert (out / "convergence.png").stat().st_size > 10_000


def test_lame_rates(quick):
    out, rows, rates = quick
    md = (out / "convergence.md").read_text()
    for element in ("tet4", "hex8"):
        l2 = rate(rates, f"{element}, nu 0.3", "L2 u")
        assert 1.8 < l2["rate"] < 2.2, (element, l2)
        assert f"| {element}, nu 0.3 | L2 u | " in md and f"| {l2['rate']:.2f} |" in md
        assert 0.8 < rate(rates, f"{element}, nu 0.3", "L2 sigma")["rate"] < 1.3
        assert 1.4 < rate(rates, f"{element}, nu 0.3", "max u_r")["rate"] < 2.2
        for nu in convergence.LAME_NU:
            series = sorted(
                (
                    r
                    for r in rows
                    if r["element"] == element and r["nu"] == nu and r["study"] == "lame"
                ),
                key=lambda r: r["h"],
            )
            for key in ("max_ur", "l2_u", "l2_sigma"):
                errs = [r[key] for r in series]
                assert all(e > 0 for e in errs) and errs == sorted(errs), (element, nu, key)
            # pointwise, on two sequences of centroids (see the notes): smaller at the end
            hoop = [r["hoop_mid"] for r in series]
            assert 0 < hoop[0] < hoop[-1], (element, nu)
    # the coarsest meshes: a few percent in displacement, no more
    assert all(r["l2_u"] < 0.2 for r in rows if r["study"] == "lame")


def test_full_hex8_locks_b_bar_and_tet_split_barely(quick):
    _, rows, _ = quick

    def finest(element, nu):
        series = [r for r in rows if r["study"] == "lame" and r["element"] == element]
        return min((r for r in series if r["nu"] == nu), key=lambda r: r["h"])

    def ratio(element):
        return finest(element, 0.45)["l2_sigma"] / finest(element, 0.3)["l2_sigma"]

    assert ratio("hex8 full") > 2.5  # fully integrated bricks lock
    assert ratio("hex8") < 1.5  # B-bar bricks do not
    assert ratio("tet4") < 1.5
    assert finest("hex8", 0.45)["l2_sigma"] < 0.5 * finest("hex8 full", 0.45)["l2_sigma"]


def test_hertz_rows(quick):
    _, rows, rates = quick
    hertz = sorted((r for r in rows if r["study"] == "hertz"), key=lambda r: r["h"])
    assert abs(hertz[0]["radius_err"]) < 0.05
    assert abs(hertz[0]["pressure_err"]) < 0.05
    # the force tends to the half-space model error (a few percent high), not to zero
    assert all(0.02 < r["force_err"] < 0.1 for r in hertz[:-1])  # all but the coarsest
    assert "levels off" in rate(rates, "hex8 octant", "total force")["note"]


def test_fitted_rate():
    h = np.array([0.4, 0.2, 0.1, 0.05])
    assert convergence.fitted_rate(h, 3 * h**2) == pytest.approx(2.0, abs=1e-12)
    assert convergence.fitted_rate(h, -3 * h) == pytest.approx(1.0, abs=1e-12)
    assert math.isnan(convergence.fitted_rate(h, [0.1, 0.01, -0.001, -0.002]))
    assert math.isnan(convergence.fitted_rate(h[:1], [0.1]))
    row = convergence_rates._rate_row(
        "hertz",
        "s",
        [{"h": x, "e": e} for x, e in zip(h, [0.1, 0.01, -0.001, -0.002])],
        "e",
        "e",
        "1",
    )
    assert math.isnan(row["rate"]) and "changes sign" in row["note"]
