"""Coulomb friction: a frame's cost against the same frame frictionless, and its iterations.

Two studies, run together by ``python -m benchmarks friction [--quick]``:

1. *cost*: a frame with friction against the same frame without it, each the fastest of
   :data:`REPEAT` runs taken in turn in one run (goal: at most :data:`GOAL_RATIO` times).
   Scenes: the hand cup (:func:`benchmarks.scenes.hand_cup`, every pair at ``mu =``
   :data:`MU`), the two-pad pinch (``examples/pads.toml``: its frames in order, the last
   one timed; frictionless, the ball is held by a frictionless table 0.1 mm into its
   bottom instead) and the bowl example (``examples/bowl.toml`` with ``[hand]
   friction = 0.5``, every frame in order, as ``python -m contact.grasp`` solves it). The
   frame's split: geometry, compliance rows (:meth:`ContactSpace.system`: the Delassus
   operator of the normal and tangential rows), the law (the semismooth Newton solve, or
   the frictionless LCP), the bodies' states, factorisation, the rest.
2. *iterations*: Newton steps per frame (summed over its contact-set updates) and the
   updates against ``mu`` (0.1 to 2), the stiffness ratio (0.01 to 100) and three mesh
   refinements (goal: within +-:data:`GOAL_REFINEMENT` of their mean), on the hand cup and
   on Hertz's sphere pressed into a block (:func:`contact.cases.hertz_bodies.hertz_scene`).
"""

from __future__ import annotations

import dataclasses
import gc
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from contact.cases.hertz_bodies import hertz_scene
from contact.solver import ContactSettings, coulomb, delassus, solve_frame, tangential
from contact.solver.pairs import ContactPair
from contact.solver.results import FrameResult

from ._common import Column, machine_info, markdown_table, results_dir, write_csv, write_markdown
from .iteration import _code_version
from .scenes import REFINEMENTS, CupLevel, hand_body, hand_cup

__all__ = ["GOAL_RATIO", "GOAL_REFINEMENT", "MU", "MUS", "REPEAT", "cost_rows", "run", "split"]

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

#: What the tables need to be read right.
NOTES = """\
- Hertz's sphere on a block is a quarter model: the contacts on its two symmetry planes have
  a tangential row across the plane, a direction both bodies hold fixed there, so that row
  has no compliance (the contact on the axis has two). The Delassus operator is then
  singular (rank 175-177 of 198 rows at h = 0.045), each Newton step's Jacobian too (the
  solve falls back on least squares), and frames at E ratio 0.01 or 100, or mu = 2, stop at
  the Newton limit. Dropping the tangential rows that lie in both bodies' prescribed
  directions would make these frames well posed.
- The split comes from wrappers around the contact solve's parts; a profile (cProfile) of
  the hand cup at E ratio 0.1 puts the Newton time in the dense LU factorisation of each
  step's Jacobian (about 7 ms a step, 31 steps) and in least-squares fallbacks where that
  Jacobian is singular (about 55 ms each, 4 in the frame); the compliance rows cost about
  three times the frictionless ones (three rows a contact).
- The frictionless pinch stands on a table 0.1 mm into the ball's bottom (the solver
  reports the overlap at the first frame): on a table touching it exactly, the table
  carries all but about 1e-5 of the weight and the frame stops "not held".
"""

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

    sc = load_scene(EXAMPLES / "bowl.toml")
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


def _refinement_goals(rows: list[dict]) -> list[dict]:
    goals = []
    sel = [r for r in rows if r["study"] == "refinement"]
    for key in dict.fromkeys((r["scene"], r["ratio"], r["mu"]) for r in sel):
        group = [r for r in sel if (r["scene"], r["ratio"], r["mu"]) == key]
        steps = np.array([r["newton"] for r in group], dtype=float)
        spread = float(np.abs(steps / steps.mean() - 1).max())
        ok = all(r["solved"] for r in group) and spread <= GOAL_REFINEMENT
        goals.append(
            {
                "scene": key[0],
                "ratio": key[1],
                "mu": key[2],
                "newton": " / ".join(f"{r['newton']}" + ("" if r["solved"] else "*")
                                     for r in group),
                "updates": " / ".join(str(r["updates"]) for r in group),
                "spread": spread,
                "verdict": "met" if ok else "**missed**",
            }
        )
    return goals


# --- the report ---------------------------------------------------------------------------

COST_COLUMNS = (
    Column("scene", "scene"),
    Column("case", "case"),
    Column("dofs", "DOFs", ","),
    Column("free_frame_s", "frictionless (s)", ".3f"),
    Column("frame_s", "friction (s)", ".3f"),
    Column("ratio", "ratio", ".2f"),
    Column("met", "<= 2"),
    Column("free_updates", "updates, frictionless", "d"),
    Column("updates", "updates", "d"),
    Column("newton", "Newton steps", "d"),
    Column("stick", "stick", "d"),
    Column("slip", "slip", "d"),
    Column("residual", "residual", ".1e"),
)
SPLIT_COLUMNS = (
    Column("scene", "scene"),
    Column("case", "case"),
    Column("side", "side"),
    Column("geometry_s", "geometry", ".3f"),
    Column("rows_s", "compliance rows", ".3f"),
    Column("law_s", "Newton / LCP", ".3f"),
    Column("states_s", "states", ".3f"),
    Column("factor_s", "factorisation", ".3f"),
    Column("other_s", "other", ".3f"),
    Column("frame_s", "frame", ".3f"),
)
ITER_COLUMNS = (
    Column("scene", "scene"),
    Column("mesh", "mesh"),
    Column("dofs", "DOFs", ","),
    Column("ratio", "E ratio", "g"),
    Column("mu", "mu", "g"),
    Column("updates", "updates", "d"),
    Column("newton", "Newton steps", "d"),
    Column("per_update", "per update", ".1f"),
    Column("contacts", "contacts", "d"),
    Column("stick", "stick", "d"),
    Column("slip", "slip", "d"),
    Column("residual", "residual", ".1e"),
    Column("frame_s", "frame (s)", ".2f"),
    Column("stop_reason", "stop"),
)
GOAL_COLUMNS = (
    Column("scene", "scene"),
    Column("ratio", "E ratio", "g"),
    Column("mu", "mu", "g"),
    Column("newton", "Newton steps (3 meshes)"),
    Column("updates", "updates"),
    Column("spread", "largest deviation from the mean", ".0%"),
    Column("verdict", "+-30 %"),
)


def _split_rows(cost: list[dict]) -> list[dict]:
    out = []
    for r in cost:
        if "free_frame_s" in r:
            free = {k[5:]: v for k, v in r.items() if k.startswith("free_")}
            out.append({"scene": r["scene"], "case": r["case"], "side": "frictionless", **free})
        out.append({**r, "side": f"mu {r['mu']:g}"})
    return out


def _summary(cost: list[dict], goals: list[dict], rows: list[dict]) -> str:
    timed = [r for r in cost if r["met"] != "-"]
    worst = max(timed, key=lambda r: r["ratio"])
    met = sum(r["ratio"] <= GOAL_RATIO for r in timed)
    lines = [
        f"Cost: friction / frictionless <= {GOAL_RATIO:g} on {met} of {len(timed)} frames; "
        f"worst {worst['ratio']:.2f} ({worst['scene']}, {worst['case']}).",
        f"Refinement: Newton steps within +-{GOAL_REFINEMENT:.0%} of their mean on "
        f"{sum(g['verdict'] == 'met' for g in goals)} of {len(goals)} (scene, E ratio, mu).",
    ]
    missed = [r for r in timed if r["ratio"] > GOAL_RATIO]
    if missed:
        lines += ["", "Where each missed frame's extra time goes (friction less frictionless):"]
        lines += [
            f"- {r['scene']}, {r['case']}: +{r['frame_s'] - r['free_frame_s']:.3f} s, of which "
            + ", ".join(
                f"{label} {r[k] - r['free_' + k]:+.3f} s"
                for label, k in (("Newton against LCP", "law_s"), ("compliance rows", "rows_s"),
                                 ("states", "states_s"), ("other", "other_s"))
            )
            + f" ({r['newton']} Newton steps, {r['contacts']} contacts)"
            for r in missed
        ]
    failed = [r for r in rows if not r["solved"]]
    if failed:
        lines.append("")
        lines.append("Frames not solved (stop reason):")
        lines += [
            f"- {r['study']}: {r['scene']}, {r.get('mesh') or r.get('case')}, E ratio "
            f"{r.get('ratio', '-')}, mu {r['mu']:g}: {r['stop_reason']}"
            for r in failed
        ]
    return "\n".join(lines)


def run(quick: bool = False, out: str | Path | None = None) -> list[dict]:
    """Run both studies and write ``friction.{csv,md,png}``.

    Parameters
    ----------
    quick : bool
        Small scenes, each once: seconds.
    out : path, optional
        Results folder; ``benchmarks/results`` (``.../quick``) by default.

    Returns
    -------
    list of dict
        The cost rows (``study == "cost"``), then one row per frame of study 2.
    """
    folder = results_dir(out, quick)
    info = machine_info()
    info["code"] = _code_version()
    cost = cost_rows(quick)
    for r in cost:
        print(f"[friction] {r['scene']}, {r['case']}: {r['frame_s']:.3f} s against "
              f"{r.get('free_frame_s', float('nan')):.3f} s ({r['ratio']:.2f})")
    iters = [_iteration(*case, quick) for case in _iteration_cases(quick)]
    rows = cost + iters
    goals = _refinement_goals(iters)
    keys = list(dict.fromkeys(k for r in rows for k in r))
    write_csv(folder / "friction.csv", rows, keys)
    q = " (quick)" if quick else ""
    by = {s: [r for r in iters if r["study"] == s] for s in ("mu", "ratio", "refinement")}
    sections = [
        ("Summary" + q, _summary(cost, goals, rows)),
        (
            "Cost: a frame with friction against the same frame frictionless" + q,
            markdown_table(cost, COST_COLUMNS)
            + f"\n\nmu = {MU:g} on every pair of the hand cup and on the bowl example's "
            "hand; the pinch's pads carry its own. Each side is the fastest of "
            f"{REPEAT[quick]} runs, taken in turn. Newton steps: the semismooth Newton "
            "solve's, summed over the frame's contact-set updates; stick and slip: closed "
            "contacts at the end. The pinch and the bowl example solve their frames in "
            "order (the anchors carried) and reuse the ball's factorisation after the "
            "first frame; the hand cup's frames factor their bodies.",
        ),
        (
            "Where the time goes (s)" + q,
            markdown_table(_split_rows(cost), SPLIT_COLUMNS)
            + "\n\nCompliance rows: the Delassus operator of the rows (normal and "
            "tangential), from the bodies' factorisations; Newton / LCP: the frictional "
            "solve (dense Jacobians) or the frictionless LCP; states: the bodies' "
            "displacements under the forces; other: contact-set bookkeeping, anchors, "
            "tangential rows.",
        ),
        ("Refinement goal" + q, markdown_table(goals, GOAL_COLUMNS)
         + "\n\n`*`: not solved (counts as missed)."),
        ("Newton steps against mu (E ratio 1)" + q, markdown_table(by["mu"], ITER_COLUMNS)),
        (f"Newton steps against the stiffness ratio (mu {MU:g})" + q,
         markdown_table(by["ratio"], ITER_COLUMNS)),
        ("Newton steps against mesh refinement" + q,
         markdown_table(by["refinement"], ITER_COLUMNS)
         + f"\n\nHand cup: press {PRESS * 1e3:g} mm; Hertz: R = 1 m, interference 0.01 m, "
         "quarter model, pairs both ways."),
        ("Notes", NOTES),
    ]
    write_markdown(folder / "friction.md", "Coulomb friction: cost and iterations", info, sections)
    _plot(folder / "friction.png", cost, iters)
    return rows


def _plot(path: Path, cost: list[dict], iters: list[dict]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(12, 9))
    a0, a1, a2, a3 = axes.ravel()
    timed = [r for r in cost if r["met"] != "-"]
    x = np.arange(len(timed))
    a0.bar(x, [r["ratio"] for r in timed], color="tab:blue")
    a0.axhline(GOAL_RATIO, color="k", ls="--", lw=1, label=f"goal {GOAL_RATIO:g}")
    a0.set_xticks(x, [f"{r['scene']}\n{r['case'][:24]}" for r in timed], fontsize=7,
                  rotation=30, ha="right")
    a0.set_ylabel("friction / frictionless")
    a0.set_title("cost of a frame")
    a0.legend(fontsize="small")
    for ax, study, key, log in ((a1, "mu", "mu", True), (a2, "ratio", "ratio", True),
                                (a3, "refinement", "dofs", True)):
        sel = [r for r in iters if r["study"] == study]
        groups = dict.fromkeys((r["scene"], r["ratio"] if study != "ratio" else None,
                                r["mu"] if study == "refinement" else None) for r in sel)
        for scene, ratio, mu in groups:
            g = [r for r in sel if r["scene"] == scene
                 and (ratio is None or r["ratio"] == ratio) and (mu is None or r["mu"] == mu)]
            label = scene + (f", E ratio {ratio:g}" if study == "refinement" else "")
            label += f", mu {mu:g}" if mu is not None else ""
            ax.plot([r[key] for r in g], [r["newton"] for r in g], marker="o", label=label)
            bad = [(r[key], r["newton"]) for r in g if not r["solved"]]
            if bad:
                ax.plot(*zip(*bad), ls="", marker="o", ms=11, mfc="none", color="r")
        ax.set_xscale("log" if log else "linear")
        ax.set_ylabel("Newton steps per frame")
        ax.set_xlabel({"mu": "mu", "ratio": "E ball / E other body", "dofs": "DOFs"}[key])
        ax.set_title(f"against {study} (ringed: not solved)", fontsize="medium")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize="x-small")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
