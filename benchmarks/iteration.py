"""The contact iteration: convergence histories and iteration counts of both algorithms.

Two scenes, both with two deformable bodies:

``"hand cup"``
    The hand at rest pressed by a free ball that a rising cup of four rigid planes holds
    (:func:`benchmarks.scenes.hand_cup`): flesh ``E = 100 kPa``, the ball ``ratio``
    times stiffer, the cup raised by ``press`` (5 mm unless said otherwise); node to
    surface pairs both ways between ball and hand.
``"sphere-block"``
    Hertz's sphere (R = 1 m, quarter model) pressed 0.01 m into an elastic block
    (:func:`contact.cases.hertz_bodies.hertz_scene`), the sphere ``ratio`` times stiffer than
    the block, graded hex meshes of ``fine_size`` cells at the contact.

Algorithms (:func:`contact.solver.iteration.solve_frame`): ``"contact-space"`` (contact-set
updates, each solved exactly with both bodies' compliance) and the Dirichlet-Neumann loop of
Gourret, Magnenat-Thalmann and Thalmann (1989) with each relaxation of its Neumann side
(none, a fixed factor 0.5, Aitken's). The seed loop's Dirichlet body is the ball (the
sphere): in the hand cup it must be, since the cup's planes touch only the ball. On the
Hertz scene the seed loop runs with the sphere's nodes against the block only (one way), as
with pairs both ways it diverges on its first iteration (rows met node to node prescribe the
sphere twice: one variant shows it); one more variant makes the softer body the Dirichlet
one.

Studies:

1. *histories and the stiffness ratio*: every variant at ``E_ball / E_other`` 0.01 to 100
   on both scenes; the largest change of a nodal displacement per iteration (CSV
   ``iteration_history.csv``, plot ``iteration.png``) and the iterations, stop reason,
   back-solves, time, force and penetration of each frame (``iteration.csv``);
2. *mesh refinement*: contact space on three meshes of each scene at ratios 0.01, 1 and
   100 (goal: iterations within +-30 % over the three);
3. *press depth*: contact space and the seed loop (Aitken) on the hand cup at several
   depths.

Goals (from the issue): contact iterations over three refinements within +-30 %, and at
most 10 contact-set updates over E ratios 0.01 to 100. Run with ``python -m benchmarks
iteration`` (or ``python -m benchmarks.iteration``), ``--quick`` for a smoke test.
"""

from __future__ import annotations

import argparse
import gc
import hashlib
import math
import subprocess
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import contact
from contact.cases.hertz_bodies import hertz_scene
from contact.solver import ContactSettings, solve_frame
from contact.solver.results import FrameResult

from ._common import (
    Column,
    load_average,
    machine_info,
    markdown_table,
    results_dir,
    write_csv,
    write_markdown,
)
from .scenes import REFINEMENTS, CupLevel, clearance, hand_body, hand_cup

__all__ = [
    "CUP_LEVELS",
    "GOAL_REFINEMENT",
    "GOAL_UPDATES",
    "HERTZ_SIZES",
    "PRESSES",
    "RATIOS",
    "SCENES",
    "Case",
    "Variant",
    "run",
    "solve_case",
    "variants",
]

#: The two scenes.
SCENES = ("hand cup", "sphere-block")
#: Goal: largest deviation of the contact iterations over three meshes from their mean.
GOAL_REFINEMENT = 0.30
#: Goal: most contact-set updates of a frame over E ratios 0.01 to 100.
GOAL_UPDATES = 10
#: Relaxation factor of the seed loop's fixed relaxation (and Aitken's first one).
FACTOR = 0.5
#: Default press of the hand cup (m).
PRESS = 0.005
#: Radii of the Hertz scene (the second is unused for the block).
RADII = (1.0, 2.0)

#: Stiffness ratios of study 1: full run and ``--quick``.
RATIOS: dict[bool, tuple[float, ...]] = {
    False: (0.01, 0.1, 1.0, 10.0, 100.0),
    True: (0.1, 10.0),
}
#: Iteration limit of every frame: full run and ``--quick``.
MAX_ITERATIONS = {False: 40, True: 20}
#: Ratios of the refinement study: full run and ``--quick``.
REFINE_RATIOS: dict[bool, tuple[float, ...]] = {False: (0.01, 1.0, 100.0), True: (1.0,)}
#: Hand cup meshes: full run and ``--quick`` (the first is that of studies 1 and 3).
CUP_LEVELS: dict[bool, tuple[CupLevel, ...]] = {
    False: REFINEMENTS,
    True: (
        CupLevel("coarse hand, ball 6/3", "coarse", 6, 3),
        CupLevel("coarse hand, ball 8/4", "coarse", 8, 4),
    ),
}
#: Hertz fine sizes (m): full run and ``--quick`` (the first is that of study 1).
HERTZ_SIZES: dict[bool, tuple[float, ...]] = {
    False: (0.03, 0.02, 0.015),
    True: (0.08, 0.045, 0.03),
}
#: Press depths (m) and the ratios of study 3: full run and ``--quick``.
PRESSES: dict[bool, tuple[float, ...]] = {
    False: (0.00375, 0.005, 0.00625, 0.0075, 0.01),
    True: (0.00375, 0.0075),
}
PRESS_RATIOS: dict[bool, tuple[float, ...]] = {False: (0.1, 10.0), True: (0.1,)}


@dataclass(frozen=True)
class Variant:
    """One way of solving a frame.

    Attributes
    ----------
    label : str
        For tables and plots.
    algorithm : {"contact-space", "seed"}
    relaxation : {"none", "fixed", "aitken"}
    both_ways : bool
        Node-to-surface pairs both ways between the deformable bodies, or the first
        body's nodes only (Hertz scene).
    softer_dirichlet : bool
        Seed loop: the softer body is the Dirichlet one (default: the first body).
    """

    label: str
    algorithm: str = "contact-space"
    relaxation: str = "none"
    both_ways: bool = True
    softer_dirichlet: bool = False

    @property
    def seed(self) -> bool:
        """True for the seed loop."""
        return self.algorithm == "seed"


CONTACT_SPACE = Variant("contact space")
SEED_NONE = Variant("seed, none", "seed", "none", both_ways=False)
SEED_FIXED = Variant("seed, fixed 0.5", "seed", "fixed", both_ways=False)
SEED_AITKEN = Variant("seed, Aitken", "seed", "aitken", both_ways=False)
SEEDS = (SEED_NONE, SEED_FIXED, SEED_AITKEN)


def variants(scene: str, quick: bool = False) -> tuple[Variant, ...]:
    """The variants of study 1 on a scene, contact space first.

    Parameters
    ----------
    scene : {"hand cup", "sphere-block"}
    quick : bool
        Leave out the Hertz scene's extra variants.

    Returns
    -------
    tuple of Variant
    """
    if scene == "hand cup":
        # the hand cup's seed loop keeps the scene's pairs (both ways)
        return (CONTACT_SPACE, *(Variant(v.label, v.algorithm, v.relaxation) for v in SEEDS))
    extra = (
        ()
        if quick
        else (
            Variant("contact space, one way", both_ways=False),
            Variant("seed, Aitken, softer body Dirichlet", "seed", "aitken", False, True),
            Variant("seed, none, pairs both ways", "seed", "none", both_ways=True),
        )
    )
    return (CONTACT_SPACE, *SEEDS, *extra)


@dataclass(frozen=True)
class Case:
    """One frame to solve.

    Attributes
    ----------
    study : {"ratio", "refinement", "press"}
    scene : {"hand cup", "sphere-block"}
    ratio : float
        The ball's (sphere's) modulus over the other body's.
    mesh : str
        The mesh's name (hand cup level, or the Hertz fine size).
    level : int
        Refinement level, 0 the coarsest.
    press : float
        Hand cup: the cup's rise (m); Hertz: the interference (m).
    """

    study: str
    scene: str
    ratio: float
    mesh: str
    level: int
    press: float


def _scene(case: Case, variant: Variant, quick: bool) -> tuple[list, list, list, str]:
    """Bodies, pairs, planes and the seed loop's Dirichlet body of a case (new bodies)."""
    if case.scene == "hand cup":
        lv = CUP_LEVELS[quick][case.level]
        hand = hand_body(lv.resolution)
        bodies, pairs, planes = hand_cup(
            case.ratio,
            case.press,
            divisions=lv.divisions,
            layers=lv.layers,
            hand=hand,
        )
        return bodies, pairs, planes, bodies[0].name
    sc = hertz_scene(
        "sphere-block",
        case.ratio,
        fine_size=HERTZ_SIZES[quick][case.level],
        radii=RADII,
        depth=case.press,
        both_directions=variant.both_ways,
    )
    bodies = list(sc.bodies)
    dirichlet = bodies[1].name if variant.softer_dirichlet and case.ratio > 1 else bodies[0].name
    return bodies, list(sc.pairs), [], dirichlet


def _largest_displacement(res: FrameResult) -> float:
    return max(float(np.abs(u).max(initial=0.0)) for u in res.displacement.values())


def solve_case(
    case: Case, variant: Variant, quick: bool = False
) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """Solve one frame on new bodies and summarise it.

    Parameters
    ----------
    case : Case
    variant : Variant
    quick : bool
        Which meshes the levels name, and the iteration limit.

    Returns
    -------
    row : dict
        The frame: iterations, stop reason, back-solves per body, times, force,
        penetration.
    history : list of dict
        One row per iteration: largest change, deepest penetration, contacts, force.
    """
    t0 = time.perf_counter()
    bodies, pairs, planes, dirichlet = _scene(case, variant, quick)
    setup = time.perf_counter() - t0
    before = {b.name: b.solver.n_back_solves for b in bodies}
    partial0 = {b.name: getattr(b.solver, "n_partial_solves", 0) for b in bodies}
    settings = ContactSettings(
        algorithm=variant.algorithm,
        relaxation=variant.relaxation,
        relaxation_factor=FACTOR,
        max_iterations=MAX_ITERATIONS[quick],
    )
    t = time.perf_counter()
    res = solve_frame(bodies, pairs, planes, settings, dirichlet=dirichlet)
    seconds = time.perf_counter() - t
    back = {b.name: b.solver.n_back_solves - before[b.name] for b in bodies}
    partial = {b.name: getattr(b.solver, "n_partial_solves", 0) - partial0[b.name] for b in bodies}
    other = bodies[1].name
    last = res.history[-1] if res.history else None
    row: dict[str, Any] = {
        "study": case.study,
        "scene": case.scene,
        "ratio": case.ratio,
        "mesh": case.mesh,
        "level": case.level,
        "press": case.press,
        "dofs": sum(b.mesh.n_dofs for b in bodies),
        "variant": variant.label,
        "algorithm": variant.algorithm,
        "relaxation": variant.relaxation,
        "pairs": "both ways" if variant.both_ways else "one way",
        "dirichlet": dirichlet if variant.seed else "",
        "iterations": res.iterations,
        "converged": res.converged,
        "stop_reason": res.stop_reason,
        "cell": _cell(res),
        "contacts": len(res.contacts["node"]),
        "back_solves": sum(back.values()),
        "back_solves_by_body": ", ".join(f"{k} {v}" for k, v in back.items()),
        "partial_solves": sum(partial.values()),
        "setup_s": setup,
        "frame_s": seconds,
        "factor_s": res.timings.get("factorisation", 0.0),
        "contact_s": seconds - res.timings.get("factorisation", 0.0),
        "rows_s": res.timings.get("contact solve", 0.0),
        "geometry_s": res.timings.get("geometry", 0.0),
        "bodies_s": res.timings.get("bodies", 0.0),
        "normal_force": last.normal_force if last is not None else 0.0,
        "force_z": float(res.total_contact_force(other)[2]),
        "max_support_force": last.max_support_force if last is not None else 0.0,
        "penetration_ratio": res.penetration_ratio,
        "max_penetration": res.max_penetration,
        "max_displacement": _largest_displacement(res),
        "final_change": last.max_change if last is not None else math.nan,
        "clearance": clearance(bodies[1]) if case.scene == "hand cup" else math.nan,
        "load": load_average(),
    }
    history = [
        {
            "study": case.study,
            "scene": case.scene,
            "ratio": case.ratio,
            "mesh": case.mesh,
            "press": case.press,
            "variant": variant.label,
            "iteration": r.iteration,
            "max_change": r.max_change,
            "max_penetration": r.max_penetration,
            "n_contacts": r.n_contacts,
            "added": r.added,
            "released": r.released,
            "normal_force": r.normal_force,
            "relaxation": r.relaxation,
        }
        for r in res.history
    ]
    return row, history


def _cell(res: FrameResult) -> str:
    """``"4"`` when converged, else ``"40 (iteration limit)"``."""
    if res.converged:
        return str(res.iterations)
    return f"{res.iterations} ({res.stop_reason.split(':')[0]})"


# --- the studies ------------------------------------------------------------------------


def _cases(quick: bool) -> list[tuple[Case, tuple[Variant, ...]]]:
    """Every frame of the three studies, in the order they run."""
    out: list[tuple[Case, tuple[Variant, ...]]] = []
    cup0, size0 = CUP_LEVELS[quick][0].name, f"h = {HERTZ_SIZES[quick][0]:g}"
    for scene in SCENES:
        mesh, press = (cup0, PRESS) if scene == "hand cup" else (size0, 0.01 * RADII[0])
        for ratio in RATIOS[quick]:
            out.append((Case("ratio", scene, ratio, mesh, 0, press), variants(scene, quick)))
    for scene in SCENES:
        levels = CUP_LEVELS[quick] if scene == "hand cup" else HERTZ_SIZES[quick]
        press = PRESS if scene == "hand cup" else 0.01 * RADII[0]
        for ratio in REFINE_RATIOS[quick]:
            for i, lv in enumerate(levels):
                mesh = lv.name if isinstance(lv, CupLevel) else f"h = {lv:g}"
                out.append((Case("refinement", scene, ratio, mesh, i, press), (CONTACT_SPACE,)))
    for ratio in PRESS_RATIOS[quick]:
        for press in PRESSES[quick]:
            out.append(
                (Case("press", "hand cup", ratio, cup0, 0, press), (CONTACT_SPACE, SEED_AITKEN))
            )
    return out


def run(quick: bool = False, out: str | Path | None = None) -> list[dict]:
    """Run the contact-iteration study and write ``iteration*.{csv,md,png}``.

    Parameters
    ----------
    quick : bool
        Small meshes and the fewest cases: seconds.
    out : path, optional
        Results folder; ``benchmarks/results`` (``.../quick`` for quick runs) by default.

    Returns
    -------
    list of dict
        One row per frame solved (study, scene, ratio, mesh, press and variant).
    """
    folder = results_dir(out, quick)
    info = machine_info()
    info["code"] = _code_version()
    t_start = time.perf_counter()
    rows: list[dict] = []
    history: list[dict] = []
    for case, vs in _cases(quick):
        reference = None
        for v in vs:
            row, hist = solve_case(case, v, quick)
            if v.label == CONTACT_SPACE.label:
                reference = row
            if reference is not None and reference["force_z"]:
                if not row["stop_reason"].startswith("diverged"):
                    # the resultant on the hand (block), not the sum of the rows' forces:
                    # where both meshes touch, rows both ways share one physical force
                    row["force_vs_cs_pct"] = 100 * (row["force_z"] / reference["force_z"] - 1.0)
                scale = reference["max_displacement"]
                for h in hist:
                    h["max_change_rel"] = h["max_change"] / scale if scale > 0 else math.nan
            rows.append(row)
            history += hist
            print(
                f"[iteration] {case.study}: {case.scene} E ratio {case.ratio:g}, {case.mesh}, "
                f"press {case.press:g}: {v.label}: {row['cell']} in {row['contact_s']:.2f} s",
                flush=True,
            )
            gc.collect()
    info["load average at end"] = load_average()
    info["run time"] = f"{time.perf_counter() - t_start:.0f} s"
    write_csv(folder / "iteration.csv", rows, CSV_KEYS)
    write_csv(folder / "iteration_history.csv", history, HISTORY_KEYS)
    goals = _goals(rows, quick)
    _write_report(folder, info, rows, goals, quick)
    _plot_histories(folder / "iteration.png", history, quick)
    _plot_counts(folder / "iteration_counts.png", rows, quick)
    return rows


def _code_version() -> str:
    """The git commit, whether contact/, fem/ or meshes/ differ from it, and digests."""
    root = Path(contact.__file__).resolve().parent
    digest = hashlib.sha1(b"".join(f.read_bytes() for f in sorted(root.rglob("*.py"))))
    hand = sorted((root.parent / "meshes" / "hand").glob("flesh_*.vtu"))
    meshes = hashlib.sha1(b"".join(f.read_bytes() for f in hand)).hexdigest()[:12]
    try:
        head = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"],
            cwd=root,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--", "contact", "fem", "meshes"],
            cwd=root.parent,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        head, dirty = "unknown", ""
    state = " with uncommitted changes in contact/, fem/ or meshes/" if dirty else ""
    return (
        f"commit {head}{state}; contact sources sha1 {digest.hexdigest()[:12]}; hand flesh "
        f"meshes sha1 {meshes}"
    )


CSV_KEYS = [
    "study",
    "scene",
    "ratio",
    "mesh",
    "level",
    "press",
    "dofs",
    "variant",
    "algorithm",
    "relaxation",
    "pairs",
    "dirichlet",
    "iterations",
    "converged",
    "stop_reason",
    "contacts",
    "back_solves",
    "back_solves_by_body",
    "partial_solves",
    "setup_s",
    "frame_s",
    "factor_s",
    "contact_s",
    "rows_s",
    "geometry_s",
    "bodies_s",
    "normal_force",
    "force_vs_cs_pct",
    "force_z",
    "max_support_force",
    "penetration_ratio",
    "max_penetration",
    "max_displacement",
    "final_change",
    "clearance",
    "load",
]
HISTORY_KEYS = [
    "study",
    "scene",
    "ratio",
    "mesh",
    "press",
    "variant",
    "iteration",
    "max_change",
    "max_change_rel",
    "max_penetration",
    "n_contacts",
    "added",
    "released",
    "normal_force",
    "relaxation",
]


# --- goals --------------------------------------------------------------------------------


def _goals(rows: list[dict], quick: bool) -> list[dict]:
    """The goal rows: measured value and met / missed."""
    goals: list[dict] = []
    for scene in SCENES:
        for ratio in REFINE_RATIOS[quick]:
            sel = [
                r
                for r in rows
                if r["study"] == "refinement" and r["scene"] == scene and r["ratio"] == ratio
            ]
            if not sel:
                continue
            n = np.array([r["iterations"] for r in sel], dtype=float)
            mean = float(n.mean())
            dev = float(np.abs(n / mean - 1.0).max())
            spread = float(n.max() / n.min() - 1.0)
            ok = all(r["converged"] for r in sel)
            goals.append(
                {
                    "goal": f"contact iterations over {len(sel)} refinements: within +-30 %",
                    "case": f"{scene}, E ratio {ratio:g}, contact space",
                    "measured": (
                        f"{', '.join(r['cell'] for r in sel)} (mean {mean:.2f}); largest "
                        f"deviation from the mean {100 * dev:.0f} %; max/min - 1 = "
                        f"{100 * spread:.0f} %"
                    ),
                    "verdict": _flag(ok and dev <= GOAL_REFINEMENT)
                    + (
                        ""
                        if spread <= GOAL_REFINEMENT or not ok or dev > GOAL_REFINEMENT
                        else " (max/min - 1 over 30 %)"
                    ),
                }
            )
    for scene in SCENES:
        for v in variants(scene, quick):
            for study, what in (("ratio", "study-1 mesh"), ("refinement", "every mesh")):
                sel = [
                    r
                    for r in rows
                    if r["study"] == study and r["scene"] == scene and r["variant"] == v.label
                ]
                if not sel:
                    continue
                ok = all(r["converged"] and r["iterations"] <= GOAL_UPDATES for r in sel)
                failed = [r for r in sel if not r["converged"]]
                most = max(
                    (r for r in sel if r["converged"]), key=lambda r: r["iterations"], default=None
                )
                goals.append(
                    {
                        "goal": f"contact-set updates, E ratio 0.01 to 100: <= {GOAL_UPDATES}",
                        "case": f"{scene}, {v.label}, {what}",
                        "measured": (
                            "; ".join(
                                f"E ratio {r['ratio']:g}"
                                + (f", {r['mesh']}" if study == "refinement" else "")
                                + f": {r['cell']}"
                                for r in sel
                            )
                            + (
                                f" (most when converged: {most['iterations']})"
                                if most is not None
                                else ""
                            )
                            + (f"; {len(failed)} of {len(sel)} not converged" if failed else "")
                        ),
                        "verdict": _flag(ok),
                    }
                )
    return goals


def _flag(ok: bool) -> str:
    return "met" if ok else "MISSED"


# --- the report ---------------------------------------------------------------------------

GOAL_COLUMNS = (
    Column("goal", "goal"),
    Column("case", "case"),
    Column("measured", "measured"),
    Column("verdict", "verdict"),
)
DETAIL_COLUMNS = (
    Column("scene", "scene"),
    Column("ratio", "E ratio", "g"),
    Column("mesh", "mesh"),
    Column("press", "press (m)", "g"),
    Column("dofs", "DOFs", ","),
    Column("variant", "algorithm"),
    Column("cell", "iterations"),
    Column("contacts", "contacts"),
    Column("back_solves_by_body", "back-solves"),
    Column("partial_solves", "partial solves"),
    Column("contact_s", "contact solve (s)", ".2f"),
    Column("force_z", "force on hand / block, z (N)", ".4g"),
    Column("force_vs_cs_pct", "vs contact space (%)", "+.2f"),
    Column("penetration_ratio", "penetration / cell", ".1e"),
)


def _pivot(rows: list[dict], scene: str, key: str, fmt: str) -> str:
    """A table of one scene's ratio study: a row per ratio, a column per variant."""
    sel = [r for r in rows if r["study"] == "ratio" and r["scene"] == scene]
    labels = list(dict.fromkeys(r["variant"] for r in sel))
    table = []
    for ratio in dict.fromkeys(r["ratio"] for r in sel):
        line: dict[str, Any] = {"ratio": ratio}
        for r in sel:
            if r["ratio"] == ratio:
                line[r["variant"]] = r.get(key)
        table.append(line)
    cols = [Column("ratio", "E ratio", "g"), *(Column(lb, lb, fmt) for lb in labels)]
    return markdown_table(table, cols)


def _notes(rows: list[dict]) -> str:
    """Frames that failed, seed answers away from contact space, penetrations left."""
    lines = []
    failed = [r for r in rows if not r["converged"]]
    if failed:
        lines.append("Frames that did not converge (stop reason):")
        lines += [
            f"- {r['study']}: {r['scene']}, E ratio {r['ratio']:g}, {r['mesh']}, press "
            f"{r['press']:g}: {r['variant']}: {r['iterations']} iterations, {r['stop_reason']}"
            for r in failed
        ]
    off = [
        r
        for r in rows
        if r["converged"]
        and r["algorithm"] == "seed"
        and abs(r.get("force_vs_cs_pct") or 0.0) > 2.0
    ]
    if off:
        lines.append("")
        lines.append(
            "Seed frames that converged to a contact force (the resultant on the hand or "
            "block) more than 2 % away from contact space's on the same frame (another "
            "contact set: the rows are linearised where each algorithm's iterates met the "
            "master surface):"
        )
        lines += [
            f"- {r['study']}: {r['scene']}, E ratio {r['ratio']:g}, {r['mesh']}, press "
            f"{r['press']:g}: {r['variant']}: {r['force_vs_cs_pct']:+.1f} % ("
            f"{r['iterations']} iterations, penetration / cell {r['penetration_ratio']:.1e})"
            for r in off
        ]
    deep = [r for r in rows if r["converged"] and r["penetration_ratio"] > 1e-3]
    if deep:
        lines.append("")
        lines.append(
            "Converged frames that leave a node inside its master by more than the gap "
            "tolerance (1e-3 of its local cell size; penetration / cell):"
        )
        lines += [
            f"- {r['study']}: {r['scene']}, E ratio {r['ratio']:g}, {r['mesh']}, press "
            f"{r['press']:g}: {r['variant']}: {r['penetration_ratio']:.1e}"
            for r in deep
        ]
    heavy = [r for r in rows if r["algorithm"] == "contact-space" and r["back_solves"] > 100]
    if heavy:
        lines.append("")
        lines.append(
            "Contact-space frames with more than 100 full back-solves (rows whose compliance "
            "did not come from partial solves on a body's marked contact zone):"
        )
        lines += [
            f"- {r['study']}: {r['scene']}, E ratio {r['ratio']:g}, {r['mesh']}, press "
            f"{r['press']:g}: {r['back_solves_by_body']} (partial {r['partial_solves']}), "
            f"contact solve {r['contact_s']:.1f} s"
            for r in heavy
        ]
    return "\n".join(lines) if lines else "Every frame converged."


def _write_report(
    folder: Path, info: dict, rows: list[dict], goals: list[dict], quick: bool
) -> None:
    q = " (quick)" if quick else ""
    by_study = {s: [r for r in rows if r["study"] == s] for s in ("ratio", "refinement", "press")}
    sections = [
        (
            "Goals" + q,
            markdown_table(goals, GOAL_COLUMNS)
            + "\n\nRefinement: met when each mesh's iterations lie within +-30 % of the "
            "mean of the three (max/min - 1 is given too, a stricter reading); a frame "
            "that does not converge misses. Updates: every frame converged in at most "
            f"{GOAL_UPDATES} iterations (for contact space, contact-set solves; for the "
            "seed loop, loops of its steps 2 to 5). The goal is the solver's (contact "
            "space, the default); the seed loop's rows are given for comparison.",
        ),
        (
            "Iterations against the stiffness ratio: hand cup" + q,
            _pivot(rows, "hand cup", "cell", "")
            + f"\n\nMesh {CUP_LEVELS[quick][0].name}, press {PRESS * 1e3:g} mm; limit "
            f"{MAX_ITERATIONS[quick]} iterations. The seed loop's Dirichlet body is the ball.",
        ),
        (
            "Iterations against the stiffness ratio: sphere on block" + q,
            _pivot(rows, "sphere-block", "cell", "")
            + f"\n\nFine size {HERTZ_SIZES[quick][0]:g} m (R = 1 m, interference 0.01 m). "
            "Seed rows: the sphere's nodes against the block (one way), the sphere the "
            "Dirichlet body, unless the label says otherwise.",
        ),
        (
            "Contact solve time (s) against the stiffness ratio: hand cup" + q,
            _pivot(rows, "hand cup", "contact_s", ".2f"),
        ),
        (
            "Contact solve time (s) against the stiffness ratio: sphere on block" + q,
            _pivot(rows, "sphere-block", "contact_s", ".2f"),
        ),
        (
            "Every frame of the stiffness ratio study" + q,
            markdown_table(by_study["ratio"], DETAIL_COLUMNS)
            + "\n\nBack-solves: columns of a body's compliance computed with its "
            "factorisation (n_back_solves), partial solves: those computed on the marked "
            "DOFs only (n_partial_solves, where the solver has them). The seed loop's "
            "Neumann side adds one full solve of the other body per iteration, not "
            "counted there. vs contact space: the resultant contact force on the hand "
            "(block) along z against contact space's on the same frame (blank where the "
            "seed loop diverged). Contact solve: the "
            "frame's wall time less the bodies' "
            "factorisation (done in the frame when the bodies factor lazily; "
            "`factor_s` in the CSV).",
        ),
        (
            "Iterations against mesh refinement (contact space)" + q,
            markdown_table(by_study["refinement"], DETAIL_COLUMNS)
            + "\n\nHand cup meshes: the shipped hand (coarse or fine) and the ball's cells "
            "(divisions of its core cube / layers to the sphere); Hertz: the cell size at "
            "the contact of both graded meshes.",
        ),
        (
            "Iterations against the press depth (hand cup)" + q,
            markdown_table(by_study["press"], DETAIL_COLUMNS)
            + "\n\nThe press is the cup's rise. The ball's top touches the lowest skin "
            "node above its centre's footprint, which lies off its pole: the skin's nearest "
            "node is "
            + ", ".join(
                sorted({f"{1e3 * r['clearance']:.2f} mm ({r['mesh']})" for r in by_study["press"]})
            )
            + " from the ball at press 0, so the indentation is the press less that.",
        ),
        ("Notes" + q, _notes(rows)),
    ]
    write_markdown(folder / "iteration.md", "The contact iteration", info, sections)


# --- plots --------------------------------------------------------------------------------

STYLES = {
    "contact space": ("k", "o"),
    "contact space, one way": ("0.5", "o"),
    "seed, none": ("tab:red", "s"),
    "seed, fixed 0.5": ("tab:orange", "^"),
    "seed, Aitken": ("tab:blue", "D"),
    "seed, Aitken, softer body Dirichlet": ("tab:green", "v"),
    "seed, none, pairs both ways": ("tab:purple", "x"),
}


#: Top of the history plots' y-axes (diverging seed iterates go far beyond).
CLIP = 1e4


def _plot_histories(path: Path, history: list[dict], quick: bool) -> None:
    """Semilog-y panels of the largest change per iteration: a panel per scene and ratio."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ratios = RATIOS[quick]
    fig, axes = plt.subplots(
        len(SCENES), len(ratios), figsize=(3.4 * len(ratios), 3.2 * len(SCENES)), squeeze=False
    )
    for i, scene in enumerate(SCENES):
        for j, ratio in enumerate(ratios):
            ax = axes[i, j]
            sel = [h for h in history if h["study"] == "ratio" and h["scene"] == scene]
            sel = [h for h in sel if h["ratio"] == ratio]
            for label in dict.fromkeys(h["variant"] for h in sel):
                pts = [
                    (h["iteration"], h.get("max_change_rel", math.nan))
                    for h in sel
                    if h["variant"] == label
                ]
                x = [p[0] for p in pts]
                y = [min(p[1], CLIP) for p in pts]  # diverging iterates drawn at the clip
                color, marker = STYLES.get(label, (None, "."))
                ax.semilogy(x, y, marker=marker, color=color, ms=3, lw=1, label=label)
            ax.axhline(1e-4, color="0.6", ls=":", lw=0.8)
            low, high = ax.get_ylim()
            if high > CLIP:
                ax.set_ylim(low, 3 * CLIP)
            ax.set_title(f"{scene}, E ratio {ratio:g}", fontsize="small")
            ax.set_xlabel("iteration")
            if j == 0:
                ax.set_ylabel("change / |u|max of contact space")
            ax.grid(True, which="both", alpha=0.3)
    handles: dict[str, Any] = {}
    for ax in axes.ravel():
        for h, lb in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lb, h)
    fig.legend(handles.values(), handles.keys(), loc="lower center", ncol=4, fontsize="small")
    fig.suptitle(
        "Largest change of a nodal displacement per iteration (dotted: the seed loop's "
        f"tolerance 1e-4; values above {CLIP:g} drawn at {CLIP:g}: diverging)",
        fontsize="medium",
    )
    fig.tight_layout(rect=(0, 0.08, 1, 0.96))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _plot_counts(path: Path, rows: list[dict], quick: bool) -> None:
    """Iterations against the ratio, the mesh and the press (open markers: not converged)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2, a3) = plt.subplots(1, 3, figsize=(15, 6.8))
    lines = {"hand cup": "-", "sphere-block": "--"}

    def draw(ax: Any, sel: Sequence[dict], xkey: str, label: str, style: tuple) -> None:
        color, marker, ls = style
        x = [r[xkey] for r in sel]
        y = [r["iterations"] for r in sel]
        ax.plot(x, y, ls=ls, marker=marker, color=color, label=label, ms=5)
        bad = [(r[xkey], r["iterations"]) for r in sel if not r["converged"]]
        if bad:
            ax.plot(*zip(*bad), ls="", marker="o", ms=11, mfc="none", color="r")

    for scene in SCENES:
        for v in variants(scene, quick):
            sel = [
                r
                for r in rows
                if r["study"] == "ratio" and r["scene"] == scene and r["variant"] == v.label
            ]
            color, marker = STYLES.get(v.label, (None, "."))
            draw(a1, sel, "ratio", f"{scene}: {v.label}", (color, marker, lines[scene]))
        for ratio in REFINE_RATIOS[quick]:
            sel = [
                r
                for r in rows
                if r["study"] == "refinement" and r["scene"] == scene and r["ratio"] == ratio
            ]
            draw(a2, sel, "dofs", f"{scene}, E ratio {ratio:g}", (None, "o", lines[scene]))
    for ratio in PRESS_RATIOS[quick]:
        for v in (CONTACT_SPACE, SEED_AITKEN):
            sel = [
                r
                for r in rows
                if r["study"] == "press" and r["ratio"] == ratio and r["variant"] == v.label
            ]
            color, marker = STYLES[v.label]
            ls = "-" if ratio < 1 else "--"
            sel = [{**r, "press_mm": 1e3 * r["press"]} for r in sel]
            draw(a3, sel, "press_mm", f"E ratio {ratio:g}: {v.label}", (color, marker, ls))
    a1.set_xscale("log")
    a1.set_xlabel("E ball / E other body")
    a2.set_xscale("log")
    a2.set_xlabel("DOFs (three meshes per scene)")
    a3.set_xlabel("press of the cup (mm)")
    for ax, title in zip(
        (a1, a2, a3),
        (
            "against the stiffness ratio",
            "against mesh refinement (contact space)",
            "hand cup: against the press",
        ),
    ):
        ax.axhline(GOAL_UPDATES, color="0.5", ls=":", lw=1)
        ax.set_ylabel("iterations")
        ax.set_title(title, fontsize="medium")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize="x-small", loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2)
    fig.suptitle("Iterations of a frame (ringed: not converged; dotted: the goal of 10)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> None:
    """``python -m benchmarks.iteration [--quick] [--out DIR]``."""
    ap = argparse.ArgumentParser(prog="python -m benchmarks.iteration", description=__doc__)
    ap.add_argument("--quick", action="store_true", help="small meshes, fewest cases")
    ap.add_argument("--out", help="results folder")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    run(quick=args.quick, out=args.out)
    print(f"[iteration] done in {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
