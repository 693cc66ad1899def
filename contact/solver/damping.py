"""The damping of free finite bodies' Newton steps: springs in their modes, a trust region.

A free body is placed by its contacts alone. Where they hardly hold one of its motions (a
ball pinched at two points swings about the line through them), its linearised step
takes it far past where the linearisation holds, or the friction solve cannot settle;
where they cannot hold it where it is (a pinched ball whose weight turns it to hang below
the pinch), the step has no balance to go to. Levenberg and Marquardt's remedy: springs
on the body's rigid modes (``prox`` of :class:`~contact.solver.delassus.ContactSpace`, in
the contacts' stiffness seen there) carry what the contacts do not, the body moves toward
its balance by a step of their size, and they vanish with the step: the balance a
converged frame finds is exact.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["FIRST", "FOLLOW", "IDLE", "LEAST", "MOST", "PROGRESS", "REACH", "Damping"]

#: The springs' first, largest and least stiffness, in the contacts' seen in the modes.
FIRST, MOST, LEAST = 1e-2, 1.0, 1e-5
#: A step's rigid motion the damping aims at (rad, or a move over the body's half size):
#: one that goes past twice this is solved again, damped in proportion.
REACH = 0.1
#: Damped steps that may follow a body its contacts do not hold where it is, and the
#: fraction by which each must lessen the share of its loads they leave.
FOLLOW, PROGRESS = 12, 1e-3
#: Damped steps in a row that leave the residual above its least before an undamped one.
IDLE = 3


@dataclass
class Damping:
    """The springs of one frame's Newton steps, and what they have seen.

    Attributes
    ----------
    prox : float
        The springs' stiffness for the next solve (0: none).
    verdict : tuple or None
        The last undamped linear frame that found a free body not held, and the
        displacements it was solved at: the frame's verdict where following the body
        finds no balance.
    """

    prox: float = 0.0
    verdict: tuple[Any, dict] | None = None
    _tried: float = np.inf  # the motion of this step's last try
    _share: tuple[float, bool] | None = None  # the last share not carried, and a turn
    _follows: int = 0
    _following: bool = False
    _least: float = np.inf  # the least residual after a step
    _idle: int = 0  # damped steps in a row that left the residual above its least

    def springs(self, names: list[str]) -> dict[str, float] | None:
        """The springs on the bodies ``names`` for the next solve (None: none)."""
        return {n: self.prox for n in names} if self.prox else None

    def unsettled(self) -> bool:
        """A step whose friction did not settle: again, damped tenfold more (False: no more)."""
        if self.prox >= MOST:
            return False
        self.prox = FIRST if not self.prox else min(10.0 * self.prox, MOST)
        return True

    def too_far(self, motion: float) -> bool:
        """A step whose rigid motion is past twice :data:`REACH`: again, damped (True).

        Damped in proportion to the motion, while that shortens it by half at least (a
        motion the contacts drive, a ball rolled by a plate, no spring shortens).
        """
        if not 2 * REACH < motion < 0.5 * self._tried or self.prox >= MOST:
            self._tried = np.inf
            return False
        self._tried = motion
        self.prox = min(max(self.prox, FIRST) * motion / REACH, MOST)
        return True

    def unheld(self, result: Any, u: dict) -> bool:
        """A linear frame that found a body not held: follow it, damped (True), or stop.

        The body may turn or slide to where its contacts hold it (a ball that swings to
        hang below a pinch). It is followed while the share of its loads its contacts
        leave, ``not_carried / (not_carried + available)``, falls by :data:`PROGRESS` from
        one undamped linear frame to the next (or a force left becomes a moment: it
        need only turn), at most :data:`FOLLOW` times; a load that no motion brings into
        balance (a ball between parallel pads, a twist) stops it at once. A damped solve
        that found it not held was damped too little: again, damped tenfold more.
        """
        if self.prox:
            return self.unsettled()
        self.verdict = (result, dict(u))
        slip = result.slip or {}  # none: it touches nothing, all its load is left
        c, f = float(slip.get("available", 0.0)), float(slip.get("not_carried", 1.0))
        share = (f / (c + f) if c + f > 0 else 1.0, bool(slip.get("turns", False)))
        last = self._share
        if self._follows >= FOLLOW or not (
            last is None or share[1] != last[1] or share[0] < (1 - PROGRESS) * last[0]
        ):
            return False
        self._share, self._follows, self._following = share, self._follows + 1, True
        self.prox = FIRST
        return True

    def taken(self, motion: float, residual: float) -> float:
        """A step taken, its rigid motion and the residual after it: its springs; the next's.

        After a step that followed a body not held, none (the next solve says whether its
        contacts hold it now); so too after :data:`IDLE` damped steps in a row that left
        the residual above its least (the springs carry a load the contacts may never
        take: a ball that slides out of a pinch). Else scaled by the motion over
        :data:`REACH` (down to a tenth), none below :data:`LEAST`.
        """
        damp = self.prox
        self._idle = self._idle + 1 if damp and residual >= self._least else 0
        self._least = min(self._least, residual)
        if self._following or self._idle >= IDLE:
            self.prox, self._following, self._idle = 0.0, False, 0
        else:
            self.prox *= min(max(motion / REACH, 0.1), 1.0)
            if self.prox < LEAST:
                self.prox = 0.0
        return damp
