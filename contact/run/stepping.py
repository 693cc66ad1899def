"""A frame's steps of time: friction's substeps, and a finite frame's cut-backs.

Quasi-static friction is path dependent: with ``solver.substeps = n > 1`` the steps of
time between the last frame solved and the next are solved first, each carrying its
anchors to the next. A frame with a neo-Hookean body whose Newton does not converge
(where no free body fell) is solved again from the last frame's state with its step of
time cut in 2, then 4 (:data:`MAX_CUTS`): a smaller increment of the pose and the loads,
as a finite-strain code cuts back its time step.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

__all__ = ["MAX_CUTS", "solve_stepped"]

log = logging.getLogger(__name__)

#: A finite frame Newton does not solve is solved again with its step of time cut in
#: two, then four... up to this many parts.
MAX_CUTS = 4


def solve_stepped(run: Any, t: float, callback: Callable | None) -> tuple:
    """``run``'s frame at ``t`` (:meth:`contact.run.GraspRun.frame`), by steps of time."""
    n = run.scene.solver.substeps
    last = run.last_time
    kept = run.history()
    out = _stepped(run, t, last, n, callback)
    cuts = 1
    while _cut(out) and cuts < MAX_CUTS and last is not None and t > last:
        cuts *= 2
        log.info("t = %g: Newton did not converge; solved again in %d steps", t, n * cuts)
        run.restore(kept)
        out = _stepped(run, t, last, n * cuts, callback)
    return out


def _stepped(run: Any, t: float, last: float | None, n: int, callback: Callable | None):
    """The frame at ``t``, after ``n - 1`` steps of time from ``last`` where they apply.

    Friction's history, or a finite body's Newton, asks for the steps.
    """
    if n > 1 and last is not None and t > last and (run.scene.frictional or run.finite):
        for i in range(1, n):
            run.frame_time = t  # the automatic flexions of the frame the step leads to
            run.solve_at(last + (t - last) * i / n, None)
    run.frame_time = None
    run.last_time = t
    return run.solve_at(t, callback)


def _cut(out: tuple) -> bool:
    """A finite frame whose Newton did not converge, where no free body fell."""
    newton = out[1].get("newton")
    return newton is not None and not newton["converged"] and out[0].held is not False
