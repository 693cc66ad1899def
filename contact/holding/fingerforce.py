"""Force-driven fingers: a joint closes until its finger's normal contact force is given.

``[[hand.auto_flexion]] force = N`` asks for the flexion of one joint at which the total
normal contact force on its finger is ``N``. Force grows with the flexion past first
contact (the finger presses deeper), so each joint's angle is a 1-D root of
``F(alpha) - N``; every trial is a contact solve of the whole frame.

All force-driven joints first press :data:`FIRST_PRESS` past their first contact (the
geometry's angle, force 0: a guess, since the ball may have moved since it was
measured), one solve. Then, in turn, each joint whose force is off is searched alone,
the others held (one finger's force also moves the others' where they squeeze one free
ball: in a pinch the thumb's force follows the index's, and one search does both): its
press past first contact scaled as a Hertz contact's (``F ~ d^{3/2}``) to the target
(from a trial at or below first contact, the body moved since: as far again toward it),
then the secant through its last two trials while the force is below the target (the
force is convex in the press, so the secant overshoots and brackets the root), limited
to :data:`GROWTH` times the last step (above the target on a force flat within its
tolerance, twice the last step back), and the Illinois variant of regula falsi once the
root is bracketed, bisecting a bracket two steps did not halve. Turns repeat until every
force is within its ``force_tolerance``, in at most :data:`MAX_STEPS` solves a joint that
settle (and as many more that do not).
A joint stops short at its limit, or where its force jumps across the target within
:data:`ANGLE_RESOLUTION` (a node entering the contact, stick turning to slip): the frame
then ends below the jump, its grip no firmer than the one asked. A trial whose free body
is not held counts as below the force, whatever its fingers' forces (a moving body's): a
finger closed less holds no better. So where the angles that hold give more than the
target, the frame ends not held, at the angle below them that did not hold: once the held
force's secant (convex, the force lies above it) stays above the target down to that
angle, or within :data:`ANGLE_RESOLUTION` of one that held.

A trial whose frame did not settle (Newton or friction stopped short, a linear ball
turned past its bound) guides the next step but never brackets the root nor ends the
search: the next trial goes halfway back to the settled trials below the force (above
it, where none is below; with none settled past first contact, along the secant of the
trials that did not settle), and a joint whose next trial would fall within
:data:`ANGLE_RESOLUTION` of the settled ones next to it or of one that did not settle
stops, saying so (the solver's limit, not the finger's).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = [
    "ANGLE_RESOLUTION",
    "FIRST_PRESS",
    "GROWTH",
    "MAX_STEPS",
    "Drive",
    "Target",
    "drive",
]  # fmt: skip

#: The first trial presses each force-driven finger this far (m) past first contact.
FIRST_PRESS = 5e-4
#: Contact solves that settle a frame may take for each of its force-driven joints (and as
#: many that do not: they say nothing of the force).
MAX_STEPS = 12
#: The largest factor by which an extrapolated step may exceed the joint's last one.
GROWTH = 4.0
#: A bracket narrower than this (degrees) whose ends miss the force: the force jumps there.
ANGLE_RESOLUTION = 1e-2


@dataclass(frozen=True)
class Target:
    """One force-driven joint.

    Attributes
    ----------
    joint : str
        The angle searched.
    force : float
        The finger's normal contact force to reach (N).
    tolerance : float
        Relative accuracy of that force.
    limit : float
        The joint's upper limit (degrees): it closes no further.
    part : int
        Its finger's hand part (:attr:`contact.hand.shipped.Hand.part_names`).
    """

    joint: str
    force: float
    tolerance: float
    limit: float
    part: int = -1

    def reached(self, f: float) -> bool:
        """Whether force ``f`` is within the tolerance of the target."""
        return abs(f - self.force) <= self.tolerance * self.force


@dataclass
class Drive:
    """A force-driven joint's search: its trials and outcome (``summary.json``).

    Attributes
    ----------
    joint : str
    force : float
        The target (N).
    trials : list of (float, float)
        ``(angle, force)`` of every trial, in order (the first contact's, force 0, first).
    converged : bool
        The last trial settled with its force within the tolerance.
    reason : str
        Why it stopped.
    unsettled : dict of float to str
        The angles whose frames did not settle, and why: their forces guide, never bracket.
    lost : set of float
        The angles whose frames settled with the free body not held: below the force.
    """

    joint: str
    force: float
    trials: list[tuple[float, float]] = field(default_factory=list)
    converged: bool = False
    reason: str = ""
    unsettled: dict[float, str] = field(default_factory=dict)
    lost: set[float] = field(default_factory=set)
    _side: int = 0  # Illinois: which end of the bracket was kept last, -1 low, +1 high
    _widths: list[float] = field(default_factory=list)  # the bracket's, step by step
    _start: int = 1  # the trials of the current search, the other joints held (from here)
    final: tuple[float | None, float | None] = (None, None)  # the last search's bracket

    @property
    def angle(self) -> float:
        """The last angle tried (the frame's)."""
        return self.trials[-1][0]

    @property
    def reached(self) -> float:
        """The force at the last angle (N); 0 where the body was not held there."""
        a, f = self.trials[-1]
        return 0.0 if a in self.lost else f

    def bracket(self) -> tuple[float | None, float | None]:
        """The largest angle solved whose force is below the target and the least above it.

        The first contact's force, 0, is a guess of the geometry (the ball may have moved
        since it was measured), never an end of the bracket.
        """
        now = self.settled()
        below = [a for a, f in now if f < self.force]
        above = [a for a, f in now if f >= self.force]
        return (max(below) if below else None, min(above) if above else None)

    def settled(self) -> list[tuple[float, float]]:
        """The current search's trials whose frames settled, force 0 where not held."""
        return [
            (a, 0.0 if a in self.lost else f)
            for a, f in self.trials[self._start :]
            if a not in self.unsettled
        ]

    @property
    def failed(self) -> bool:
        """The last trial did not settle."""
        return self.trials[-1][0] in self.unsettled

    def restart(self, angle: float, force: float) -> None:
        """Start a new search from ``(angle, force)``: the other joints moved since."""
        if (angle, force) != self.trials[-1]:
            self.trials.append((angle, force))
        self._start = len(self.trials) - 1
        self._side, self._widths = 0, []

    def record(self) -> dict[str, Any]:
        """As plain JSON types."""
        lo, hi = self.final
        return {
            "joint": self.joint,
            "force": self.force,
            "reached": self.reached,
            "angle": self.angle,
            "bracket": [lo, hi],
            "steps": len(self.trials) - 1,
            "trials": [[a, f] for a, f in self.trials],
            "converged": self.converged,
            "reason": self.reason,
            "unsettled": [[a, why] for a, why in self.unsettled.items()],
            "not_held": sorted(self.lost),
        }


def _next(d: Drive, target: Target) -> float:
    """The next angle of one joint from its trials (see the module docstring)."""
    lo, hi = d.bracket()
    settled = d.settled()
    pts = dict(settled)
    if d.failed and pts:
        # the last trial did not settle, and what settled is unchanged: go halfway back
        return 0.5 * (d.angle + _back(d))
    if lo is not None and hi is not None:
        if lo in d.lost:  # no force there to interpolate: the edge of holding, bisected
            return 0.5 * (lo + hi)
        flo, fhi = pts[lo] - target.force, pts[hi] - target.force
        # Illinois: halve the value kept at the end that did not move last time
        last = d.trials[-1][0]
        side = -1 if last == lo else 1
        if side == d._side:
            if side == -1:
                fhi *= 0.5
            else:
                flo *= 0.5
        d._side = side
        d._widths.append(hi - lo)
        if len(d._widths) >= 3 and d._widths[-1] > 0.5 * d._widths[-3]:
            return 0.5 * (lo + hi)  # two steps did not halve it (a force that jumps)
        a = lo - flo * (hi - lo) / (fhi - flo) if fhi != flo else 0.5 * (lo + hi)
        inner = 0.02 * (hi - lo)
        if not lo + inner <= a <= hi - inner:
            a = 0.5 * (lo + hi)
        return a
    guide = settled if len(settled) >= 2 else d.trials[d._start :]
    a1, f1 = guide[-1]
    if len(guide) == 1:
        a0 = d.trials[0][0]
        step = a1 - a0
        if step < ANGLE_RESOLUTION:  # at or below first contact (the body moved since it
            # was measured): no press to scale; as far again toward the force
            step = max(-step, ANGLE_RESOLUTION)
            return min(a1 - step if f1 > target.force else a1 + step, target.limit)
        # its press past first contact scaled as a Hertz contact's, F ~ d^(3/2)
        press = step * (target.force / f1) ** (2.0 / 3.0) if f1 > 0 else GROWTH * step
        return min(a0 + min(press, GROWTH * step), target.limit)
    a0, f0 = guide[-2]
    step = a1 - a0
    if hi is None:  # every settled force below the target: the secant, up (or back, where
        # trials that did not settle guide it and passed the force)
        slope = (f1 - f0) / step if step else 0.0
        grow = GROWTH * abs(step)
        want = (target.force - f1) / slope if slope > 0 else grow
        return min(a1 + min(max(want, -grow), grow), target.limit)
    # every force solved above it (the finger pressed already at first contact): step back
    # by the secant of the last two solves; where their forces differ by less than the
    # tolerance (flat: the body gives way, or holds only past an edge) the secant says
    # nothing, and the step back doubles
    if abs(f1 - f0) <= target.tolerance * target.force:
        return a1 - 2.0 * abs(step)
    first = abs(d.trials[1][0] - d.trials[0][0]) or 1.0
    slope = (f1 - f0) / step if step else 0.0
    back = (f1 - target.force) / slope if slope > 0 else GROWTH * abs(step)
    return a1 - min(max(back, 0.0), GROWTH * max(abs(step), first))


def drive(
    solve: Callable[[dict[str, float]], tuple[Any, Mapping[str, float], str]],
    touching: Mapping[str, float],
    pressed: Mapping[str, float],
    targets: Sequence[Target],
    max_steps: int = MAX_STEPS,
    lost: Callable[[Any], bool] | None = None,
) -> tuple[Any, dict[str, float], dict[str, Drive]]:
    """Close the force-driven joints until each finger's force is its target.

    Parameters
    ----------
    solve : callable
        ``solve(angles) -> (result, forces, why)``: the frame solved at ``angles`` (every
        joint), each force-driven joint's finger force (N), and why the frame did not
        settle ("" where it did).
    touching : mapping of str to float
        The pose with each force-driven joint at first contact (force 0, no solve).
    pressed : mapping of str to float
        The same with each one pressed :data:`FIRST_PRESS` past it: the first trial.
    targets : sequence of Target
    max_steps : int
        Solves before giving up.
    lost : callable, optional
        ``lost(result)``: the trial's free body is not held (below every force).

    Returns
    -------
    result
        The last solve's result (at the returned angles).
    angles : dict of str to float
        The pose of the last solve.
    drives : dict of str to Drive
        Each joint's trials and outcome.
    """
    if max_steps < 1:
        raise ValueError(f"max_steps = {max_steps} must be at least 1")
    drives = {t.joint: Drive(t.joint, t.force, [(float(touching[t.joint]), 0.0)]) for t in targets}
    last = {k: float(v) for k, v in pressed.items()}
    result, forces, why = solve(dict(last))
    solves, budget = 1, max_steps * len(targets)
    failures = 1 if why else 0
    gone = _note(drives, targets, last, forces, why, result, lost)
    done: set[str] = set()  # joints stopped short (a limit, a jump)
    ends: dict[str, float] = {}  # where a joint stopped ends: below a jump, an edge of holding
    while solves - failures < budget and failures < budget:
        off = [
            t for t in targets
            if t.joint not in done and (why or gone or not t.reached(forces[t.joint]))
        ]  # fmt: skip
        if not off:
            break
        for t in off:
            d = drives[t.joint]
            d.restart(last[t.joint], float(forces[t.joint]))
            if gone:
                d.lost.add(last[t.joint])
            while solves - failures < budget and failures < budget and (
                d.failed or not t.reached(d.reached)
            ):
                stuck, end = _stuck(d, t)
                if stuck:
                    d.reason = stuck
                    done.add(t.joint)
                    if end is not None:
                        ends[t.joint] = end
                    break
                angles = {**last, t.joint: _next(d, t)}
                again = _repeated(d, angles[t.joint])
                if again is not None:
                    d.reason = (
                        f"{t.joint}: the frames at {again:.6g} deg and within "
                        f"{ANGLE_RESOLUTION:g} deg of it did not settle (the solver's limit, "
                        f"not the finger's: {d.unsettled[again]})"
                    )
                    done.add(t.joint)
                    break
                result, forces, why = solve(dict(angles))
                solves += 1
                last = angles
                failures += bool(why)
                gone = _note({t.joint: d}, [t], last, forces, why, result, lost)
    if gone and not ends:  # the edge of holding not found: end where it held, nearest
        ends = {t.joint: a for t in targets if (a := drives[t.joint].bracket()[1]) is not None}
    if ends and any(last[j] != a for j, a in ends.items()):
        # solved again there, the run's history left as that trial's (below a jump: a grip
        # no firmer than the one asked, or not held where nothing below holds)
        last = {**last, **ends}
        result, forces, why = solve(dict(last))
        solves += 1
        _note(drives, targets, last, forces, why, result, lost)
    for t in targets:
        d = drives[t.joint]
        d.final = d.bracket()  # its last search's, before the frame's own force is added
        if (last[t.joint], float(forces[t.joint])) != d.trials[-1]:
            d.trials.append((last[t.joint], float(forces[t.joint])))
            if why:
                d.unsettled[last[t.joint]] = why
        d.converged = t.reached(d.reached) and not why
        if d.converged:
            d.reason = f"force reached in {solves} solve(s)"
        elif not d.reason and why:
            d.reason = f"{t.joint}: the last trial's frame did not settle ({why})"
        elif not d.reason:
            lo, hi = d.final
            d.reason = (
                f"{t.joint}: {d.reached:.4g} N of {t.force:.4g} N after {solves} solves "
                f"(angle between {lo if lo is not None else '-'} and "
                f"{hi if hi is not None else '-'} deg)"
            )
    return result, last, drives


def _note(
    drives: dict[str, Drive],
    targets: Sequence[Target],
    angles: Mapping[str, float],
    forces: Mapping[str, float],
    why: str,
    result: Any,
    lost: Callable[[Any], bool] | None,
) -> bool:
    """Add one solve, at ``angles``, to every joint's trials; whether its body was lost."""
    gone = not why and lost is not None and lost(result)
    for t in targets:
        d = drives[t.joint]
        d.trials.append((angles[t.joint], float(forces[t.joint])))
        if why:
            d.unsettled[angles[t.joint]] = why
        elif gone:
            d.lost.add(angles[t.joint])
    return gone


def _repeated(d: Drive, angle: float) -> float | None:
    """The current search's trial near ``angle`` that did not settle, or None.

    Near: within :data:`ANGLE_RESOLUTION`. A search guided by such trials alone could ask
    for the same angle again.
    """
    for a, _ in d.trials[d._start :]:
        if a in d.unsettled and abs(a - angle) < ANGLE_RESOLUTION:
            return a
    return None


def _back(d: Drive) -> float:
    """Where a search goes back to from a trial that did not settle: the bracket's low end.

    Else its high end: the settled trials below, else above, the force.
    """
    lo, hi = d.bracket()
    return lo if lo is not None else hi  # type: ignore[return-value]


def _stuck(d: Drive, t: Target) -> tuple[str, float | None]:
    """Why a joint's search cannot go on ("" where it can), and where its frame then ends.

    A limit reached short, a force that jumps, the edge of holding found, or a frame that
    does not settle within :data:`ANGLE_RESOLUTION` of the last that did, toward the force.
    Below a jump or the edge of holding the frame ends at the bracket's low end.
    """
    lo, hi = d.bracket()
    if d.failed and d.settled() and abs(d.angle - _back(d)) < ANGLE_RESOLUTION:
        a = _back(d)
        return (
            f"{t.joint}: the frames next to {a:.6g} deg ({dict(d.settled())[a]:.4g} N of "
            f"{t.force:.4g} N) did not settle (the solver's limit, not the finger's: "
            f"{d.unsettled[d.angle]})"
        ), None
    if lo is not None and hi is not None:
        f = dict(d.settled())
        if lo in d.lost:
            least = _least_held(d, lo, hi)
            if hi - lo < ANGLE_RESOLUTION or least > t.force * (1 + t.tolerance):
                between = f", at least {least:.4g} N where it holds between" if least > 0 else ""
                return (
                    f"{t.joint}: not held at {lo:.6g} deg, held at {hi:.6g} deg with "
                    f"{f[hi]:.4g} N on its finger{between}: no angle holds with {t.force:.4g} N"
                ), lo
        elif hi - lo < ANGLE_RESOLUTION:
            return (
                f"{t.joint}: its finger's force jumps from {f[lo]:.4g} N to {f[hi]:.4g} N at "
                f"{lo:.6g} deg (a node entering the contact, or its stick and slip changing): "
                f"no angle gives {t.force:.4g} N within {100 * t.tolerance:g} %"
            ), lo
    if d.angle >= t.limit and d.reached < t.force:
        return (
            f"{t.joint} reached its limit {t.limit:g} deg with {d.reached:.4g} N of "
            f"{t.force:.4g} N on its finger"
        ), None
    return "", None


def _least_held(d: Drive, lo: float, hi: float) -> float:
    """The least force the finger can hold with between ``lo`` (not held) and ``hi``.

    The force is convex and growing in the angle where the body is held, so it lies above
    its secant through ``hi`` and the next angle that held, extended down to ``lo``
    (no bound, -inf, where no other angle held).
    """
    held = sorted((a, f) for a, f in d.settled() if a >= hi and a not in d.lost)
    if len(held) < 2:
        return -np.inf
    (a1, f1), (a2, f2) = held[:2]
    return f1 - max((f2 - f1) / (a2 - a1), 0.0) * (hi - lo)
