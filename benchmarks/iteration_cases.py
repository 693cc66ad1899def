"""The contact-iteration study's cases: its constants, variants and frames, each solved.

The scenes, stiffness ratios, meshes and press depths of the three studies of
:mod:`benchmarks.iteration`, the ways of solving a frame (:class:`Variant`), and
:func:`solve_case`, which solves one frame on new bodies and summarises it.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from contact.cases.hertz_bodies import hertz_scene
from contact.solver import ContactSettings, solve_frame
from contact.solver.results import FrameResult

from ._common import load_average
from .scenes import REFINEMENTS, CupLevel, clearance, hand_body, hand_cup

__all__ = [
    "CONTACT_SPACE",
    "CUP_LEVELS",
    "FACTOR",
    "GOAL_REFINEMENT",
    "GOAL_UPDATES",
    "HERTZ_SIZES",
    "MAX_ITERATIONS",
    "PRESS",
    "PRESSES",
    "PRESS_RATIOS",
    "RADII",
    "RATIOS",
    "REFINE_RATIOS",
    "SCENES",
    "SEEDS",
    "SEED_AITKEN",
    "SEED_FIXED",
    "SEED_NONE",
    "Case",
    "Variant",
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
