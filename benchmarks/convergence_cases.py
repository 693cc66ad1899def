"""The meshes of the convergence study: Lame's thick sphere and Hertz's ball, one case each.

Lame's exact solution, the errors of a computed displacement against it (integrated with
their own quadrature) and :func:`lame_case`, one mesh solved and measured; and
:func:`hertz_case`, the Hertz ball's errors on one octant mesh. What the errors mean is
told in :mod:`benchmarks.convergence`, the study.
"""

from __future__ import annotations

import math
import time

import numpy as np
from numpy.typing import NDArray

import fem
from contact.cases.hertz import effective_modulus, hertz_check
from fem.elements import ELEMENTS
from fem.mapping import det3, inv3, jacobians

__all__ = [
    "HERTZ_DEPTH",
    "HERTZ_SIZES",
    "LAME",
    "LAME_LEVELS",
    "LAME_NU",
    "hertz_case",
    "lame_case",
    "lame_exact",
    "mean_edge_length",
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
    """The four Lame errors of a displacement ``u`` (N, 3) on ``mesh``.

    What they measure: see :mod:`benchmarks.convergence`. With ``bbar``, the stress of a
    B-bar element takes its volumetric strain as the element's mean, as its stiffness does.
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
