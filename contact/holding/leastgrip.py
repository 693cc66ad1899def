"""``--least-grip``: the least scale of a scene's grip that holds its free ball at every frame.

Every force-driven element (:attr:`contact.scene.Scene.grip`) is scaled together, in the
scene's proportions (:meth:`contact.scene.Scene.grip_scaled`). A trial at scale ``s``
solves every frame in time order with a fresh friction history
(:meth:`contact.run.GraspRun.restart`, which shares the factorised bodies) and holds when
every frame is held; it stops at the first frame that is not. The search brackets the
least grip between a trial that does not hold (``lo``) and one that holds (``hi``), both
run, until ``(hi - lo) / hi <= tol``; the least grip reported is ``hi``.

Each trial also gives a continuous measure of how far it is from slipping,
``h = available / needed`` friction (:func:`measure`): for a ball held by friction,
the friction available grows with the grip while the load it must carry does not, so
``h`` is about proportional to ``s`` and the least grip is where ``h = 1``. The next
scale is the root of ``h - 1`` (regula falsi between the bracket's ends, Illinois-weighted,
or ``s / h`` from one trial), nudged by a third of the tolerance to the side the last
trial did not reach, so that a good estimate closes the bracket in two trials. No
estimate, or trials in a row on the same side (two outside a bracket, three inside one,
the second of them Illinois-weighted), fall back to bisection (doubling or halving
outside a bracket), which bounds the number of trials however noisy ``h`` is.

A verdict is a promise: a trial holds only when every frame is held and converged (a
frame whose bone passes its limit is converged and counts as held: its contacts hold the
ball; the frame's own verdict says the bone is overloaded; so does one held where its
fingers' forces jump over those asked and it stopped below them). A trial whose ball slips or
turns brackets the answer from below; one that fails for another reason (friction that
did not settle, a finger force not reached, an iteration limit, bad input) says nothing
of the grip and never brackets it: the search steps past it, and where only such trials
lie below the least grip that held, the answer is not found (``limit = "solver"``),
unless the cones there are full (friction available over needed within
:data:`FULL` of 1). The answer names what limits it (:attr:`LeastGrip.limit`) and the
frame that does, with the forces there.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

from ..errors import ContactError
from ..run import GraspRun
from ..scene import model
from ..scene.spec import Scene
from ..solver.results import FrameResult

__all__ = [
    "BOUND", "FULL", "MAX_TRIALS", "LeastGrip", "Trial", "judge", "least_grip", "measure",
    "search",
]  # fmt: skip

#: The largest (and 1 / the smallest) scale of the scene's grip the search tries.
BOUND = 64.0
#: The most trials one search runs: bisection alone brackets 1 % of a 64x range in 13.
MAX_TRIALS = 40
#: Friction available over needed within this of 1: the cones are full (the grip's
#: limit is friction whatever the trials below it did).
FULL = 0.02

@dataclass(frozen=True)
class Trial:
    """One trial of the search: the scene's grip times ``scale``.

    Attributes
    ----------
    scale : float
    holds : bool
        Every frame held and converged.
    h : float or None
        Friction available over friction needed at the hardest frame (:func:`measure`):
        > 1 holds with room, < 1 slips; None where no frame gave one.
    solves : int
        Frames solved (0 for a trial reused from the normal run).
    time : float or None
        The first frame not held, None where all are.
    reason : str
        That frame's stop reason, or ``"held"``.
    hardest : float or None
        The frame that limits it: the first not held, else the one with the least ``h``.
    bone : bool
        A frame of it had a bone past its limit.
    """

    scale: float
    holds: bool
    h: float | None = None
    solves: int = 0
    time: float | None = None
    reason: str = "held"
    hardest: float | None = None
    bone: bool = False

    @property
    def slipped(self) -> bool:
        """The trial failed because the ball slips or turns (not for another reason)."""
        return self.kind in ("friction", "rotation")

    @property
    def kind(self) -> str:
        """How it ended: ``"held"``, ``"friction"``, ``"rotation"`` or ``"solver"``.

        The ball slides (friction), turns or turned past what the linear model describes
        (rotation), or the frame stopped for another reason (solver).
        """
        if self.holds:
            return "held"
        r = self.reason
        if r.startswith("not held"):
            return "rotation" if " turns" in r else "friction"
        if " turned " in r and "past the" in r:
            return "rotation"
        return "solver"


@dataclass(frozen=True)
class LeastGrip:
    """The outcome of the search.

    Attributes
    ----------
    scale : float or None
        The least grip found as a multiple of the scene's (a scale that was run and
        held); None where none held up to :data:`BOUND`.
    forces : dict of str to float
        Each force-driven element's peak force at ``scale`` (N); empty where none held.
    margin : float or None
        ``1 / scale``: the scene's own grip over the least that holds.
    steps : int
        Trials, the scene's own grip included.
    solves : int
        Frame solves the search ran (the scene's own run, where reused, not counted).
    lo, hi : float or None
        The bracket: ``lo`` does not hold (0 where every scale tried down to
        ``1 / BOUND`` held), ``hi`` holds (None where none did).
    seconds : float
        Wall time of the search.
    found : bool
        The bracket is within the tolerance.
    note : str
        What the search found, in words.
    limit : str or None
        What sets the answer: ``"friction"`` (a grip just below slips), ``"rotation"``
        (just below, the ball turns), ``"bone"`` (the grip that holds takes a bone past
        its limit) or ``"solver"`` (the trials below did not settle: not found); None
        where nothing held.
    frame : float or None
        The time of the frame that limits the answer (the hardest of ``hi``'s trial).
    frame_forces : dict of str to float
        Each force-driven element's force at that frame (N).
    trials : tuple of Trial
        Every trial, in the order run.
    """

    scale: float | None
    forces: dict[str, float]
    margin: float | None
    steps: int
    solves: int
    lo: float | None
    hi: float | None
    seconds: float
    found: bool
    note: str
    limit: str | None = None
    frame: float | None = None
    frame_forces: dict[str, float] = field(default_factory=dict)
    trials: tuple[Trial, ...] = field(default=(), repr=False)

    def record(self) -> dict:
        """The ``least_grip`` item of ``summary.json``: JSON types, ``bracket = [lo, hi]``."""
        return {
            "scale": self.scale,
            "forces": dict(self.forces),
            "margin": self.margin,
            "steps": self.steps,
            "solves": self.solves,
            "seconds": self.seconds,
            "bracket": [self.lo, self.hi],
            "found": self.found,
            "note": self.note,
            "limit": self.limit,
            "limiting_frame": {"time": self.frame, "forces": dict(self.frame_forces)},
            "trials": [
                {"scale": t.scale, "holds": t.holds, "h": t.h, "solves": t.solves,
                 "time": t.time, "reason": t.reason, "kind": t.kind}
                for t in self.trials
            ],
        }  # fmt: skip


def measure(result: FrameResult, scene: Scene, body: str | None = None) -> float | None:
    """Friction available over friction needed by ``body`` in one frame, or None.

    ``body`` None: the least over the scene's free objects (:attr:`Scene.free_objects`).

    Held: the sum of ``mu N`` over the body's contacts over the sum of the magnitudes of
    the tangential forces of its pairs. Not held by friction (:attr:`FrameResult.slip`):
    ``C / (C + F)``, ``C`` the friction available and ``F`` the load its contacts did not
    carry (:func:`contact.solver.coulomb.unheld`): forces where it slides, moments where
    it turns. Both are 1 at the slip limit and grow about
    in proportion to the grip. None where the frame gives neither (no friction used, or
    a stop for another reason).
    """
    slip = result.slip
    if slip is not None:  # not held: the friction its contacts had, the load they left
        # (forces where it slides; moments, sum mu N r, where it turns)
        f, c = float(slip["not_carried"]), float(slip["available"])
        return c / (c + f) if c + f > 0 else None
    if result.held is not True or result.friction is None:
        return None
    if body is None:
        each = [measure(result, scene, name) for name in scene.free_objects]
        found = [h for h in each if h is not None]
        return min(found) if found else None
    c = result.contacts or {}
    names = [str(n) for n in c.get("pair", ())]
    forces = [abs(float(x)) for x in c.get("force", ())]
    mus: dict[str, float] = {}
    available = 0.0
    for name, n in zip(names, forces, strict=True):
        if name not in mus:
            mus[name] = _pair_mu(scene, name, body)
        available += mus[name] * n
    used = sum(
        math.hypot(*(float(x) for x in t))
        for name, t in result.friction.tangential_force.items()
        if "/" in name and body in name.split("/")
    )
    return available / used if used > 0 and available > 0 else None


def _pair_mu(scene: Scene, pair: str, body: str) -> float:
    """Coulomb's coefficient of a ``slave/master`` pair of ``body`` (0 if not its pair)."""
    slave, _, master = pair.partition("/")
    other = master if slave == body else slave if master == body else None
    if other is None:
        return 0.0
    try:
        return scene.friction(other, body)
    except KeyError:
        return 0.0


def _holds(result: FrameResult) -> bool:
    """A frame holds: held and converged (a bone over its limit does not stop a frame).

    Or held where its fingers stopped below the forces asked (a force that jumps as a
    node enters the contact, :attr:`FrameResult.below_grip`): a grip that holds at smaller
    finger forces holds at those asked, as the search's premise (held grows with the grip).
    """
    return result.held is True and (bool(result.converged) or result.below_grip)


def judge(
    scale: float, results: Sequence[FrameResult], times: Sequence[float], scene: Scene
) -> Trial:
    """A trial from its frames' results, in time order (the last may be the first not held).

    Parameters
    ----------
    scale : float
    results : sequence of FrameResult
        The frames solved, ``times[i]`` each.
    times : sequence of float
    scene : Scene
        The scene (for the pairs' friction).
    """
    hs = [measure(r, scene) for r in results]
    bone = any(bool(r.over_limit) for r in results)
    for t, r, h in zip(times, results, hs, strict=False):
        if not _holds(r):
            return Trial(scale, False, h, len(results), t, str(r.stop_reason), t, bone)
    known = [(h, t) for h, t in zip(hs, times, strict=False) if h is not None]
    h, hardest = min(known) if known else (None, times[-1] if len(times) else None)
    return Trial(scale, True, h, len(results), hardest=hardest, bone=bone)


def _trial(run: GraspRun, frames: Sequence[float], scale: float) -> Trial:
    """Solve every frame at ``scale`` in order, stopping at the first not held."""
    scene = run.scene
    trial = run.restart(scene.grip_scaled(scale))
    results: list[FrameResult] = []
    for t in frames:
        try:
            result = trial.frame(t)[0]
        except ContactError as exc:  # counts as not held, with no measure
            return Trial(scale, False, None, len(results) + 1, t, f"failed: {exc}")
        results.append(result)
        if not _holds(result):
            break
    return judge(scale, results, frames[: len(results)], scene)


def least_grip(
    run: GraspRun,
    frames: Sequence[float],
    *,
    tol: float = 0.01,
    bound: float = BOUND,
    first: Trial | None = None,
    on_trial: Callable[[int, Trial], None] | None = None,
) -> LeastGrip:
    """The least scale of ``run``'s grip that holds its ball at every frame of ``frames``.

    Parameters
    ----------
    run : GraspRun
        The scene's run; each trial restarts it (:meth:`GraspRun.restart`).
    frames : sequence of float
        The frame times, increasing.
    tol : float
        Relative width of the final bracket, ``(hi - lo) / hi``.
    bound : float
        The search stays within ``[1 / bound, bound]`` times the scene's grip (and under
        :data:`contact.scene.model.MAX_FORCE` on every element).
    first : Trial, optional
        The trial at scale 1 where it was already run (:func:`judge` of the normal run).
    on_trial : callable, optional
        Called with each trial's number (1-based) and the trial.

    Raises
    ------
    SceneError
        When the scene has nothing force-driven, nothing to hold or no friction.
    """
    grip = run.scene.grip
    top = min(bound, model.MAX_FORCE / max(max(grip.values()), 1e-300))
    out = search(
        lambda s: _trial(run, frames, s), tol=tol, bound=top, floor=1.0 / bound,
        first=first, on_trial=on_trial,
    )  # fmt: skip
    if out.scale is None:
        return out
    forces = {k: v * out.scale for k, v in grip.items()}
    at = {}
    if out.frame is not None:
        at = {k: v * out.scale for k, v in run.scene.grip_at(out.frame).items()}
    return replace(out, forces=forces, frame_forces=at)


def search(
    trial: Callable[[float], Trial],
    *,
    tol: float = 0.01,
    bound: float = BOUND,
    floor: float = 1.0 / BOUND,
    first: Trial | None = None,
    on_trial: Callable[[int, Trial], None] | None = None,
    max_trials: int | None = None,
) -> LeastGrip:
    """The bracketing search on a trial function (scale -> :class:`Trial`), from scale 1.

    ``forces`` of the answer is empty (:func:`least_grip` fills it). See the module's
    docstring for the rule that picks each next scale.
    """
    limit = MAX_TRIALS if max_trials is None else max_trials
    t0 = time.perf_counter()
    trials: list[Trial] = []
    lo: Trial | None = None  # the largest scale that slipped or turned
    hi: Trial | None = None  # the smallest scale that held
    below: Trial | None = None  # the largest scale under hi that did not settle
    weights = [1.0, 1.0]  # Illinois: lo's and hi's measure weights
    streak = 0  # trials in a row on the same side

    def run(s: float) -> Trial:
        tr = first if (first is not None and not trials) else trial(s)
        trials.append(tr)
        if on_trial is not None:
            on_trial(len(trials), tr)
        return tr

    last = run(1.0)
    note = ""
    while True:
        same = len(trials) > 1 and trials[-2].holds == last.holds
        streak = streak + 1 if same else 1
        # Illinois: the end kept twice in a row counts half in the regula falsi
        if last.holds:
            hi, weights[1] = last, 1.0
            below = below if below is not None and below.scale < hi.scale else None
        elif last.slipped:
            lo, weights[0] = last, 1.0
        elif hi is None or last.scale < hi.scale:
            below = last if below is None or last.scale > below.scale else below
        if same:
            weights[0 if last.holds else 1] /= 2
        if hi is not None and lo is not None and (hi.scale - lo.scale) / hi.scale <= tol:
            note = f"held at {hi.scale:.4g}x, not at {lo.scale:.4g}x ({lo.kind})"
            break
        under = _under(lo, below)
        if hi is not None and under is not None and (hi.scale - under.scale) / hi.scale <= tol:
            note = (
                f"held at {hi.scale:.4g}x; below it the trials did not settle "
                f"({under.scale:.4g}x: {under.reason.split(':')[0]})"
            )
            break
        if len(trials) >= limit:
            note = f"stopped after {len(trials)} trials"
            break
        under = _under(lo, below)
        if hi is None:
            assert under is not None
            if under.scale >= bound * (1 - 1e-12):
                note = f"no grip up to {bound:g}x holds"
                break
            s = _up(under, bound, tol, streak)
        elif under is None:
            if hi.scale <= floor * (1 + 1e-12):
                note = f"held down to {floor:g}x: the least grip is below it"
                break
            s = _down(hi, floor, tol, streak)
        else:
            s = _between(under, hi, weights, last.holds, tol, streak)
        last = run(s)
    bracketed = hi is not None and lo is not None and (hi.scale - lo.scale) / hi.scale <= tol
    full = hi is not None and hi.h is not None and abs(hi.h - 1.0) <= FULL
    found = bracketed or full
    scale = None if hi is None else hi.scale
    if hi is None:
        why = None
    elif hi.bone:
        why = "bone"
    elif bracketed:
        why = lo.kind if lo is not None else None
    else:
        why = "friction" if full else "solver"
    return LeastGrip(
        scale=scale,
        forces={},
        margin=None if scale is None else 1.0 / scale,
        steps=len(trials),
        solves=sum(t.solves for t in trials),
        lo=0.0 if lo is None else lo.scale,
        hi=scale,
        seconds=time.perf_counter() - t0,
        found=found,
        note=note,
        limit=why,
        frame=None if hi is None else hi.hardest,
        trials=tuple(trials),
    )


def _under(lo: Trial | None, below: Trial | None) -> Trial | None:
    """The trial under the answer that the next scale steps up from.

    The higher of the last that slipped and the last that did not settle (which brackets
    nothing).
    """
    if lo is None or below is None:
        return lo or below
    return below if below.scale > lo.scale else lo


def _estimate(tr: Trial) -> float | None:
    """``s / h``: where ``h`` (about proportional to ``s``) reaches 1, from one trial."""
    if tr.h is None or not tr.h > 0 or not math.isfinite(tr.h):
        return None
    return tr.scale / tr.h


def _up(lo: Trial, bound: float, tol: float, streak: int) -> float:
    """The next scale above a grip that slips, none held yet: the estimate, or double."""
    e = _estimate(lo) if streak < 2 else None
    s = 2.0 * lo.scale if e is None else max(e * (1 + tol / 3), lo.scale * (1 + tol))
    return min(s, bound)


def _down(hi: Trial, floor: float, tol: float, streak: int) -> float:
    """The next scale below a grip that holds, none slipped yet: the estimate, or halve."""
    e = _estimate(hi) if streak < 2 else None
    s = 0.5 * hi.scale if e is None else min(e * (1 - tol / 3), hi.scale * (1 - tol))
    return max(s, floor)


def _between(
    lo: Trial, hi: Trial, weights: list[float], held: bool, tol: float, streak: int
) -> float:
    """The next scale inside the bracket: regula falsi (Illinois) on ``h - 1``, nudged."""
    a, b = lo.scale, hi.scale
    mid = 0.5 * (a + b)
    if streak >= 3:
        return mid
    if lo.h is not None and hi.h is not None and hi.h > lo.h:
        fa, fb = weights[0] * (lo.h - 1.0), weights[1] * (hi.h - 1.0)
        r = a - fa * (b - a) / (fb - fa) if fb != fa else mid
    else:
        r = _estimate(hi if held else lo)
        if r is None:
            r = _estimate(lo if held else hi)
    if r is None:
        return mid
    # aim just past the estimate, on the side the last trial did not reach
    s = r * (1 - tol / 3) if held else r * (1 + tol / 3)
    return s if a < s < b else mid
