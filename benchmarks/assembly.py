"""Stiffness assembly: ``fem.assemble_stiffness`` against scikit-fem on the same meshes.

Both assemble the isotropic linear elastic stiffness of a structured box of TET4 cells
(one-point rule in both) and of HEX8 cells (2x2x2 Gauss in both). The scikit-fem mesh is
built from the same points and cells: tetrahedra as they are, hexahedra with their nodes
reordered from VTK's numbering to scikit-fem's. scikit-fem's DOFs are mapped to ours
(``3 * node + component``) through ``basis.nodal_dofs`` and the two matrices compared.

Times exclude building the meshes; scikit-fem's includes making its ``Basis`` (the
mapping and basis functions at the quadrature points), which is part of its assembly.
scikit-fem is skipped at sizes where its time or memory, extrapolated linearly (plus 15%)
from the largest size it ran, would pass :data:`SKFEM_TIME_LIMIT` or
:data:`SKFEM_MEMORY_LIMIT`.
"""

from __future__ import annotations

import cProfile
import gc
import io
import pstats
import re
import time
from pathlib import Path
from typing import Any

import numpy as np
import psutil
import scipy.sparse as sp

import fem

from ._common import (
    GIB,
    MIB,
    Column,
    load_average,
    machine_info,
    markdown_table,
    measure,
    plot_loglog,
    results_dir,
    write_csv,
    write_markdown,
)

__all__ = [
    "HEX_VTK_TO_SKFEM",
    "SIZES",
    "fem_to_skfem_dofs",
    "profile_assembly",
    "run",
    "skfem_mesh",
    "skfem_stiffness",
]

#: Young's modulus (Pa) and Poisson's ratio of the benchmark material.
E, NU = 1.0e6, 0.3

#: Divisions of the unit cube per element type: full run and ``--quick``. Six tetrahedra
#: per brick: 20, 35, 55 give 48k, 257k and 998k tets; 20, 36, 58 give 8k, 47k, 195k hexes.
SIZES: dict[str, dict[bool, tuple[int, ...]]] = {
    "tetra": {False: (20, 35, 55), True: (2, 3, 5)},
    "hexahedron": {False: (20, 36, 58), True: (2, 3, 5)},
}

#: scikit-fem is not run where it is predicted to take longer than this (s) ...
SKFEM_TIME_LIMIT = 300.0
#: ... or to need more memory than this (bytes) above what the process holds.
SKFEM_MEMORY_LIMIT = 10 * GIB

#: ``skfem_hex[:, i] = vtk_hex[:, HEX_VTK_TO_SKFEM[i]]``: scikit-fem numbers the unit
#: cube's corners (0,0,0), (0,0,1), (0,1,0), (1,0,0), (0,1,1), (1,0,1), (1,1,0), (1,1,1).
HEX_VTK_TO_SKFEM = np.array([0, 4, 3, 1, 7, 5, 2, 6])

#: The two matrices must agree to this relative Frobenius norm.
MATCH_TOL = 1e-12

#: Goal: at least this many times faster than scikit-fem.
GOAL = 10.0

#: Seconds the repeats of one timing may take (full run, quick run).
BUDGET = {False: 20.0, True: 0.2}


def skfem_mesh(mesh: fem.Mesh, kind: str) -> Any:
    """The scikit-fem mesh of the same points and cells (``kind``: tetra or hexahedron)."""
    import skfem

    p = np.ascontiguousarray(mesh.points.T)
    conn = mesh.cells[kind]
    if kind == "tetra":
        return skfem.MeshTet(p, np.ascontiguousarray(conn.T))
    if kind == "hexahedron":
        return skfem.MeshHex(p, np.ascontiguousarray(conn[:, HEX_VTK_TO_SKFEM].T))
    raise ValueError(f"no scikit-fem mesh for {kind!r}")


def skfem_stiffness(m: Any, kind: str) -> tuple[sp.csr_matrix, Any, float, float]:
    """Assemble the elastic stiffness with scikit-fem.

    Returns
    -------
    K : scipy.sparse.csr_matrix
        In scikit-fem's DOF order.
    basis : skfem.Basis
    t_basis, t_asm : float
        Seconds spent making the basis and in ``asm``.
    """
    import skfem
    from skfem.models.elasticity import lame_parameters, linear_elasticity

    t0 = time.perf_counter()
    if kind == "tetra":
        basis = skfem.Basis(m, skfem.ElementVector(skfem.ElementTetP1()))
    else:  # intorder 3: the 2x2x2 Gauss rule, as fem's HEX8
        basis = skfem.Basis(m, skfem.ElementVector(skfem.ElementHex1()), intorder=3)
    t1 = time.perf_counter()
    k = skfem.asm(linear_elasticity(*lame_parameters(E, NU)), basis)
    t2 = time.perf_counter()
    return sp.csr_matrix(k), basis, t1 - t0, t2 - t1


def fem_to_skfem_dofs(basis: Any) -> np.ndarray | None:
    """``perm[3 * node + c]`` is scikit-fem's DOF of that node and component.

    ``None`` when the orders agree (then ``K_fem == K_skfem`` as they are); otherwise
    ``K_fem ≈ K_skfem[perm][:, perm]``.
    """
    nodal = np.asarray(basis.nodal_dofs)  # (3, n_nodes): DOF of component c at node j
    perm = nodal.T.ravel()
    return None if np.array_equal(perm, np.arange(perm.size)) else perm


def relative_difference(a: sp.spmatrix, b: sp.spmatrix) -> float:
    """``||a - b||_F / ||a||_F``."""
    return float(sp.linalg.norm(a - b) / sp.linalg.norm(a))


# --- profile ------------------------------------------------------------------------------

#: Profile categories: (label, functions whose own time counts to it). Names of both the
#: scalar-COO and the node-block assembly are listed, so the grouping survives refactors;
#: whatever matches none of them is "other" (see the listing of the top functions).
CATEGORIES: tuple[tuple[str, tuple[str, ...]], ...] = (
    (
        "element matrices: products, lam/mu terms, diagonal (element_stiffness/_blocks)",
        ("element_stiffness", "element_blocks"),
    ),
    (
        "mapping and einsum: Jacobians, inverses, gradients, outer products",
        ("gradients", "jacobians", "inv3", "det3", "c_einsum", "einsum", "bmm_einsum"),
    ),
    (
        "sparsity pattern: keys, np.unique and its sorts",
        ("unique", "_unique1d", "_unique_hash", "sort", "argsort", "concatenate"),
    ),
    (
        "index building (element_dofs, repeat, tile, astype, reshape copies)",
        ("element_dofs", "repeat", "tile", "astype", "reshape"),
    ),
    (
        "assemble_stiffness's own time: np.bincount scatter-adds, gathers, slicing "
        "(numpy's C-level functions such as bincount are invisible to cProfile)",
        ("assemble_stiffness", "bincount"),
    ),
    ("numpy reductions (index range checks, sums)", ("reduce",)),
    ("COO/BSR -> CSR conversion", ("coo_tocsr", "bsr_tocsr", "csr_count_blocks")),
    (
        "CSR canonicalisation: sort_indices, sum_duplicates, prune copies",
        ("csr_sort_indices", "csr_sum_duplicates", "csr_has_canonical_format", "copy"),
    ),
)


def _function_key(name: str) -> str:
    """A profiled function's bare name: ``<method 'repeat' of ...>`` -> ``repeat``."""
    m = re.search(r"method '([^']+)'", name)
    if m:
        return m.group(1)
    return name.strip("<>").split(" ")[-1].split(".")[-1]


def profile_assembly(mesh: fem.Mesh, material: fem.LinearElastic) -> tuple[list[dict], str]:
    """Profile one ``fem.assemble_stiffness`` call with cProfile.

    Returns
    -------
    rows : list of dict
        ``category``, ``seconds``, ``share`` (of the profiled total): own time of the
        functions grouped as in :data:`CATEGORIES`, the rest as "other".
    top : str
        The pstats listing of the functions with the most own time.
    """
    prof = cProfile.Profile()
    gc.collect()
    prof.enable()
    fem.assemble_stiffness(mesh, material, bbar=False)  # scikit-fem's formulation
    prof.disable()
    stats = pstats.Stats(prof)
    own: dict[str, float] = {}
    for (_, _, name), (_, _, tottime, _, _) in stats.stats.items():  # type: ignore[attr-defined]
        key = _function_key(name)
        own[key] = own.get(key, 0.0) + tottime
    total = sum(own.values())
    rows = []
    for label, names in CATEGORIES:
        sec = sum(own.get(n, 0.0) for n in names)
        rows.append({"category": label, "seconds": sec, "share": sec / total})
    rest = total - sum(r["seconds"] for r in rows)
    rows.append({"category": "other", "seconds": rest, "share": rest / total})
    rows.append({"category": "total (profiled)", "seconds": total, "share": 1.0})
    buf = io.StringIO()
    pstats.Stats(prof, stream=buf).sort_stats("tottime").print_stats(12)
    text = buf.getvalue()
    for prefix in (Path(np.__file__).parents[1], Path(fem.__file__).parents[1]):
        text = text.replace(f"{prefix}/", "")
    lines = text.splitlines()
    top = "\n".join(ln for ln in lines if ln.strip() and "function calls" not in ln)
    return rows, top


# --- the benchmark ----------------------------------------------------------------------


def _bench_size(kind: str, n: int, quick: bool, skfem_model: dict | None) -> dict:
    """Time both assemblies on an ``n``-cube of ``kind`` cells; one result row."""
    mesh = fem.box_mesh((1.0, 1.0, 1.0), (n, n, n), element=kind)
    material = fem.LinearElastic(E, NU)
    cells = len(mesh.cells[kind])
    row: dict[str, Any] = {
        "element": kind,
        "divisions": n,
        "cells": cells,
        "nodes": mesh.n_points,
        "dofs": mesh.n_dofs,
    }
    # the same matrix as scikit-fem's (full integration; B-bar adds one small product)
    ours = measure(lambda: fem.assemble_stiffness(mesh, material, bbar=False), 5, BUDGET[quick])
    k = ours.result
    row.update(
        nnz=k.nnz,
        fem_s=ours.best,
        fem_runs=ours.n,
        fem_peak_mib=ours.peak_increment / MIB,
        fem_mcells_per_s=cells / ours.best / 1e6,
    )
    del ours

    # scikit-fem, unless extrapolation from the last size says it would take too long
    if skfem_model is not None:
        t_pred = skfem_model["s_per_cell"] * cells
        m_pred = skfem_model["bytes_per_cell"] * cells
        avail = psutil.virtual_memory().available
        if t_pred > SKFEM_TIME_LIMIT or m_pred > min(SKFEM_MEMORY_LIMIT, 0.7 * avail):
            row["note"] = (
                f"scikit-fem skipped: predicted {t_pred:.0f} s and {m_pred / GIB:.1f} GiB "
                f"(limits {SKFEM_TIME_LIMIT:.0f} s, {SKFEM_MEMORY_LIMIT / GIB:.0f} GiB)"
            )
            return row
    m = skfem_mesh(mesh, kind)
    splits: list[tuple[float, float]] = []

    def call() -> tuple[sp.csr_matrix, Any]:
        ks, basis, tb, ta = skfem_stiffness(m, kind)
        splits.append((tb, ta))
        return ks, basis

    ref = measure(call, 3, BUDGET[quick])
    best = int(np.argmin(ref.times))
    ks, basis = ref.result
    perm = fem_to_skfem_dofs(basis)
    del basis
    if perm is not None:
        ks = ks[perm][:, perm]
    row.update(
        skfem_s=ref.best,
        skfem_basis_s=splits[best][0],
        skfem_asm_s=splits[best][1],
        skfem_runs=ref.n,
        skfem_peak_mib=ref.peak_increment / MIB,
        ratio=ref.best / row["fem_s"],
        rel_diff=relative_difference(k, ks),
        dof_order="same" if perm is None else "permuted",
    )
    if not row["rel_diff"] <= MATCH_TOL:
        row["note"] = f"K DIFFERS from scikit-fem's: relative difference {row['rel_diff']:.1e}"
    row["skfem_model"] = {
        "s_per_cell": 1.15 * max(ref.times[0], ref.best) / cells,
        "bytes_per_cell": 1.15 * ref.peak_increment / cells,
    }
    return row


COLUMNS = (
    Column("element", "element"),
    Column("cells", "cells", ","),
    Column("dofs", "DOFs", ","),
    Column("nnz", "nnz(K)", ","),
    Column("fem_s", "fem (s)", ".3f"),
    Column("fem_runs", "runs", "d"),
    Column("fem_mcells_per_s", "fem Mcells/s", ".2f"),
    Column("fem_peak_mib", "fem peak (MiB)", ",.0f"),
    Column("skfem_s", "skfem (s)", ".3f"),
    Column("skfem_basis_s", "of which Basis (s)", ".3f"),
    Column("skfem_runs", "runs", "d"),
    Column("skfem_peak_mib", "skfem peak (MiB)", ",.0f"),
    Column("ratio", "skfem / fem", ".1f"),
    Column("rel_diff", "rel. diff of K", ".1e"),
)

CSV_KEYS = (
    "element", "divisions", "cells", "nodes", "dofs", "nnz", "fem_s", "fem_runs",
    "fem_mcells_per_s", "fem_peak_mib", "skfem_s", "skfem_basis_s", "skfem_asm_s",
    "skfem_runs", "skfem_peak_mib", "ratio", "rel_diff", "dof_order", "note",
)  # fmt: skip


def run(quick: bool = False, out: str | Path | None = None) -> list[dict]:
    """Run the assembly benchmark and write ``assembly.{csv,md,png}``.

    Parameters
    ----------
    quick : bool
        Tiny sizes, a few seconds in all.
    out : path, optional
        Results folder; ``benchmarks/results`` (``.../quick`` for quick runs) by default.

    Returns
    -------
    list of dict
        One row per element type and size.
    """
    folder = results_dir(out, quick)
    info = machine_info()
    rows: list[dict] = []
    for kind, sizes in SIZES.items():
        model = None
        for n in sizes[quick]:
            t0 = time.perf_counter()
            row = _bench_size(kind, n, quick, model)
            model = row.pop("skfem_model", model)
            rows.append(row)
            print(
                f"[assembly] {kind:10s} n={n:3d} cells={row['cells']:>9,} "
                f"fem {row['fem_s']:.3f} s  skfem {row.get('skfem_s', float('nan')):.3f} s  "
                f"ratio {row.get('ratio', float('nan')):.1f}  ({time.perf_counter() - t0:.0f} s)",
                flush=True,
            )
            gc.collect()

    # profile fem at the largest size of each type
    profiles = []
    for kind, sizes in SIZES.items():
        n = sizes[quick][-1]
        mesh = fem.box_mesh((1.0, 1.0, 1.0), (n, n, n), element=kind)
        fem.assemble_stiffness(mesh, fem.LinearElastic(E, NU))  # warm
        prows, top = profile_assembly(mesh, fem.LinearElastic(E, NU))
        profiles.append((kind, n, len(mesh.cells[kind]), prows, top))
        del mesh
        gc.collect()

    info["load average at end"] = load_average()
    write_csv(folder / "assembly.csv", rows, CSV_KEYS)
    _write_report(folder, info, rows, profiles, quick)
    series = {}
    for kind in SIZES:
        rk = [r for r in rows if r["element"] == kind]
        short = "tet4" if kind == "tetra" else "hex8"
        series[f"fem {short}"] = ([r["dofs"] for r in rk], [r["fem_s"] for r in rk])
        series[f"scikit-fem {short}"] = (
            [r["dofs"] for r in rk],
            [r.get("skfem_s") for r in rk],
        )
    plot_loglog(folder / "assembly.png", series, title="Stiffness assembly time")
    return rows


def _write_report(folder: Path, info: dict, rows: list[dict], profiles: list, quick: bool) -> None:
    sections = []
    verdicts = []
    for kind in SIZES:
        rk = [r for r in rows if r["element"] == kind and r.get("ratio") is not None]
        if not rk:
            verdicts.append(f"- {kind}: scikit-fem ran at no size.")
            continue
        last = rk[-1]
        ratios = ", ".join(format(r["ratio"], ".1f") for r in rk)
        ok = "meets" if last["ratio"] >= GOAL else "MISSES"
        verdicts.append(
            f"- {kind}: at {last['cells']:,} cells (largest size scikit-fem ran) fem is "
            f"{last['ratio']:.1f}x faster: {ok} the goal of {GOAL:.0f}x "
            f"(ratios at all sizes: {ratios})."
        )
    notes = [r["note"] for r in rows if r.get("note")]
    body = markdown_table(rows, COLUMNS)
    body += (
        "\n\nTimes are the best of `runs` calls (wall clock); peak is the resident memory "
        "above what the process held before the first call (kernel high-water mark). "
        "scikit-fem's time includes building its `Basis`. `rel. diff of K` is "
        "`||K_fem - P K_skfem P^T||_F / ||K_fem||_F` with scikit-fem's DOFs mapped to fem's."
    )
    if notes:
        body += "\n\n" + "\n".join(
            f"- {r['element']} {r['cells']:,} cells: {r['note']}" for r in rows if r.get("note")
        )
    sections.append(
        ("Results" + (" (quick: tiny sizes, not representative)" if quick else ""), body)
    )
    sections.append(
        (f"Against the goal (>= {GOAL:.0f}x faster than scikit-fem)", "\n".join(verdicts))
    )
    prof_cols = (
        Column("category", "where the time goes"),
        Column("seconds", "seconds", ".3f"),
        Column("share", "share", ".0%"),
    )
    for kind, _n, cells, prows, top in profiles:
        sections.append(
            (
                f"Profile of fem.assemble_stiffness, {kind}, {cells:,} cells (cProfile, own time)",
                markdown_table(prows, prof_cols) + "\n\n```text\n" + top + "\n```",
            )
        )
    write_markdown(folder / "assembly.md", "Stiffness assembly: fem vs scikit-fem", info, sections)
