"""Force-driven fingers: a joint closes until its finger's normal contact force is given.

``[[hand.auto_flexion]] force = N`` asks for the flexion of one joint at which the total
normal contact force on its finger is ``N``. Force grows with the flexion past first
contact (the finger presses deeper), so each joint's angle is a 1-D root of
``F(alpha) - N``; every trial is a contact solve of the whole frame, all force-driven
joints moved at once (each by its own search: a finger's force depends mostly on its own
angle; where two fingers squeeze one free ball, any placement of the ball between them
that gives both their forces is a root).

Each joint starts from two angles the geometry gives without a solve: first contact
(force 0, a guess: the ball may have moved since it was measured) and a press of
:data:`FIRST_PRESS` past it. After that first solve, the press is scaled as a Hertz
contact's (``F ~ d^{3/2}``) to the target; then, per joint, the secant through its last
two trials while its force is below the target (the force is convex in the
press, so the secant overshoots and brackets the root), limited to :data:`GROWTH` times
the last step, and the Illinois variant of regula falsi once the root is bracketed, with
a bisection where that would not shrink the bracket. A joint is done when its force is
within its ``force_tolerance`` of the target; the search stops after :data:`MAX_STEPS`
solves, or where a joint reaches its limit short of the force.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "ANGLE_RESOLUTION", "FIRST_PRESS", "GROWTH", "MAX_STEPS", "Drive", "Target", "drive",
    "finger_forces", "guess", "remember",
]  # fmt: skip

#: The first trial presses each force-driven finger this far (m) past first contact.
FIRST_PRESS = 5e-4
#: Contact solves a frame's force-driven fingers may take.
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
        The last trial's force is within the tolerance.
    reason : str
        Why it stopped.
    """

    joint: str
    force: float
    trials: list[tuple[float, float]] = field(default_factory=list)
    converged: bool = False
    reason: str = ""
    _side: int = 0  # Illinois: which end of the bracket was kept last, -1 low, +1 high
    _widths: list[float] = field(default_factory=list)  # the bracket's, step by step

    @property
    def angle(self) -> float:
        """The last angle tried (the frame's)."""
        return self.trials[-1][0]

    @property
    def reached(self) -> float:
        """The force at the last angle (N)."""
        return self.trials[-1][1]

    def bracket(self) -> tuple[float | None, float | None]:
        """The largest angle solved whose force is below the target and the least above it.

        The first contact's force, 0, is a guess of the geometry (the ball may have moved
        since it was measured), never an end of the bracket.
        """
        below = [a for a, f in self.trials[1:] if f < self.force]
        above = [a for a, f in self.trials[1:] if f >= self.force]
        return (max(below) if below else None, min(above) if above else None)

    def record(self) -> dict[str, Any]:
        """As plain JSON types."""
        lo, hi = self.bracket()
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
        }


def _next(d: Drive, target: Target) -> float:
    """The next angle of one joint from its trials (see the module docstring)."""
    lo, hi = d.bracket()
    pts = {a: f for a, f in d.trials}
    if lo is not None and hi is not None:
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
    (a0, f0), (a1, f1) = d.trials[-2], d.trials[-1]
    step = a1 - a0
    if len(d.trials) == 2 and f1 > 0:
        # one solve: its press past first contact scaled as a Hertz contact's, F ~ d^(3/2)
        press = step * (target.force / f1) ** (2.0 / 3.0)
        return min(a0 + min(press, GROWTH * abs(step)), target.limit)
    if hi is None:  # every force below the target: extrapolate upwards
        slope = (f1 - f0) / step if step else 0.0
        grow = GROWTH * abs(step)
        want = (target.force - f1) / slope if slope > 0 else grow
        return min(a1 + min(max(want, 0.0), grow), target.limit)
    # every force solved above it (the finger pressed already at first contact): step back
    # by the secant of the last two solves
    first = abs(d.trials[1][0] - d.trials[0][0]) or 1.0
    slope = (f1 - f0) / step if step else 0.0
    back = (f1 - target.force) / slope if slope > 0 else GROWTH * abs(step)
    return a1 - min(max(back, 0.0), GROWTH * max(abs(step), first))


def drive(
    solve: Callable[[dict[str, float]], tuple[Any, Mapping[str, float]]],
    touching: Mapping[str, float],
    pressed: Mapping[str, float],
    targets: Sequence[Target],
    max_steps: int = MAX_STEPS,
) -> tuple[Any, dict[str, float], dict[str, Drive]]:
    """Close the force-driven joints until each finger's force is its target.

    Parameters
    ----------
    solve : callable
        ``solve(angles) -> (result, forces)``: the frame solved at ``angles`` (every joint)
        and each force-driven joint's finger force (N).
    touching : mapping of str to float
        The pose with each force-driven joint at first contact (force 0, no solve).
    pressed : mapping of str to float
        The same with each one pressed :data:`FIRST_PRESS` past it: the first trial.
    targets : sequence of Target
    max_steps : int
        Solves before giving up.

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
    angles = {k: float(v) for k, v in pressed.items()}
    result, last = None, dict(angles)
    for step in range(1, max_steps + 1):
        last = dict(angles)
        result, forces = solve(dict(last))
        for t in targets:
            drives[t.joint].trials.append((angles[t.joint], float(forces[t.joint])))
        if all(t.reached(drives[t.joint].reached) for t in targets):
            for d in drives.values():
                d.converged, d.reason = True, f"force reached in {step} solve(s)"
            break
        stuck = False
        for t in targets:
            d = drives[t.joint]
            if t.reached(d.reached):
                continue
            lo, hi = d.bracket()
            if lo is not None and hi is not None and hi - lo < ANGLE_RESOLUTION:
                f = dict(d.trials[1:])
                d.reason = (
                    f"{t.joint}: its finger's force jumps from {f[lo]:.4g} N to {f[hi]:.4g} N "
                    f"at {lo:.6g} deg (a node entering the contact): no angle gives "
                    f"{t.force:.4g} N within {100 * t.tolerance:g} %"
                )
                stuck = True
                continue
            a = _next(d, t)
            if a >= t.limit and d.angle >= t.limit and d.reached < t.force:
                d.reason = (
                    f"{t.joint} reached its limit {t.limit:g} deg with {d.reached:.4g} N "
                    f"of {t.force:.4g} N on its finger"
                )
                stuck = True
            angles[t.joint] = a
        if stuck:
            break
    for t in targets:
        d = drives[t.joint]
        d.converged = t.reached(d.reached)
        if not d.converged and not d.reason:
            lo, hi = d.bracket()
            d.reason = (
                f"{t.joint}: {d.reached:.4g} N of {t.force:.4g} N after {len(d.trials) - 1} "
                f"solves (angle between {lo if lo is not None else '-'} and "
                f"{hi if hi is not None else '-'} deg)"
            )
    return result, last, drives


def finger_forces(
    fields: Mapping[str, NDArray] | None, parts: NDArray[np.int64], targets: Sequence[Target]
) -> dict[str, float]:
    """Each target's finger: the sum of the hand's nodal normal contact forces on its part (N).

    ``fields`` are the hand's contact fields (:attr:`FrameResult.contact_fields`), None
    where it touches nothing; ``parts`` the hand part of every flesh node.
    """
    fn = np.zeros(parts.size) if fields is None else np.asarray(fields["normal_force"])
    return {t.joint: float(fn[parts == t.part].sum()) for t in targets}


#: What a run remembers of a frame's force-driven joints: (frame time, joint) ->
#: (first contact's angle, the angle found, its force).
Memory = dict[tuple[float, str], tuple[float, float, float]]


def guess(
    memory: Memory, t: float, touching: Mapping[str, float], pressed: Mapping[str, float],
    targets: Sequence[Target],
) -> dict[str, float]:
    """The first trial's angles: where this frame's search ended last time, where it did.

    A run that solves the frame again with other forces (``--least-grip``) starts each
    joint at its last angle, its press past first contact scaled as a Hertz contact's
    (``F ~ d^{3/2}``) to the new force; the others at :data:`FIRST_PRESS` (``pressed``).
    """
    out = dict(pressed)
    for tg in targets:
        last = memory.get((t, tg.joint))
        if last is None or last[2] <= 0:
            continue
        a0, a, f = last
        press = max(a - a0, 0.0) * (tg.force / f) ** (2.0 / 3.0)
        out[tg.joint] = min(touching[tg.joint] + press, tg.limit)
    return out


def remember(
    memory: Memory, t: float, touching: Mapping[str, float], drives: Mapping[str, Drive]
) -> None:
    """Keep each joint's first contact, angle found and force for the frame's next search."""
    for j, d in drives.items():
        memory[(t, j)] = (float(touching[j]), d.angle, d.reached)
