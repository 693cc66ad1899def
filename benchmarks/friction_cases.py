"""The friction study's frames: its constants, the timed split of a frame, both studies.

The frames of :mod:`benchmarks.friction`: :func:`split` times the contact solve's parts,
:func:`cost_rows` solves study 1 (a frame with friction against the same frame
frictionless) and ``_iteration`` one frame of study 2 (Newton steps against ``mu``, the
stiffness ratio and mesh refinement).
"""

from __future__ import annotations

import dataclasses
import gc
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from contact.cases.hertz_bodies import hertz_scene
from contact.solver import ContactSettings, coulomb, delassus, solve_frame, tangential
from contact.solver.pairs import ContactPair
from contact.solver.results import FrameResult

from ._common import with_models
from .scenes import REFINEMENTS, CupLevel, hand_body, hand_cup

__all__ = [
    "EXAMPLES",
    "GOAL_RATIO",
    "GOAL_REFINEMENT",
    "HERTZ_SIZES",
    "MU",
    "MUS",
    "PARTS",
    "PRESS",
    "QUICK_CUP",
    "RATIOS",
    "REFINE_CASES",
    "REPEAT",
    "TABLE_INTO",
    "cost_rows",
    "split",
]

#: Goal: a frame with friction over the same frame frictionless.
GOAL_RATIO = 2.0
#: Goal: largest deviation of a frame's Newton steps over three meshes from their mean.
GOAL_REFINEMENT = 0.30
#: Coulomb's coefficient of the cost study and of the stiffness-ratio sweep.
MU = 0.5
#: Coefficients of the ``mu`` sweep.
MUS = (0.1, 0.2, 0.5, 1.0, 2.0)
#: Stiffness ratios (ball or sphere over the other body): full run and ``--quick``.
RATIOS: dict[bool, tuple[float, ...]] = {False: (0.01, 0.1, 1.0, 10.0, 100.0), True: (0.1, 10.0)}
#: Runs of each side of a cost row, the fastest kept: full run and ``--quick``.
REPEAT = {False: 3, True: 1}
#: The hand cup's rise (m).
PRESS = 0.005
#: Hertz's cell sizes at the contact (m), coarsest first: full run and ``--quick``.
HERTZ_SIZES: dict[bool, tuple[float, ...]] = {False: (0.045, 0.03, 0.02), True: (0.1, 0.08, 0.05)}
#: (E ratio, mu) of the refinement study: full run and ``--quick``.
REFINE_CASES: dict[bool, tuple[tuple[float, float], ...]] = {
    False: ((1.0, 0.5), (0.01, 0.5), (100.0, 0.5), (1.0, 0.1), (1.0, 2.0)),
    True: ((1.0, 0.5),),
}
#: The frictionless pinch's table: how far into the ball's bottom (m).
TABLE_INTO = 1e-4

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
PARTS = ("geometry_s", "rows_s", "law_s", "states_s", "factor_s", "other_s")


# --- the frame's split --------------------------------------------------------------------


@contextmanager
def split() -> Iterator[dict[str, float]]:
    """Time the contact solve's parts while the block runs: wrappers, restored after.

    Yields
    ------
    dict of str to float
        ``rows_s`` (the Delassus operators), ``law_s`` (frictional Newton solves, the
        frictionless LCP) and ``states_s`` (the bodies' displacements), summed (s).
    """
    acc = {"rows_s": 0.0, "law_s": 0.0, "states_s": 0.0}
    targets: list[tuple[Any, str, str]] = [
        (delassus.ContactSpace, "system", "rows_s"),
        (delassus.ContactSpace, "states", "states_s"),
        (tangential, "solve_friction", "law_s"),
        (coulomb, "solve_friction", "law_s"),
        (delassus, "solve_lcp", "law_s"),
    ]
    saved = [(owner, name, getattr(owner, name)) for owner, name, _ in targets]

    def timed(fn: Callable, key: str) -> Callable:
        def wrapper(*args: Any, **kw: Any) -> Any:
            t = time.perf_counter()
            try:
                return fn(*args, **kw)
            finally:
                acc[key] += time.perf_counter() - t

        return wrapper

    try:
        for (owner, name, key), (_, _, fn) in zip(targets, saved):
            setattr(owner, name, timed(fn, key))
        yield acc
    finally:
        for owner, name, fn in saved:
            setattr(owner, name, fn)


def _frame_row(res: FrameResult, seconds: float, parts: dict[str, float]) -> dict[str, Any]:
    """A frame's outcome, its Newton steps and its split."""
    tm = res.timings
    row: dict[str, Any] = {
        "frame_s": seconds,
        "updates": res.iterations,
        "converged": res.converged,
        "stop_reason": res.stop_reason,
        "contacts": len(res.contacts["node"]),
        "geometry_s": tm.get("geometry", 0.0),
        "factor_s": tm.get("factorisation", 0.0),
        **parts,
    }
    row["other_s"] = max(seconds - sum(row[k] for k in PARTS[:-1]), 0.0)
    f = res.friction
    if f is not None:
        row |= {
            "newton": f.iterations,
            "stick": f.stick,
            "slip": f.slip,
            "residual": f.residual,
            "max_cone_use": f.max_cone_use,
        }
    return row


def _solve(make: Callable[[], tuple]) -> dict[str, Any]:
    """Build a scene (untimed) and solve its frame, timed and split."""
    bodies, pairs, planes = make()
    gc.collect()
    with split() as parts:
        t = time.perf_counter()
        res = solve_frame(bodies, pairs, planes, ContactSettings())
        seconds = time.perf_counter() - t
    row = _frame_row(res, seconds, parts)
    row["dofs"] = sum(b.mesh.n_dofs for b in bodies)
    return row


def _with_friction(pairs: list[ContactPair], mu: float) -> list[ContactPair]:
    return [dataclasses.replace(p, friction=mu) for p in pairs]


# --- study 1: the cost --------------------------------------------------------------------


def _pair_rows(scene: str, case: str, free: dict, fric: dict) -> dict[str, Any]:
    """One cost row from the frictionless and the frictional frame."""
    ratio = fric["frame_s"] / free["frame_s"] if free else float("nan")
    row = {"study": "cost", "scene": scene, "case": case, "mu": MU, **fric}
    row |= {f"free_{k}": v for k, v in free.items()}
    row["ratio"] = ratio
    row["met"] = "-" if not free else ("met" if ratio <= GOAL_RATIO else "**missed**")
    row["solved"] = bool(fric["converged"] and (not free or free["converged"]))
    return row


def _best(rows: list[dict]) -> dict:
    return min(rows, key=lambda r: r["frame_s"])


def _cup_rows(quick: bool) -> list[dict]:
    cases = [(10.0, 4)] if quick else [(0.1, 8), (10.0, 8)]
    out = []
    for ratio, divisions in cases:

        def make(mu: float, ratio: float = ratio, n: int = divisions) -> tuple:
            bodies, pairs, planes = hand_cup(ratio, PRESS, "coarse", divisions=n)
            return bodies, _with_friction(pairs, mu), planes

        free, fric = [], []
        for _ in range(REPEAT[quick]):
            free.append(_solve(lambda: make(0.0)))
            fric.append(_solve(lambda: make(MU)))
        out.append(_pair_rows("hand cup", f"E ratio {ratio:g}", _best(free), _best(fric)))
    return out


def _sequence(scene: Any) -> list[dict]:
    """Every frame of a scene in time order (the anchors carried), each timed and split."""
    from contact.run import GraspRun

    run = GraspRun(scene)
    rows = []
    for t in scene.frames:
        gc.collect()
        with split() as parts:
            t0 = time.perf_counter()
            res, _, _, bodies = run.frame(t)
            seconds = time.perf_counter() - t0 - res.timings.get("setup", 0.0)
        row = _frame_row(res, seconds, parts)
        row["dofs"] = sum(b.mesh.n_dofs for b in bodies)
        rows.append(row)
    return rows


def _best_sequence(scene: Any, repeat: int) -> list[dict]:
    runs = [_sequence(scene) for _ in range(repeat)]
    return [_best(list(frames)) for frames in zip(*runs)]


def _pinch_rows(quick: bool) -> list[dict]:
    """The pinch's last frame; frictionless, a frictionless table carries the weight."""
    from contact.scene.model import PlaneScene
    from contact.scene.read import load_scene

    sc = load_scene(EXAMPLES / "pads.toml")
    bottom = sc.ball.center[2] - sc.ball.radius + TABLE_INTO
    table = PlaneScene("table", (0.0, 0.0, bottom), (0.0, 0.0, 1.0), friction=0.0)
    pads = tuple(dataclasses.replace(p, friction=0.0) for p in sc.planes)
    free = dataclasses.replace(sc, planes=(*pads, table))
    fric = _best_sequence(sc, REPEAT[quick])[-1]
    frames = _best_sequence(free, REPEAT[quick])[-1]
    case = f"last frame (t {sc.frames[-1]:g}); frictionless: on a table"
    row = _pair_rows("two-pad pinch", case, frames, fric)
    row["mu"] = sc.friction(sc.planes[0].name)
    return [row]


def _example_rows(quick: bool) -> list[dict]:
    """The bowl example's frames, frictionless and with ``[hand] friction = 0.5``."""
    from contact.scene.read import load_scene

    sc = with_models(load_scene(EXAMPLES / "bowl.toml"), "linear")
    assert sc.hand is not None
    fric_sc = dataclasses.replace(sc, hand=dataclasses.replace(sc.hand, friction=MU))
    free = _best_sequence(sc, REPEAT[quick])
    fric = _best_sequence(fric_sc, REPEAT[quick])
    return [
        _pair_rows("bowl example", f"frame {i} (t {t:g})", a, b)
        for i, (t, a, b) in enumerate(zip(sc.frames, free, fric, strict=True))
    ]


def cost_rows(quick: bool = False) -> list[dict]:
    """Study 1: the hand cup, the pinch and (full run) the bowl example.

    Parameters
    ----------
    quick : bool
        The hand cup with a coarse ball and the pinch, each once.

    Returns
    -------
    list of dict
        One row per frame: both times, their ratio, updates, Newton steps, stick and
        slip, and the split of each side (``free_*`` the frictionless one).
    """
    rows = _cup_rows(quick) + _pinch_rows(quick)
    return rows if quick else rows + _example_rows(quick)


# --- study 2: iterations ------------------------------------------------------------------

QUICK_CUP = (CupLevel("coarse hand, ball 6/3", "coarse", 6, 3),)


def _iteration(study: str, scene: str, level: int, ratio: float, mu: float, quick: bool) -> dict:
    if scene == "hand cup":
        lv = (QUICK_CUP if quick else REFINEMENTS)[level]

        def make() -> tuple:
            hand = hand_body(lv.resolution)
            bodies, pairs, planes = hand_cup(
                ratio, PRESS, divisions=lv.divisions, layers=lv.layers, hand=hand
            )
            return bodies, _with_friction(pairs, mu), planes

        mesh = lv.name
    else:
        h = HERTZ_SIZES[quick][level]

        def make() -> tuple:
            sc = hertz_scene("sphere-block", ratio, fine_size=h, radii=(1.0, 2.0))
            return list(sc.bodies), _with_friction(list(sc.pairs), mu), []

        mesh = f"h = {h:g}"
    row = _solve(make)
    row |= {"study": study, "scene": scene, "mesh": mesh, "level": level}
    row |= {"ratio": ratio, "mu": mu, "solved": bool(row["converged"])}
    row["per_update"] = row["newton"] / max(row["updates"], 1)
    return row


def _iteration_cases(quick: bool) -> list[tuple[str, str, int, float, float]]:
    scenes = ("sphere-block",) if quick else ("hand cup", "sphere-block")
    out = []
    for scene in scenes:
        out += [("mu", scene, 0, 1.0, mu) for mu in ((0.5, 2.0) if quick else MUS)]
        out += [("ratio", scene, 0, r, MU) for r in RATIOS[quick]]
        out += [
            ("refinement", scene, lv, ratio, mu)
            for ratio, mu in REFINE_CASES[quick]
            for lv in range(3)
        ]
    return out
