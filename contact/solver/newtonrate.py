"""How Newton's steps of a finite frame go: their rate, their mixing, contacts that flip.

Bookkeeping across the steps of :func:`contact.solver.finite.solve_finite_frame`: a free
body's full-tangent steps that shrink only at a linear rate (:func:`linear_rate`), steps
too slow for Newton's own (:func:`slow`) that Anderson mixing takes up (:func:`anderson`),
a contact set that flips from step to step (:class:`Flips`), and the error a step leaves,
from its rate (:class:`StepErrors`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "ANDERSON",
    "ANDERSON_FROM",
    "CONTRACTS",
    "FAST",
    "SLOW_FULL",
    "Flips",
    "StepErrors",
    "anderson",
    "linear_rate",
    "slow",
]

#: From this Newton step on, where the steps shrink slowly (:data:`FAST`), a free body's
#: placement is Anderson-mixed from its last :data:`ANDERSON` steps: the material
#: tangent converges linearly, and the mixing takes up the rate it leaves.
ANDERSON_FROM = 4
ANDERSON = 3
#: Steps that shrink by more than this ratio are Newton's own: they are left whole.
FAST = 0.05
#: A free body whose full-tangent steps shrink by less than this ratio from its third
#: step on takes the material tangent for the rest of the frame (:func:`linear_rate`).
SLOW_FULL = 0.3
#: Two consecutive steps whose ratio is at most this contract: the error left after the
#: second is estimated from their rate (:class:`StepErrors`).
CONTRACTS = 0.5


class StepErrors:
    """The error a body's Newton step leaves, estimated from the rate of its last two.

    Where two consecutive plain steps (neither damped, mixed nor shortened, closing the
    same contacts) shrink by a ratio ``rho <= CONTRACTS``, the steps still to come sum to
    about ``rho / (1 - rho)`` of the last one (a geometric series; far less at Newton's
    quadratic rate): that is the error left, where the last step alone would call for one
    more step to show it small. Otherwise the last step itself is taken.
    """

    def __init__(self) -> None:
        self.last: dict[str, tuple[int, float] | None] = {}

    def left(self, name: str, step: int, move: float, plain: bool) -> float:
        """Body ``name``'s error left after Newton step ``step`` of size ``move``."""
        before = self.last.get(name)
        self.last[name] = (step, move) if plain else None
        if not plain or before is None or before[0] != step - 1 or not before[1] > 0.0:
            return move
        rho = move / before[1]
        return move * rho / (1.0 - rho) if rho <= CONTRACTS else move


class Flips:
    """Whether a contact has flipped: closed by one step, open in the steps on either side.

    A frictionless linear frame searches its contacts from rest; a contact at the edge
    of the penetration tolerance may then be taken by one step and not by the next, for
    ever. Once one flips, the steps search from where the last one left the bodies.
    """

    def __init__(self) -> None:
        self.seen: list[set[tuple[str, int]]] = []
        self.flipped = False

    def add(self, contacts: Mapping[str, NDArray]) -> bool:
        """Record a step's closed contacts (``pair``, ``node``); True once one has flipped."""
        pairs, nodes = contacts.get("pair", ()), contacts.get("node", ())
        self.seen.append({(str(p), int(n)) for p, n in zip(pairs, nodes, strict=True)})
        if len(self.seen) >= 3:
            a, b, c = self.seen[-3:]
            self.flipped |= bool((b - a) & (b - c) or (a & c) - b)
        return self.flipped

    @property
    def steady(self) -> bool:
        """The last two steps closed the same contacts."""
        return len(self.seen) >= 2 and self.seen[-1] == self.seen[-2]


def linear_rate(moves: list[float]) -> bool:
    """A free body's full-tangent steps shrink at a linear rate, not Newton's.

    The free-body solve borders the full tangent with its turn stiffness
    (:class:`fem.TurningInverse`), so its steps converge quadratically where the linear
    frames are Newton's; where they still shrink by a constant ratio (a frictionless
    body, whose turns the frames hold), the material tangent, with Anderson mixing, does
    better.
    """
    return len(moves) >= 3 and moves[-1] > SLOW_FULL * moves[-2]


def slow(history) -> bool:
    """The last two steps shrink by less than :data:`FAST`: linear, not Newton's, rate."""
    if len(history) < 2:
        return False
    a, b = (float(np.linalg.norm(h[1])) for h in history[-2:])
    return b > FAST * a


def anderson(history, u, steps, names, depth: int = ANDERSON):
    """Anderson-mixed placements of the free bodies ``names`` from their last steps.

    ``history`` keeps the last ``depth + 1`` placements and steps (appended here); the
    mix is the type-II update of the fixed point ``u -> u + du``.
    """
    if not names:
        history.clear()  # a mix spans consecutive steps of the same bodies only
        return {}
    x = np.concatenate([u[n] for n in names])
    f = np.concatenate([steps[n] for n in names])
    if history and history[-1][0].size != x.size:
        history.clear()
    history.append((x.copy(), f.copy()))
    del history[:-(depth + 1)]
    new = x + f
    if len(history) > 1:
        dx = np.column_stack([history[i + 1][0] - history[i][0] for i in range(len(history) - 1)])
        df = np.column_stack([history[i + 1][1] - history[i][1] for i in range(len(history) - 1)])
        gamma = np.linalg.lstsq(df, f, rcond=None)[0]
        new = new - (dx + df) @ gamma
    out, k = {}, 0
    for n in names:
        m = u[n].size
        out[n] = new[k : k + m]
        k += m
    return out
