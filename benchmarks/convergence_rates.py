"""The fits of the convergence study: the errors' expected rates and the fitted ones.

:func:`fitted_rate` (a least-squares slope of ``log |error|`` on ``log h``) and
:func:`rate_rows`, one row per error of every series of :mod:`benchmarks.convergence`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

__all__ = ["HERTZ_ERRORS", "LAME_ERRORS", "fitted_rate", "rate_rows"]

#: Errors of each study: (row key, label, expected rate, why).
LAME_ERRORS: tuple[tuple[str, str, str, str], ...] = (
    ("max_ur", "max u_r", "2", "nodal displacement, linear elements"),
    ("l2_u", "L2 u", "2", "displacement L2, linear elements"),
    ("l2_sigma", "L2 sigma", "1", "stress L2, linear elements"),
    ("hoop_mid", "hoop mid", "1 (2)", "stress at a point, 2 at superconvergent brick centroids"),
)
HERTZ_ERRORS: tuple[tuple[str, str, str, str], ...] = (
    ("radius_err", "contact radius", "1 to 2", "the moment radius averages the patch edge"),
    ("pressure_err", "peak pressure", "1", "a stress"),
    ("force_err", "total force", "-", "tends to the half-space model error O(a/R), not 0"),
)

# --- rates ----------------------------------------------------------------------------------


def fitted_rate(h: Sequence[float], err: Sequence[float]) -> float:
    """Least-squares slope of ``log |err|`` against ``log h``.

    Parameters
    ----------
    h, err : sequence of float
        Mesh sizes and errors (at least two).

    Returns
    -------
    float
        The slope; NaN where fewer than two sizes, a zero or non-finite error, or an error
        that changes sign (then no rate means anything).
    """
    x = np.asarray(h, dtype=np.float64)
    e = np.asarray(err, dtype=np.float64)
    if len(x) < 2 or not np.isfinite(e).all() or (e == 0).any():
        return math.nan
    if (e > 0).any() and (e < 0).any():
        return math.nan
    return float(np.polyfit(np.log(x), np.log(np.abs(e)), 1)[0])


def _rate_row(
    study: str, series: str, rows: Sequence[dict], key: str, label: str, expected: str
) -> dict:
    rows = sorted(rows, key=lambda r: -r["h"])
    h = [r["h"] for r in rows]
    e = [r[key] for r in rows]
    rate = fitted_rate(h, e)
    last = fitted_rate(h[-2:], e[-2:])
    if any(v > 0 for v in e) and any(v < 0 for v in e):
        signs = ", ".join(f"{v:+.2g}" for v in e)
        note = f"changes sign ({signs}): no rate"
    elif not math.isnan(rate) and rate < 0.5:
        note = f"does not decrease: it levels off near {np.mean(e[-3:]):+.2g}"
    else:
        note = ""
    return {
        "study": study,
        "series": series,
        "error": label,
        "meshes": len(rows),
        "finest": e[-1],
        "rate": rate,
        "last_rate": last,
        "expected": expected,
        "note": note,
    }


def rate_rows(rows: Sequence[dict]) -> list[dict]:
    """The fitted rates of every error of every series of ``rows`` (see ``convergence.run``)."""
    out = []
    lame = [r for r in rows if r["study"] == "lame"]
    for element, nu in dict.fromkeys((r["element"], r["nu"]) for r in lame):
        series = [r for r in lame if r["element"] == element and r["nu"] == nu]
        for key, label, expected, _ in LAME_ERRORS:
            out.append(_rate_row("lame", f"{element}, nu {nu:g}", series, key, label, expected))
    hertz = [r for r in rows if r["study"] == "hertz"]
    if hertz:
        for key, label, expected, _ in HERTZ_ERRORS:
            out.append(_rate_row("hertz", "hex8 octant", hertz, key, label, expected))
    return out
