"""Mesh convergence: Lame's thick sphere and Hertz's ball, errors against h with fitted rates.

Lame: a hollow sphere (inner radius 0.8 m, outer 1 m, E = 1 MPa) under an internal
pressure of 10 kPa, meshed whole as a free body (no support; the rigid-body modes are
removed exactly) by :func:`fem.shell_mesh` (a cubed sphere of bricks, ``4 k`` cells along
each face edge and ``k`` through the wall, so the cell shapes stay the same as ``k``
grows) and, for tet4, by the same bricks split into 24 tetrahedra each
(:func:`fem.hex_to_tet`). Errors against Lame's exact solution:

- ``max u_r``: the largest nodal error of the radial displacement, relative to the
  largest exact radial displacement (at the inner surface);
- ``L2 u``: the relative L2 norm of the displacement error (vector), integrated over the
  mesh with a quadrature exact to degree 5 (27 Gauss points per brick, 64 collapsed-cube
  points per tetrahedron), not the stiffness rule;
- ``L2 sigma``: the relative L2 norm of the stress error (Frobenius), same quadrature;
- ``hoop mid``: the largest error of the hoop stress at the centroids of the cells that
  reach the mid-wall sphere ``r = 0.9 m`` (a pointwise check), relative to the exact hoop
  stress there.

``h`` is the mean edge length of the cells. Poisson's ratio 0.3; the same meshes are also
run at 0.45, where fully integrated bricks stiffen (volumetric locking, a known limit of
HEX8 in :mod:`fem`). Rates are least-squares slopes of ``log error`` against ``log h``.

Hertz: the octant model of :mod:`contact.cases.hertz` (ball R = 1 m, E = 1 Pa, nu = 0.3,
between rigid frictionless plates advancing 0.01 R), ``h`` its cell size at the poles;
the contact radius and peak pressure against Hertz for the solver's own force (as in
:mod:`benchmarks.hertz`) and the total force against Hertz's force for the plate's advance.
"""

from __future__ import annotations

import gc
import math
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

import fem
from contact.cases.hertz import effective_modulus, hertz_check
from fem.elements import ELEMENTS
from fem.mapping import det3, inv3, jacobians

from ._common import (
    Column,
    load_average,
    machine_info,
    markdown_table,
    results_dir,
    write_csv,
    write_markdown,
)

__all__ = [
    "HERTZ_DEPTH",
    "HERTZ_SIZES",
    "LAME",
    "LAME_LEVELS",
    "LAME_NU",
    "fitted_rate",
    "hertz_case",
    "lame_case",
    "lame_exact",
    "mean_edge_length",
    "rate_rows",
    "run",
]

#: Lame's sphere: inner radius, outer radius (m), Young's modulus, internal pressure (Pa).
LAME: dict[str, float] = {"inner": 0.8, "outer": 1.0, "E": 1.0e6, "pressure": 1.0e4}

#: Poisson's ratios of the Lame meshes: the study's, and the one that shows HEX8 locking.
LAME_NU: tuple[float, ...] = (0.3, 0.45)

#: Refinement levels ``k`` (``4 k`` cells along a face edge, ``k`` through the wall) per
#: element type: full run and ``--quick``.
LAME_LEVELS: dict[bool, dict[str, tuple[int, ...]]] = {
    False: {"hex8": (1, 2, 3, 4, 5, 6), "hex8 full": (1, 2, 3, 4, 5, 6), "tet4": (1, 2, 3, 4, 5)},
    True: {"hex8": (1, 2, 3), "hex8 full": (1, 2, 3), "tet4": (1, 2)},
}

#: Plate advance of the Hertz ball (m, R = 1): a/R is about 0.1.
HERTZ_DEPTH = 0.01

#: Hertz cell sizes at the poles (m): full run and ``--quick``.
HERTZ_SIZES: dict[bool, tuple[float, ...]] = {
    False: (0.04, 0.03, 0.02, 0.015, 0.01),
    True: (0.04, 0.03),
}

_HERTZ = {"radius": 1.0, "E": 1.0, "nu": 0.3}

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

LAME_COLUMNS = (
    Column("element", "element"),
    Column("nu", "nu", ".2f"),
    Column("level", "k", "d"),
    Column("h", "h (m)", ".4f"),
    Column("cells", "cells", ","),
    Column("dofs", "DOFs", ","),
    Column("max_ur", "max u_r err", ".3e"),
    Column("l2_u", "L2 u err", ".3e"),
    Column("l2_sigma", "L2 sigma err", ".3e"),
    Column("hoop_mid", "hoop mid err", ".3e"),
    Column("solve_s", "mesh+solve (s)", ".2f"),
    Column("error_s", "errors (s)", ".2f"),
)

HERTZ_COLUMNS = (
    Column("h", "fine size h (m)", ".4g"),
    Column("dofs", "DOFs", ","),
    Column("cells_per_a", "cells per a", ".1f"),
    Column("contacts", "contact nodes", "d"),
    Column("radius_err", "radius err", "+.3e"),
    Column("pressure_err", "peak pressure err", "+.3e"),
    Column("force_err", "force err", "+.3e"),
    Column("solve_s", "mesh+solve (s)", ".1f"),
)

RATE_COLUMNS = (
    Column("study", "study"),
    Column("series", "series"),
    Column("error", "error"),
    Column("meshes", "meshes", "d"),
    Column("finest", "error at finest h", ".3e"),
    Column("rate", "fitted rate", ".2f"),
    Column("last_rate", "rate of the last two", ".2f"),
    Column("expected", "expected"),
    Column("note", "note"),
)

CSV_KEYS = (
    "study",
    "element",
    "nu",
    "level",
    "h",
    "cells",
    "dofs",
    "max_ur",
    "l2_u",
    "l2_sigma",
    "hoop_mid",
    "cells_per_a",
    "contacts",
    "iterations",
    "radius_err",
    "pressure_err",
    "force_err",
    "solve_s",
    "error_s",
    "load",
)


# --- Lame's thick sphere ------------------------------------------------------------------


def _lame_fields(
    r: NDArray[np.float64], nu: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Lame's radial displacement, radial stress and hoop stress at radii ``r``."""
    a, b, e, p = LAME["inner"], LAME["outer"], LAME["E"], LAME["pressure"]
    c = p * a**3 / (b**3 - a**3)
    ur = c * ((1 - 2 * nu) * r / e + (1 + nu) * b**3 / (2 * e * r**2))
    return ur, -c * (b**3 / r**3 - 1), c * (b**3 / (2 * r**3) + 1)


def lame_exact(
    x: NDArray[np.float64], nu: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Lame's displacement and stress of the pressurised sphere :data:`LAME` at points ``x``.

    Parameters
    ----------
    x : ndarray, shape (..., 3)
        Points (m), centre at the origin.
    nu : float
        Poisson's ratio.

    Returns
    -------
    u : ndarray, shape (..., 3)
        Displacement (m): ``u_r = p a^3 / (b^3 - a^3) ((1 - 2 nu) r / E + (1 + nu) b^3 /
        (2 E r^2))``, radial.
    sigma : ndarray, shape (..., 3, 3)
        Stress (Pa): ``sigma_rr = -p a^3 (b^3 / r^3 - 1) / (b^3 - a^3)`` and the hoop
        stress ``p a^3 (b^3 / (2 r^3) + 1) / (b^3 - a^3)``.
    """
    r = np.linalg.norm(x, axis=-1)
    er = x / r[..., None]
    ur, srr, stt = _lame_fields(r, nu)
    sigma = stt[..., None, None] * np.eye(3) + (srr - stt)[..., None, None] * (
        er[..., :, None] * er[..., None, :]
    )
    return ur[..., None] * er, sigma


def _gauss01(n: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (x + 1.0), 0.5 * w


def _error_quadrature(kind: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Reference points and weights: 3^3 Gauss (brick), 3^3 collapsed-cube Gauss (tet)."""
    if kind == "hexahedron":
        x, w = np.polynomial.legendre.leggauss(3)
        g = np.stack(np.meshgrid(x, x, x, indexing="ij"), axis=-1).reshape(-1, 3)
        wg = (w[:, None, None] * w[None, :, None] * w[None, None, :]).ravel()
        return g, wg
    if kind == "tetra":
        s, ws = _gauss01(3)
        a, b, c = (v.ravel() for v in np.meshgrid(s, s, s, indexing="ij"))
        wa, wb, wc = (v.ravel() for v in np.meshgrid(ws, ws, ws, indexing="ij"))
        pts = np.stack([a, (1 - a) * b, (1 - a) * (1 - b) * c], axis=1)
        return pts, wa * wb * wc * (1 - a) ** 2 * (1 - b)
    raise ValueError(f"no error quadrature for {kind!r} cells")


def mean_edge_length(mesh: fem.Mesh) -> float:
    """Mean length of the cells' edges (each edge once): the mesh's ``h``."""
    bottom_top_sides = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4)]
    pairs = {
        "hexahedron": [*bottom_top_sides, (0, 4), (1, 5), (2, 6), (3, 7)],
        "tetra": [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)],
    }
    edges = np.concatenate([c[:, pairs[kind]].reshape(-1, 2) for kind, c in mesh.cells.items()])
    edges = np.unique(np.sort(edges, axis=1), axis=0)
    return float(np.linalg.norm(np.diff(mesh.points[edges], axis=1)[:, 0], axis=1).mean())


def _lame_errors(
    mesh: fem.Mesh, u: NDArray[np.float64], nu: float, chunk: int = 8192, bbar: bool = True
) -> dict[str, float]:
    """The four Lame errors of a displacement ``u`` (N, 3) on ``mesh`` (see the module).

    With ``bbar``, the stress of a B-bar element takes its volumetric strain as the
    element's mean, as its stiffness does.
    """
    a, b = LAME["inner"], LAME["outer"]
    r = np.linalg.norm(mesh.points, axis=1)
    ur_nodes = np.einsum("ij,ij->i", u, mesh.points) / r
    ur_exact = _lame_fields(r, nu)[0]
    ur_inner = float(_lame_fields(np.array(a), nu)[0])
    lam, mu = fem.LinearElastic(LAME["E"], nu).lame
    num_u = den_u = num_s = den_s = 0.0
    hoop_err = 0.0
    r_mid = 0.5 * (a + b)
    hoop_mid = float(_lame_fields(np.array(r_mid), nu)[2])
    for kind, conn in mesh.cells.items():
        el = ELEMENTS[kind]
        xi, wq = _error_quadrature(kind)
        centroid = el.points.mean(axis=0, keepdims=True)
        pts = np.concatenate([xi, centroid])
        n = el.shape(pts)
        # the gradients at the quadrature points and the centroid (last); a tetrahedron's
        # are constant, taken once at its centroid
        gpts = centroid if kind == "tetra" else pts
        dn = el.grad(gpts)
        for s in range(0, len(conn), chunk):
            c = conn[s : s + chunk]
            xc, uc = mesh.points[c], u[c]
            jac = jacobians(xc, el, gpts)  # (E, g, 3, 3)
            detj = det3(jac)
            grad = np.matmul(dn[None], inv3(jac, detj))  # (E, g, a, 3)
            du = np.matmul(uc.transpose(0, 2, 1)[:, None], grad)  # du_i / dx_j
            eps = 0.5 * (du + du.swapaxes(-1, -2))
            tr = np.trace(eps, axis1=-2, axis2=-1)
            if kind == "tetra":
                detj = np.broadcast_to(detj, (len(c), len(pts)))
            if bbar and el.mean_dilatation:
                wm = detj[:, :-1] * wq
                mean = (wm * tr[:, :-1]).sum(axis=1) / wm.sum(axis=1)
                eps = eps + ((mean[:, None] - tr) / 3.0)[..., None, None] * np.eye(3)
                tr = np.trace(eps, axis1=-2, axis2=-1)
            sig = lam * tr[..., None, None] * np.eye(3) + 2 * mu * eps
            xq = np.matmul(n[None], xc)  # (E, q, 3)
            uq = np.matmul(n[None], uc)
            rq = np.linalg.norm(xq, axis=-1)
            er = xq / rq[..., None]
            ur, srr, stt = _lame_fields(rq, nu)
            w = detj[:, :-1] * wq
            # |u_h - u|^2 and |sigma_h - sigma|^2 with sigma = stt I + (srr - stt) er er^T
            du2 = ((uq - ur[..., None] * er) ** 2).sum(-1)
            ses = (np.matmul(sig, er[..., None])[..., 0] * er).sum(-1)
            trs = np.trace(sig, axis1=-2, axis2=-1)
            ds2 = (sig**2).sum((-1, -2)) - 2 * (stt * trs + (srr - stt) * ses)
            ds2 += srr**2 + 2 * stt**2
            num_u += float((w * du2[:, :-1]).sum())
            den_u += float((w * ur[:, :-1] ** 2).sum())
            num_s += float((w * ds2[:, :-1]).sum())
            den_s += float((w * (srr**2 + 2 * stt**2)[:, :-1]).sum())
            # hoop stress at the centroids of the cells reaching the mid-wall sphere
            rn = np.linalg.norm(xc, axis=-1)
            tol = 1e-9 * b
            mid = (rn.min(axis=1) <= r_mid + tol) & (rn.max(axis=1) >= r_mid - tol)
            if mid.any():
                hoop = 0.5 * (trs[mid, -1] - ses[mid, -1])
                err = np.abs(hoop - stt[mid, -1]).max() / hoop_mid
                hoop_err = max(hoop_err, float(err))
    return {
        "max_ur": float(np.abs(ur_nodes - ur_exact).max() / ur_inner),
        "l2_u": math.sqrt(num_u / den_u),
        "l2_sigma": math.sqrt(num_s / den_s),
        "hoop_mid": hoop_err,
    }


def lame_case(element: str, level: int, nu: float = 0.3) -> dict:
    """Solve Lame's sphere on one mesh and measure its errors.

    Parameters
    ----------
    element : {"hex8", "hex8 full", "tet4"}
        Bricks of :func:`fem.shell_mesh` (B-bar, fem's default; or fully integrated),
        or each brick split into 24 tetrahedra.
    level : int
        ``k``: ``4 k`` cells along each cube-face edge, ``k`` through the wall.
    nu : float
        Poisson's ratio.

    Returns
    -------
    dict
        ``element, nu, level, h, cells, dofs``, the errors ``max_ur, l2_u, l2_sigma,
        hoop_mid`` and the times ``solve_s, error_s``.
    """
    if element not in ("hex8", "hex8 full", "tet4"):
        raise ValueError(f"element must be 'hex8', 'hex8 full' or 'tet4', got {element!r}")
    bbar = element != "hex8 full"
    a, b = LAME["inner"], LAME["outer"]
    t0 = time.perf_counter()
    mesh = fem.shell_mesh(a, b, divisions=4 * level, layers=level)
    if element == "tet4":
        mesh = fem.hex_to_tet(mesh)
    k = fem.assemble_stiffness(mesh, fem.LinearElastic(LAME["E"], nu), bbar=bbar)
    inner = {
        kind: np.linalg.norm(mesh.points[f].mean(axis=1), axis=1) < 0.5 * (a + b)
        for kind, f in mesh.boundary.faces.items()
    }
    f = fem.pressure_load(mesh, mesh.boundary.subset(inner), LAME["pressure"])
    u = fem.StaticSolver(k, points=mesh.points).solve(f).u.reshape(-1, 3)
    del k
    t1 = time.perf_counter()
    errors = _lame_errors(mesh, u, nu, bbar=bbar)
    t2 = time.perf_counter()
    return {
        "study": "lame",
        "element": element,
        "nu": nu,
        "level": level,
        "h": mean_edge_length(mesh),
        "cells": mesh.n_cells,
        "dofs": mesh.n_dofs,
        **errors,
        "solve_s": t1 - t0,
        "error_s": t2 - t1,
    }


# --- Hertz --------------------------------------------------------------------------------


def hertz_case(h: float) -> dict:
    """The Hertz ball's errors on the octant mesh of cell size ``h`` at the poles.

    Parameters
    ----------
    h : float
        Cell size at the poles (m).

    Returns
    -------
    dict
        ``h, dofs, cells_per_a, contacts, iterations``, the signed relative errors
        ``radius_err, pressure_err`` (against Hertz for the solver's force) and
        ``force_err`` (against Hertz's force for the plates' advance), and ``solve_s``.
    """
    t0 = time.perf_counter()
    chk = hertz_check(_HERTZ["radius"], _HERTZ["E"], _HERTZ["nu"], depth=HERTZ_DEPTH, fine_size=h)
    e_star = effective_modulus(_HERTZ["E"], _HERTZ["nu"])
    big_r = _HERTZ["radius"]
    force = 4.0 / 3.0 * e_star * math.sqrt(big_r) * HERTZ_DEPTH**1.5
    return {
        "study": "hertz",
        "element": "hex8",
        "nu": _HERTZ["nu"],
        "h": h,
        "dofs": chk.mesh.n_dofs,
        "cells": chk.mesh.n_cells,
        "cells_per_a": chk.hertz.contact_radius / h,
        "contacts": len(chk.patch.nodes),
        "iterations": chk.result.iterations,
        "radius_err": chk.radius_error,
        "pressure_err": chk.pressure_error,
        "force_err": chk.patch.force / force - 1.0,
        "solve_s": time.perf_counter() - t0,
    }


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
    """The fitted rates of every error of every series of ``rows`` (see :func:`run`)."""
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


# --- report ---------------------------------------------------------------------------------


def _plot(path: Path, rows: Sequence[dict], rates: Sequence[dict]) -> None:
    """Four log-log panels of error against h, the fitted slopes in the legends."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rate_of = {(r["study"], r["series"], r["error"]): r["rate"] for r in rates}

    def legend(study: str, series: str, label: str, name: str) -> str:
        rate = rate_of[(study, series, label)]
        return f"{name}: " + ("no rate" if math.isnan(rate) else f"slope {rate:.2f}")

    fig, axes = plt.subplots(2, 2, figsize=(12, 9))
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    markers = "osD^vP*X<>"
    lame = [r for r in rows if r["study"] == "lame"]
    labels = {key: label for key, label, _, _ in LAME_ERRORS}
    panels = (
        (axes[0, 0], ("max_ur", "l2_u"), (0.3,), "Lame, nu 0.3: displacement"),
        (axes[0, 1], ("l2_sigma", "hoop_mid"), (0.3,), "Lame, nu 0.3: stress"),
        (axes[1, 0], ("l2_u", "l2_sigma"), LAME_NU, "Lame: nu 0.3 (solid), 0.45 (dashed)"),
    )
    for ax, keys, nus, title in panels:
        for i, (element, key) in enumerate((e, k) for e in LAME_LEVELS[False] for k in keys):
            for nu in nus:
                series = sorted(
                    (r for r in lame if r["element"] == element and r["nu"] == nu),
                    key=lambda r: r["h"],
                )
                if not series:
                    continue
                sname = f"{element}, nu {nu:g}"
                name = f"{sname} {labels[key]}" if len(nus) > 1 else f"{element} {labels[key]}"
                ax.loglog(
                    [r["h"] for r in series],
                    [r[key] for r in series],
                    color=colors[i % len(colors)],
                    marker=markers[i % len(markers)],
                    linestyle="-" if nu == LAME_NU[0] else "--",
                    label=legend("lame", sname, labels[key], name),
                )
        ax.set_title(title)
        ax.set_ylabel("relative error")
    ax = axes[1, 1]
    hertz = sorted((r for r in rows if r["study"] == "hertz"), key=lambda r: r["h"])
    for i, (key, label, _, _) in enumerate(HERTZ_ERRORS):
        h = np.array([r["h"] for r in hertz])
        e = np.array([r[key] for r in hertz])
        ax.loglog(
            h,
            np.abs(e),
            color=colors[i],
            marker=markers[i],
            label=legend("hertz", "hex8 octant", label, f"|{label} err|"),
        )
        neg = e < 0
        ax.loglog(h[neg], -e[neg], linestyle="none", marker=markers[i], color="white", ms=3)
    ax.set_title("Hertz ball (octant): |relative error| (open marker: negative)")
    ax.set_ylabel("|relative error|")
    for ax in axes.ravel():
        ax.set_xlabel("h (m)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize="small")
    fig.suptitle("Mesh convergence (slopes: least squares of log |error| on log h)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _notes(rows: Sequence[dict], seconds: float) -> str:
    """The notes section: locking, what each error measures, and the run time."""
    lame = [r for r in rows if r["study"] == "lame"]
    lines = []

    def finest(element: str, nu: float) -> dict | None:
        series = [r for r in lame if r["element"] == element and r["nu"] == nu]
        return min(series, key=lambda r: r["h"]) if series else None

    for element in LAME_LEVELS[False]:
        lo, hi = finest(element, LAME_NU[0]), finest(element, LAME_NU[-1])
        if lo is not None and hi is not None and lo is not hi and lo["level"] == hi["level"]:
            lines.append(
                f"- {element} at nu {hi['nu']:g} against {lo['nu']:g} on the finest mesh "
                f"(k = {lo['level']}): L2 u error x{hi['l2_u'] / lo['l2_u']:.2f}, L2 sigma "
                f"x{hi['l2_sigma'] / lo['l2_sigma']:.2f}, max u_r "
                f"x{hi['max_ur'] / lo['max_ur']:.2f}."
            )
    lines += [
        "- Volumetric locking: fully integrated bricks ('hex8 full', 2x2x2 Gauss) constrain "
        "the volumetric strain at every Gauss point, and their error constant grows with "
        "lambda / mu (without bound as nu tends to 0.5). fem's bricks take the element's "
        "mean dilatation instead (B-bar, 'hex8', the default of fem.assemble_stiffness): "
        "their errors at nu 0.45 stay those at 0.3. The 24-tetrahedron split feels "
        "locking much less here; that is a property of this crossed split, and says "
        "nothing about unstructured tet4 meshes, which are not run.",
        "- The displacement errors include the geometric one (the faceted sphere, with the "
        "pressure on the faceted inner surface), also O(h^2). max u_r is the worst node, "
        "near the corners of the cubed sphere where the cells are most distorted; its rate "
        "rises towards 2 on the finer meshes.",
        "- hoop mid is pointwise, at the centroids of the cells that reach the mid-wall "
        "sphere. Brick centroids are superconvergent points (about 2 on each parity of k), "
        "but odd k put the centroids on the mid-wall sphere and even k half a layer to "
        "either side, two sequences with different constants: the slope of the last two "
        "meshes mixes them, the fit over all is the one to read. The tetrahedra's centroids "
        "are not such points.",
        "- Hertz: the radius and the peak pressure are compared with Hertz for the "
        "solver's own force, as in the hertz study. The total force is compared with "
        "Hertz's force for the plates' advance (the approach of the ball's centre): "
        "half-space theory leaves out that the ball is finite (in a half-space the point at "
        "the centre's depth still moves, by O(a/R) of the approach), so the force error "
        "tends to a model error of a few percent, not to zero, and it has no rate.",
        "- An error that changes sign over the meshes crosses zero somewhere between them: "
        "its magnitude on log axes says nothing about a rate, and none is fitted.",
        f"- Whole run: {seconds:.0f} s wall clock on a shared machine (see the load).",
    ]
    hertz = sorted((r for r in rows if r["study"] == "hertz"), key=lambda r: -r["h"])
    pressure = [r["pressure_err"] for r in hertz]
    if any(e > 0 for e in pressure) and any(e < 0 for e in pressure):
        lines.insert(
            -1,
            f"- The Hertz peak pressure error changes sign ({pressure[0]:+.2%} at the coarsest "
            f"mesh, {pressure[-1]:+.2%} at the finest): it settles near a small limit (the "
            "hertz study finds -0.2 % down to h = 0.006) of the model or of the fitted "
            "estimator, not a discretisation error that still decreases.",
        )
    return "\n".join(lines)


def run(quick: bool = False, out: str | Path | None = None) -> list[dict]:
    """Run the mesh convergence study and write ``convergence.{csv,md,png}``.

    Parameters
    ----------
    quick : bool
        Coarse meshes only (seconds).
    out : path, optional
        Results folder; ``benchmarks/results`` (``.../quick`` for quick runs) by default.

    Returns
    -------
    list of dict
        One row per mesh: ``study`` is ``"lame"`` or ``"hertz"``.
    """
    folder = results_dir(out, quick)
    info = machine_info()
    t_start = time.perf_counter()
    rows: list[dict] = []
    for nu in LAME_NU:
        for element, levels in LAME_LEVELS[quick].items():
            for level in levels:
                row = lame_case(element, level, nu) | {"load": load_average()}
                rows.append(row)
                print(
                    f"[convergence] lame {element} nu {nu:g} k {level}: {row['dofs']:>7,} DOFs, "
                    f"h {row['h']:.4f}, L2 u {row['l2_u']:.3e}, L2 sigma "
                    f"{row['l2_sigma']:.3e}, max u_r {row['max_ur']:.3e}, hoop "
                    f"{row['hoop_mid']:.3e} ({row['solve_s'] + row['error_s']:.1f} s)",
                    flush=True,
                )
                gc.collect()
    for h in HERTZ_SIZES[quick]:
        row = hertz_case(h) | {"load": load_average()}
        rows.append(row)
        print(
            f"[convergence] hertz h {h:g}: {row['dofs']:>7,} DOFs, radius "
            f"{row['radius_err']:+.3e}, peak {row['pressure_err']:+.3e}, force "
            f"{row['force_err']:+.3e} ({row['solve_s']:.1f} s)",
            flush=True,
        )
        gc.collect()
    seconds = time.perf_counter() - t_start
    rates = rate_rows(rows)
    write_csv(folder / "convergence.csv", rows, CSV_KEYS)
    lame = [r for r in rows if r["study"] == "lame"]
    hertz = [r for r in rows if r["study"] == "hertz"]
    expected = "\n".join(
        f"- {label}: {rate}; {why}" for _, label, rate, why in LAME_ERRORS + HERTZ_ERRORS
    )
    write_markdown(
        folder / "convergence.md",
        "Mesh convergence: Lame's thick sphere and Hertz's ball",
        info,
        [
            (
                "Lame's thick sphere (free body, internal pressure)",
                markdown_table(lame, LAME_COLUMNS),
            ),
            (
                "Hertz: a ball between two plates (octant, graded bricks)",
                markdown_table(hertz, HERTZ_COLUMNS),
            ),
            (
                "Fitted rates",
                markdown_table(rates, RATE_COLUMNS)
                + "\n\nRates are least-squares slopes of log |error| on log h over all the "
                "meshes of a series (and the slope between its two finest meshes). Expected "
                "for linear elements:\n\n" + expected,
            ),
            ("Notes", _notes(rows, seconds)),
        ],
    )
    _plot(folder / "convergence.png", rows, rates)
    return rows
