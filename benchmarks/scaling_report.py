"""The scaling study's report: its goals, columns, slope table, markdown and plot."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._common import GIB, MIB, Column, markdown_table, write_markdown
from .scaling_cubes import (
    CAP_SLACK,
    ELEMENTS,
    FIT_FROM,
    MEMORY_MARGIN,
    MIN_MEMORY_EXPONENT,
    NOISE_MIB,
    PHASES,
    _fit_power,
)
from .scaling_example import STAGES

__all__ = [
    "CSV_KEYS",
    "EXAMPLE_COLUMNS",
    "EXAMPLE_GOAL",
    "MEMORY_COLUMNS",
    "MEMORY_GOAL",
    "MILLION",
    "TIME_COLUMNS",
]


#: Goals: a million DOFs within this peak memory; the README example within this time.
MEMORY_GOAL = 24 * GIB
MILLION = 1_000_000
EXAMPLE_GOAL = 60.0


# --- report -----------------------------------------------------------------------------

CSV_KEYS = (
    "kind", "element", "divisions", "cells", "nodes", "dofs", "free_dofs", "nnz_k", "nnz_k11",
    "factor_nnz", "pardiso_mem_mib", "backend", "runs",
    *(f"{p}_s" for p in PHASES), "whole_s",
    *(f"{p}_inc_mib" for p in PHASES), "whole_inc_mib",
    *(f"{p}_peak_mib" for p in PHASES), "whole_peak_mib", "start_mib", "memory_method",
    "predicted_inc_mib", "predicted_s", "available_mib", "balance", "max_u", "max_von_mises",
    "child_wall_s", "label", "command", "wall_s", "child_peak_mib", "exit_status", "frames",
    "all_converged", "all_realistic", "pictures", *(f"{s}_s" for s in STAGES), "imports_s",
    "setup_s",
    "contact_s", "writing_s", "pictures_s", "rest_s",
    "phase", "measure", "quantity", "slope", "fit_points", "fit_over", "fit_min_dofs",
    "fit_max_dofs", "note",
)  # fmt: skip

TIME_COLUMNS = (
    Column("element", "element"),
    Column("dofs", "DOFs", ","),
    Column("cells", "cells", ","),
    Column("nnz_k11", "nnz(K11)", ","),
    Column("factor_nnz", "nnz(factor)", ","),
    *(Column(f"{p}_s", f"{p} (s)", ".3g") for p in PHASES),
    Column("whole_s", "whole (s)", ".3g"),
    Column("runs", "runs", "d"),
    Column("balance", "balance", ".0e"),
    Column("note", "note"),
)

MEMORY_COLUMNS = (
    Column("element", "element"),
    Column("dofs", "DOFs", ","),
    *(Column(f"{p}_inc_mib", f"{p} (MiB)", ",.0f") for p in PHASES),
    Column("whole_inc_mib", "whole increment (MiB)", ",.0f"),
    Column("whole_peak_mib", "process peak (MiB)", ",.0f"),
    Column("child_peak_mib", "child's max RSS (MiB)", ",.0f"),
    Column("pardiso_mem_mib", "PARDISO's own report (MiB)", ",.0f"),
    Column("predicted_inc_mib", "predicted increment (MiB)", ",.0f"),
    Column("available_mib", "available (MiB)", ",.0f"),
)

EXAMPLE_COLUMNS = (
    Column("label", "run"),
    Column("frames", "frames", "d"),
    Column("wall_s", "wall (s)", ".1f"),
    Column("child_peak_mib", "peak RSS (MiB)", ",.0f"),
    Column("exit_status", "exit", "d"),
    Column("startup_s", "interpreter + imports + exit (s)", ".2f"),
    Column("load_mesh_s", "load + mesh (s)", ".2f"),
    Column("posing_s", "posing (s)", ".2f"),
    Column("assemble_factor_s", "assemble + factor (s)", ".2f"),
    Column("setup_s", "frame set-up (s)", ".2f"),
    Column("contact_s", "contact (s)", ".2f"),
    Column("writing_s", "writing (s)", ".2f"),
    Column("pictures_s", "of which pictures (s)", ".2f"),
    Column("other_s", "other (s)", ".2f"),
    Column("rest_s", "rest (s)", ".2f"),
)


def _slope_table(fits: list[dict]) -> str:
    """Slopes as a table: a row per element and phase, time and memory side by side."""
    rows = []
    for label in ELEMENTS.values():
        for phase in (*PHASES, "whole"):
            got = {f["measure"]: f for f in fits if f["element"] == label and f["phase"] == phase}
            t = got.get("time", {})
            rows.append(
                {
                    "element": label,
                    "phase": phase,
                    "time": t.get("slope"),
                    "memory": got.get("memory increment", {}).get("slope"),
                    "peak": got.get("process peak", {}).get("slope"),
                    "points": t.get("fit_points"),
                    "range": (
                        f"{t['fit_min_dofs']:,}..{t['fit_max_dofs']:,} ({t['fit_over']})"
                        if t.get("fit_min_dofs") is not None
                        else None
                    ),
                }
            )
    cols = (
        Column("element", "element"),
        Column("phase", "phase"),
        Column("time", "time slope", ".2f"),
        Column("memory", "memory-increment slope", ".2f"),
        Column("peak", "process-peak slope", ".2f"),
        Column("points", "sizes", "d"),
        Column("range", "DOFs fitted"),
    )
    return markdown_table(rows, cols)


def _memory_goal(cubes: list[dict], fits: list[dict], cap: int) -> list[dict]:
    """Per element: the process peak at ~1M DOFs, measured or (capped) extrapolated."""
    out = []
    for label in ELEMENTS.values():
        series = [r for r in cubes if r["element"] == label]
        done = [r for r in series if r.get("whole_peak_mib") is not None]
        big = [r for r in done if r["dofs"] >= MILLION * (1 - CAP_SLACK)]
        goal = f"{MILLION:,} DOFs ({label}) fits in {MEMORY_GOAL / GIB:.0f} GiB"
        if big:
            r = big[-1]
            peak = max(r["whole_peak_mib"], r.get("child_peak_mib") or 0.0) * MIB
            ok = "met" if peak <= MEMORY_GOAL else "missed"
            measured = (
                f"{peak / GIB:.2f} GiB peak resident memory of the process at {r['dofs']:,} "
                f"DOFs (factor {r['factor_s']:.0f} s, whole {r['whole_s']:.0f} s)"
            )
        else:
            skipped = [r for r in series if r.get("whole_peak_mib") is None]
            # the increment's power law over the fitted sizes plus the RSS the process held
            fitted = [r for r in done if r["dofs"] >= FIT_FROM]
            if len(fitted) >= 2:
                slope, icpt = _fit_power(
                    [r["dofs"] for r in fitted], [r["whole_inc_mib"] * MIB for r in fitted]
                )
                guess = np.exp(icpt) * MILLION**slope + fitted[-1]["start_mib"] * MIB
                extra = f"; extrapolated from the fit (slope {slope:.2f}): {guess / GIB:.1f} GiB"
            else:
                extra = ""
            largest = done[-1]["dofs"] if done else 0
            if skipped and skipped[-1]["dofs"] >= MILLION * (1 - CAP_SLACK):
                why = skipped[-1]["note"]
                failed = why.startswith("failed")
                ok = "missed (the run failed)" if failed else "missed (predicted not to fit)"
            else:
                why = f"not run: sizes capped at {cap:,} DOFs"
                ok = "not measured"
            measured = f"{why}; largest run {largest:,} DOFs{extra}"
        out.append({"goal": goal, "measured": measured, "status": ok})
    return out


def _example_goal(examples: list[dict]) -> dict:
    goal = f"README example end to end <= {EXAMPLE_GOAL:.0f} s"
    readme = [r for r in examples if r["label"].startswith("README command (pictures")]
    if not readme:
        return {
            "goal": goal,
            "measured": "not measured (--quick runs one frame only)",
            "status": "not measured",
        }
    r = readme[0]
    if r.get("note"):
        return {"goal": goal, "measured": r["note"], "status": "missed (failed)"}
    ok = "met" if r["wall_s"] <= EXAMPLE_GOAL else "missed"
    return {
        "goal": goal,
        "measured": f"{r['wall_s']:.1f} s wall, {r['child_peak_mib']:.0f} MiB peak RSS "
        f"({r['frames']} frames, pictures and GIF)",
        "status": ok,
    }


def _write_report(
    folder: Path,
    info: dict[str, str],
    cubes: list[dict],
    fits: list[dict],
    examples: list[dict],
    cap: int,
    quick: bool,
) -> None:
    goals = [*_memory_goal(cubes, fits, cap), _example_goal(examples)]
    gcols = (Column("goal", "goal"), Column("measured", "measured"), Column("status", "status"))
    sections = [
        ("Goals", markdown_table(goals, gcols)),
        (
            "Clamped cube: time per phase" + (" (quick: small sizes)" if quick else ""),
            markdown_table(cubes, TIME_COLUMNS)
            + "\n\nPhases: `mesh` (box_mesh, boundary faces, clamped DOFs, pressure load), "
            "`assembly` (assemble_stiffness), `factor` (StaticSolver: partition of K and "
            "the factorisation of K11 with the default backend), `solve` (one "
            "StaticSolver.solve), `stress` (cell_stress, von_mises, nodal_average); `whole` "
            "their sum. Times: wall clock, the best of `runs` runs of the whole pipeline "
            "(one where a run is long). `balance`: |sum of reactions + load| / |load|. "
            "nnz(factor): PARDISO's count of the factor's nonzeros.",
        ),
        (
            "Clamped cube: peak memory per phase",
            markdown_table(cubes, MEMORY_COLUMNS)
            + "\n\nEvery size runs in a fresh process (a clean memory baseline: memory "
            "freed by a previous size and kept by the allocator would hide increments). A "
            "phase's memory is its peak increment: the highest resident memory of the "
            "process during the phase less that at its start (kernel high-water mark, from "
            "the first run at each size). `whole increment`: the highest over all phases "
            "less the resident memory before the mesh phase; `process peak`: the highest "
            "resident memory of the process during the phases (interpreter and libraries "
            "included); `child's max RSS`: the same from the child's rusage (imports and a "
            "warm-up solve of a 2-cube included). `PARDISO's own report`: its peak memory "
            "estimate (iparm 15 to 17). "
            f"`predicted increment`: what the last sizes' power law (exponent at least "
            f"{MIN_MEMORY_EXPONENT:.2f}) predicted before the size ran; a size whose "
            f"prediction times {MEMORY_MARGIN} passes the memory available is skipped.",
        ),
        (
            "Fitted slopes (log-log least squares)",
            _slope_table(fits)
            + f"\n\nFitted over the sizes of at least {FIT_FROM:,} DOFs (all sizes where "
            f"fewer than two are). Memory increments below {NOISE_MIB:g} MiB (a few pages, "
            "allocator noise) are left out of the fits and the plot; `sizes` counts the "
            "sizes of the time fit. `fem.assemble_stiffness` works through the cells in "
            "chunks (`fem.assembly.CHUNK` cells), so its transient memory grows more slowly "
            "than the DOFs once a mesh holds several chunks (the tet meshes here).",
        ),
        (
            "The README example end to end",
            markdown_table(examples, EXAMPLE_COLUMNS)
            + "\n\nWall: the subprocess from start to exit; peak RSS: the child's own "
            "(`wait4` rusage). README runs: `frame set-up` (posing, placing the ball, "
            "assembling and factoring new bodies), `contact` and `writing` (VTU files, "
            "stresses, convergence plot, pictures, GIF, summary) add up the per-frame "
            "timings of `summary.json`; `rest` is the wall time outside them (interpreter, "
            "imports, reading the scene, the ball's mesh, loading the hand). The traced run "
            "(`benchmarks/_grasp_trace.py`) times the stages directly; its `rest` is "
            "interpreter + imports, load + mesh and other.",
        ),
    ]
    notes = [f"- {r['element']} {r['dofs']:,} DOFs: {r['note']}" for r in cubes if r.get("note")]
    if notes:
        sections.insert(1, ("Skipped sizes", "\n".join(notes)))
    write_markdown(
        folder / "scaling.md",
        "Scaling: time and peak memory against DOFs, and the grasp example end to end",
        info,
        sections,
    )


def _plot(path: Path, cubes: list[dict], fits: list[dict]) -> None:
    """Two log-log panels: time and peak memory against DOFs, slopes in the legends."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    slopes = {(f["element"], f["quantity"]): f["slope"] for f in fits}
    fig, axes = plt.subplots(1, 2, figsize=(14, 9))
    colours = dict(zip((*PHASES, "whole"), plt.get_cmap("tab10").colors))
    styles = {"tet4": ("-", "o"), "hex8": ("--", "s")}
    panels = (
        (axes[0], "time (s)", [(f"{p}_s", p) for p in (*PHASES, "whole")], 1.0),
        (
            axes[1],
            "peak memory (GiB)",
            [(f"{p}_inc_mib", p) for p in PHASES] + [("whole_peak_mib", "whole (process peak)")],
            MIB / GIB,
        ),
    )
    for ax, ylabel, keys, scale in panels:
        for label, (ls, marker) in styles.items():
            rows = [r for r in cubes if r["element"] == label and r.get("whole_s") is not None]
            for key, name in keys:
                floor = NOISE_MIB if key.endswith("_mib") else 0.0
                pts = [(r["dofs"], r[key] * scale) for r in rows if (r.get(key) or 0) > floor]
                if not pts:
                    continue
                s = slopes.get((label, key), float("nan"))
                colour = colours[name.split(" ")[0]]
                ax.loglog(
                    *zip(*pts),
                    ls=ls,
                    marker=marker,
                    color=colour,
                    label=f"{label} {name} (slope {s:.2f})" if s == s else f"{label} {name}",
                )
        ax.set_xlabel("DOFs (3 x nodes)")
        ax.set_ylabel(ylabel)
        ax.grid(True, which="both", alpha=0.3)
    axes[1].axhline(MEMORY_GOAL / GIB, color="red", ls=":", lw=1.5, label="24 GiB")
    axes[0].set_title("Time per phase, clamped cube")
    axes[1].set_title("Peak memory: phase increments and process peak")
    for ax in axes:
        ax.legend(fontsize="small", ncol=2, loc="upper center", bbox_to_anchor=(0.5, -0.1))
    fig.suptitle(f"Slopes fitted over sizes >= {FIT_FROM:,} DOFs (all sizes if fewer than two)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
