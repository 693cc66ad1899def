"""Force-driven fingers' targets, forces and first trials.

The pieces :func:`contact.holding.fingerforce.drive` is given by a run: which joints are
force-driven (:func:`force_targets`), each finger's force from a frame's contact fields
(:func:`finger_forces`), and where a frame solved again starts (:func:`guess` from what
:func:`remember` kept of its last search).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .fingerforce import Drive, Target

__all__ = ["Memory", "finger_forces", "force_targets", "guess", "remember"]


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
    (``F ~ d^{3/2}``) to the new force (at that angle where it ended at or below first
    contact: the body had moved since); the others as ``pressed``.
    """
    out = dict(pressed)
    for tg in targets:
        last = memory.get((t, tg.joint))
        if last is None or last[2] <= 0:
            continue
        a0, a, f = last
        if a <= a0:  # it ended at or below first contact (the body had moved): start there
            out[tg.joint] = min(a, tg.limit)
            continue
        press = (a - a0) * (tg.force / f) ** (2.0 / 3.0)
        out[tg.joint] = min(touching[tg.joint] + press, tg.limit)
    return out


def remember(
    memory: Memory, t: float, touching: Mapping[str, float], drives: Mapping[str, Drive]
) -> None:
    """Keep each joint's first contact, angle found and force for the frame's next search."""
    for j, d in drives.items():
        memory[(t, j)] = (float(touching[j]), d.angle, d.reached)


def force_targets(
    hand: Any, flexions: Sequence[Any], pressed: Mapping[str, float], parts: Callable
) -> list[Target]:
    """The force-driven flexions among ``flexions`` (:class:`contact.scene.model.AutoFlex`).

    Those whose joint reached first contact (``pressed``); each with its joint's upper
    limit and the hand part of its point (``parts()``: the part of every flesh node).
    """
    out = []
    limits = hand.skeleton.limits
    for af in flexions:
        if af.force is None or af.joint not in pressed:
            continue
        if isinstance(af.point, str):
            part = hand.part_names.index(af.point)
        else:
            part = int(parts()[af.point])
        lim = limits[af.joint][1]
        out.append(Target(af.joint, float(af.force), af.force_tolerance, lim, part))
    return out
