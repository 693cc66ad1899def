"""The unilateral contact solve on large contact sets: time against one factorisation.

A whole hand on a ball makes contact sets of a few thousand rows. The contact-space
iteration solves their forces as a frictionless LCP (:func:`contact.solver.lcp.solve_lcp`): a
primal active-set method whose steps solve the closed rows' equality problem, each by
bordering the last Cholesky factorisation with the rows opened and closed since.

The rows here are the nodes of a square grid on an elastic half-space, pressed by a rigid
sphere: the compliance between two nodes is Boussinesq's ``(1 - nu^2) / (pi E r)``, a
node's own that of a uniformly loaded square cell (``4 (1 - nu^2) ln(1 + sqrt 2) / (pi E
h)``), and the gap before contact ``r^2 / 2R - d``; the rows deeper than half the overlap
start closed, as the contact iteration's first set. The solve must close the rows inside
Hertz's contact radius ``sqrt(R d)`` with the force ``4/3 E* sqrt(R) d^1.5``: the table
gives both errors (the grid's resolution), the closed rows, the LCP's steps, its time and
the time of one Cholesky factorisation of the closed rows' compliance, and their ratio
(goal: a few factorisations), also from no force (``start`` omitted: the rows that
penetrate without forces closed, every other open). Run with
``python -m benchmarks lcp``.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import scipy.linalg as sla

from contact.solver.lcp import solve_lcp

from ._common import (
    Column,
    load_average,
    machine_info,
    markdown_table,
    plot_loglog,
    results_dir,
    write_csv,
    write_markdown,
)

__all__ = ["SIZES", "half_space", "run"]

#: Grid nodes along the side: full run and ``--quick``.
SIZES = {False: (20, 32, 45, 55), True: (12, 20)}
#: Young's modulus (Pa), Poisson's ratio, sphere radius (m), press (m).
E, NU, RADIUS, PRESS = 1e6, 0.45, 0.02, 2e-4


def half_space(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Compliance, initial gaps and positions of an ``n x n`` grid pressed by a sphere.

    The grid spans twice Hertz's contact diameter.

    Returns
    -------
    w : ndarray, shape (n^2, n^2)
    gap : ndarray, shape (n^2,)
        Gaps before contact (m), negative where the sphere overlaps.
    x : ndarray, shape (n^2, 2)
    h : float
        Grid spacing (m).
    """
    a = math.sqrt(RADIUS * PRESS)
    s = np.linspace(-2 * a, 2 * a, n)
    h = float(s[1] - s[0])
    x = np.stack(np.meshgrid(s, s), axis=-1).reshape(-1, 2)
    r = np.linalg.norm(x[:, None] - x[None], axis=2)
    c = (1 - NU**2) / (math.pi * E)
    np.fill_diagonal(r, 1.0)
    w = c / r
    np.fill_diagonal(w, 4 * c * math.log(1 + math.sqrt(2)) / h)
    gap = (x**2).sum(axis=1) / (2 * RADIUS) - PRESS
    return w, gap, x, h


def _case(n: int) -> dict:
    w, gap, _, h = half_space(n)
    m = gap.size
    # closed at first: the rows deeper than half the deepest overlap, as the contact
    # iteration's first set (contact.solver.contactset.first_set)
    start = np.where(gap < -0.5 * PRESS, 1.0, 0.0)
    t = time.perf_counter()
    res = solve_lcp(w, np.zeros((m, 0)), -gap, np.zeros(0), tol=1e-9 * PRESS, start=start)
    lcp_s = time.perf_counter() - t
    t = time.perf_counter()
    cold = solve_lcp(w, np.zeros((m, 0)), -gap, np.zeros(0), tol=1e-9 * PRESS)
    cold_s = time.perf_counter() - t
    closed = res.lam > 0
    idx = np.flatnonzero(closed)
    t = time.perf_counter()
    sla.cho_factor(w[np.ix_(idx, idx)])
    chol_s = time.perf_counter() - t
    e_star = E / (1 - NU**2)
    force = 4.0 / 3.0 * e_star * math.sqrt(RADIUS) * PRESS**1.5
    a = math.sqrt(RADIUS * PRESS)
    radius = math.sqrt(closed.sum() * h * h / math.pi)  # of the closed cells' area
    return {
        "rows": m,
        "closed": int(closed.sum()),
        "steps": res.steps,
        "solved": res.solved,
        "lcp_s": lcp_s,
        "cholesky_s": chol_s,
        "ratio": lcp_s / chol_s,
        "cold_steps": cold.steps,
        "cold_s": cold_s,
        "cold_ratio": cold_s / chol_s,
        "same": bool(np.allclose(cold.lam, res.lam, rtol=1e-8, atol=1e-12 * res.lam.max())),
        "force_err_pct": 100 * (res.lam.sum() / force - 1),
        "radius_err_pct": 100 * (radius / a - 1),
        "min_gap": float(res.gap.min()),
    }


COLUMNS = (
    Column("rows", "rows", ","),
    Column("closed", "closed", ","),
    Column("steps", "LCP steps"),
    Column("lcp_s", "LCP (s)", ".3f"),
    Column("cholesky_s", "one Cholesky (s)", ".3f"),
    Column("ratio", "LCP / Cholesky", ".1f"),
    Column("cold_steps", "steps, from no force"),
    Column("cold_s", "LCP, from no force (s)", ".3f"),
    Column("cold_ratio", "its ratio", ".1f"),
    Column("force_err_pct", "force vs Hertz (%)", "+.2f"),
    Column("radius_err_pct", "radius vs Hertz (%)", "+.2f"),
)


def run(quick: bool = False, out: str | Path | None = None) -> list[dict]:
    """Run the study and write ``lcp.{csv,md,png}``; return its rows."""
    folder = results_dir(out, quick)
    info = machine_info()
    info["load average at start"] = load_average()
    rows = []
    for n in SIZES[quick]:
        row = _case(n)
        rows.append(row)
        print(
            f"[lcp] {row['rows']} rows: {row['closed']} closed in {row['steps']} steps, "
            f"{row['lcp_s']:.3f} s (one Cholesky {row['cholesky_s']:.3f} s), force "
            f"{row['force_err_pct']:+.2f} % of Hertz",
            flush=True,
        )
    info["load average at end"] = load_average()
    write_csv(folder / "lcp.csv", rows, list(rows[0]))
    write_markdown(
        folder / "lcp.md",
        "Unilateral contact solve: large contact sets",
        info,
        [
            (
                "Rigid sphere on a Boussinesq half-space",
                markdown_table(rows, COLUMNS)
                + f"\n\nE = {E:g} Pa, nu = {NU:g}, R = {RADIUS:g} m, press {PRESS:g} m; "
                "the grid spans twice Hertz's contact diameter. Radius: that of a disc "
                "of the closed cells' area. One Cholesky: of the closed rows' compliance "
                "(what one equality solve on the final set costs). From no force: the same "
                "solve without a start, the rows that penetrate without forces closed "
                "(solve_lcp's default); its forces equal the first's on every size.",
            )
        ],
    )
    plot_loglog(
        folder / "lcp.png",
        {
            "LCP": ([r["rows"] for r in rows], [r["lcp_s"] for r in rows]),
            "LCP, from no force": ([r["rows"] for r in rows], [r["cold_s"] for r in rows]),
            "one Cholesky": ([r["rows"] for r in rows], [r["cholesky_s"] for r in rows]),
        },
        title="Unilateral contact solve",
        xlabel="candidate rows",
    )
    return rows
