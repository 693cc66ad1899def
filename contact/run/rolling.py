"""A free ball that rolls: its rigid turn taken into its placement.

The contact solve is linear: a free body's rigid rotation is the infinitesimal one,
``u = t + omega x r``, which moves a point along the tangent of its circle and so
stretches the body by about ``|omega|^2 / 2``: a ball rolled 11 degrees between two
fingertips grows by 2 % of its radius at the contacts, as much as it is pressed. So, as
a co-rotational method does, a free ball that turned past :data:`ROLL` in a frame is
placed anew, turned by the finite rotation of ``omega`` (Rodrigues) and moved by ``t``,
and the frame is solved again from there (the history re-expressed from the new
placement, :meth:`contact.solver.anchors.Anchors.displaced`): the ball's stiffness is
the same, turned, and what the solve is left with is the small rest of the turn.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

import numpy as np

import fem
from fem import turned_placement

from ..solver.anchors import Anchors

__all__ = ["MAX_ROLLS", "ROLL", "solve_rolled", "turned_placement"]

log = logging.getLogger(__name__)

#: A free ball's rigid turn (rad) in a frame past which it is placed anew and the frame
#: solved again: half the largest turn the linear model is trusted with
#: (:data:`contact.solver.held.MAX_TURN`).
ROLL = 0.05
#: Solves of a frame again after a placement anew.
MAX_ROLLS = 3


def solve_rolled(run: Any, t: float, angles: dict[str, float], callback: Callable | None):
    """``run``'s frame at ``t`` with the hand at ``angles``, its rolled objects placed anew.

    ``run``: a :class:`contact.run.GraspRun` (not imported: it imports this module).

    A free linear object that turns past :data:`ROLL` is placed anew (``run.placed_anew``),
    turned and moved by its rigid motion, and the frame solved again from the same
    history; the placement that left the least turn is kept, with its history.
    """
    before = (run.anchors, dict(run.positions))
    out = run.solve_placed(t, angles, callback)
    free = [o.name for o in run.objects if o.rolls]
    best: tuple[float, tuple, dict] | None = None
    for _ in range(MAX_ROLLS if free else 0):
        result, bodies = out[0], {b.name: b for b in out[3]}
        stop = result.stop_reason
        settled = result.converged or any(stop.startswith(f"{n} turned") for n in free)
        if not settled:
            break  # an object not held is where a soft spring left it: no placement
        rigid = {n: fem.rigid_part(bodies[n].mesh.points, result.displacement[n]) for n in free}
        turns = {n: float(np.linalg.norm(omega)) for n, (_, omega) in rigid.items()}
        turn = max(turns.values())
        if best is not None and turn > 0.5 * best[0]:
            break  # placed anew, it turns about as much again (a pivot friction hardly holds)
        best = (turn, out, dict(run.placed_anew))
        if turn <= ROLL:
            break
        for n in free:
            if turns[n] > ROLL:
                log.info(
                    "t = %g: %s turned %.3g deg: placed anew and solved again",
                    t, n, np.degrees(turns[n]),
                )  # fmt: skip
                move, omega = rigid[n]
                turn_n = turned_placement(bodies[n].mesh.points, move, omega)
                run.placed_anew[n] = turn_n @ run.placed_anew.get(n, np.eye(4))
        # the same history: the frame starts where the objects were (at rest, first frame)
        start = before[0] or Anchors(
            displacement={n: np.zeros_like(bodies[n].mesh.points) for n in free},
            reference={n: bodies[n].mesh.points.copy() for n in free},
        )
        run.anchors, run.positions = start, dict(before[1])
        out = run.solve_placed(t, angles, callback)
    if best is not None and best[1] is not out:
        # the placement that left the least turn: its state is the history carried on
        out, run.placed_anew = best[1], best[2]
        run.anchors = out[0].anchors  # type: ignore[assignment]
        run.positions.update(
            {p.name: out[0].plane_positions[p.name] for p in run.scene.planes if p.driven}
        )
    return out
