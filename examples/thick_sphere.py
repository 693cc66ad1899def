"""A pressurised thick sphere, solved as a free body and written to a VTU file.

Until the grasp command exists this is the project's runnable example:

    python examples/thick_sphere.py --out results/

It meshes a hollow sphere with 8-node bricks, applies the internal pressure on its inner
surface, removes the six rigid-body modes exactly, compares the radial displacement with
Lame's solution and writes ``thick_sphere.vtu`` (point data ``displacement`` and
``von_mises``, cell data ``von_mises``, ``stress`` and ``region``) for ParaView.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path

import numpy as np

import fem


def lame_radial(r, a, b, p, e, nu):
    """Lame's radial displacement of a thick sphere under internal pressure ``p``."""
    return p * a**3 / (b**3 - a**3) * ((1 - 2 * nu) * r / e + (1 + nu) * b**3 / (2 * e * r**2))


def main(argv: list[str] | None = None) -> int:
    """Run the example; return the exit code (0 on success, 2 on bad input)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("results"), help="output folder")
    parser.add_argument("--inner", type=float, default=0.032, help="inner radius (m)")
    parser.add_argument("--outer", type=float, default=0.035, help="outer radius (m)")
    parser.add_argument("--pressure", type=float, default=2.0e4, help="internal pressure (Pa)")
    parser.add_argument("--E", type=float, default=1.0e6, help="Young's modulus (Pa)")
    parser.add_argument("--nu", type=float, default=0.45, help="Poisson's ratio")
    parser.add_argument("--size", type=float, default=0.0015, help="element edge length (m)")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    log = logging.getLogger("thick_sphere")

    t0 = time.perf_counter()
    try:
        mat = fem.LinearElastic(args.E, args.nu)
        mesh = fem.shell_mesh(args.inner, args.outer, args.size)
    except fem.FemError as exc:
        log.error("error: %s", exc)
        return 2
    k = fem.assemble_stiffness(mesh, mat)
    inner = {
        kind: np.linalg.norm(mesh.points[f].mean(axis=1), axis=1) < 0.5 * (args.inner + args.outer)
        for kind, f in mesh.boundary.faces.items()
    }
    f = fem.pressure_load(mesh, mesh.boundary.subset(inner), args.pressure)
    sol = fem.StaticSolver(k, points=mesh.points).solve(f)
    u = sol.u.reshape(-1, 3)
    stress = fem.cell_stress(mesh, mat, sol.u)
    vm = {kind: fem.von_mises(s) for kind, s in stress.items()}

    r = np.linalg.norm(mesh.points, axis=1)
    ur = np.einsum("ij,ij->i", u, mesh.points) / r
    exact = lame_radial(r, args.inner, args.outer, args.pressure, args.E, args.nu)
    err = float(np.abs(ur - exact).max() / np.abs(exact).max())

    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "thick_sphere.vtu"
    fem.write_mesh(
        path,
        mesh,
        point_data={"displacement": u, "von_mises": fem.nodal_average(mesh, vm)},
        cell_data={
            "von_mises": vm,
            "stress": {kind: s.reshape(len(s), 9) for kind, s in stress.items()},
        },
    )
    summary = {
        "nodes": mesh.n_points,
        "cells": mesh.n_cells,
        "dofs": mesh.n_dofs,
        "linear_solver": fem.available_backends()[0],
        "max_radial_displacement_m": float(ur.max()),
        "lame_max_radial_displacement_m": float(exact.max()),
        "max_relative_error": err,
        "max_von_mises_Pa": float(max(v.max() for v in vm.values())),
        "seconds": round(time.perf_counter() - t0, 3),
        "vtu": str(path),
    }
    (args.out / "thick_sphere.json").write_text(json.dumps(summary, indent=2) + "\n")
    log.info(
        "thick sphere: %d nodes, radial displacement %.4g m (Lame %.4g m), error %.2f%%, "
        "written %s in %.1f s",
        mesh.n_points,
        ur.max(),
        exact.max(),
        100 * err,
        path,
        summary["seconds"],
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
