"""The end of a frictional frame: its friction state, and why a free body is not held."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from . import held
from .delassus import SPRING, ContactSpace
from .fields import FrictionState
from .friction import FRICTION_TOLERANCE, SLIP, STICK, FrictionResult, solve_friction
from .results import FrictionReport
from .rows import ContactRows
from .tangential import Friction, tangent_basis

__all__ = ["Slip", "friction_state", "unheld"]

#: A free body is not held where a soft spring in its rigid modes must carry more than
#: this fraction of its loads or of its friction (held, it carries about the spring's
#: stiffness over the contacts').
UNBALANCED = 1e-3
#: The springs :func:`unheld` holds a free body by, stiff to soft, in the contacts'
#: stiffness seen in its modes (a stiff one's solve settles where a soft one's may not).
SPRINGS = (1e-1, 1e-2, 1e-3, 1e-4, SPRING)
#: A spring's share of the loads that falls by less than this factor when the spring
#: softens tenfold is a load the contacts do not carry (held, it falls tenfold too).
PERSISTS = 0.5


def friction_state(
    friction: Friction,
    rows: ContactRows,
    res: FrictionResult,
    tangent: NDArray[np.int64],
    keep: NDArray[np.bool_],
) -> FrictionState:
    """The closed contacts' friction after the frame's last solve of ``rows``."""
    k = len(rows)
    lam_n = res.lam[:k]
    forces = friction.tangential_forces(rows, res.lam, tangent)
    has = tangent[:, 0] >= 0
    mu = np.where(has, friction.mu[rows.pair] if k else 0.0, 0.0)
    size = np.linalg.norm(forces, axis=1)
    cone = np.zeros(k)
    on = has & (lam_n > 0)
    cone[on] = size[on] / (mu[on] * lam_n[on])
    slip = np.zeros(k)
    slip[has] = np.linalg.norm(res.y[tangent[has]], axis=1)
    closed_rows = rows.select(keep)
    full, tangent_c, _ = friction.rows(closed_rows)
    lam_c = np.zeros(len(full))
    lam_c[: len(closed_rows)] = lam_n[keep]
    kept_forces = forces[keep]
    hc = np.flatnonzero(tangent_c[:, 0] >= 0)
    if hc.size:
        t1, t2 = tangent_basis(closed_rows.normal[hc])
        f = kept_forces[hc]
        lam_c[tangent_c[hc, 0]] = np.einsum("ij,ij->i", f, t1)
        lam_c[tangent_c[hc, 1]] = np.einsum("ij,ij->i", f, t2)
    status = res.status[keep]
    frictional = has[keep]
    pairs = friction.frame.pairs
    per_pair: dict[str, NDArray[np.float64]] = {}
    for i, pair in enumerate(pairs):
        if pair.friction <= 0:
            continue
        sel = closed_rows.pair == i
        total = kept_forces[sel].sum(axis=0)
        per_pair[pair.name] = total
        if pair.rigid:
            name = pair.master.name
            per_pair[name] = per_pair.get(name, np.zeros(3)) - total
    report = FrictionReport(
        iterations=friction.iterations,
        residual=float(res.residual),
        tolerance=FRICTION_TOLERANCE,
        stick=int(((status == STICK) & frictional).sum()),
        slip=int(((status == SLIP) & frictional).sum()),
        max_slip=float(slip[keep][frictional].max(initial=0.0)),
        max_cone_use=float(cone[keep].max(initial=0.0)),
        tangential_force=per_pair,
    )
    return FrictionState(
        rows=full,
        lam=lam_c,
        tangential=kept_forces,
        status=status,
        cone_use=cone[keep],
        slip=slip[keep],
        report=report,
        pair_mu=friction.mu.copy(),
    )


@dataclass(frozen=True)
class Slip:
    """A free body that friction does not hold: which way it slips and by how much load.

    Attributes
    ----------
    body : str
        The body.
    direction : ndarray, shape (3,)
        The unit direction of the load its contacts leave: the way it slips.
    not_carried : float
        That load (N), or moment (N m) where it turns.
    available : float
        The friction its contacts had against that motion: ``sum mu N`` (N), or where it
        turns ``sum mu N r`` (N m, ``r`` each contact's distance from the axis).
    turns : bool
        Only a moment is left: the body turns about ``direction``.
    """

    body: str
    direction: NDArray[np.float64]
    not_carried: float
    available: float
    turns: bool = False

    @property
    def reason(self) -> str:
        """The frame's stop reason, ``"not held: <body> slips along (...): ..."``.

        Or ``"not held: <body> turns about (...): ..."`` where the moment of its loads is
        what its contacts do not carry (``not_carried`` in N m, ``direction`` the axis).
        """
        way = held.way(self.direction)
        if self.turns:
            return (
                f"not held: {self.body} turns about {way}: {self.not_carried:.4g} N m of the "
                "moment of its loads is not carried by its contacts (friction's moment "
                f"available sum mu N r = {self.available:.4g} N m)"
            )
        return (
            f"not held: {self.body} slips along {way}: {self.not_carried:.4g} N of its load "
            f"is not carried by its contacts (friction available sum mu N = "
            f"{self.available:.4g} N)"
        )

    def record(self) -> dict:
        """As plain JSON types (``not_carried`` and ``available`` in N m where it turns)."""
        return {
            "body": self.body,
            "direction": [float(x) for x in self.direction],
            "not_carried": float(self.not_carried),
            "available": float(self.available),
            "turns": bool(self.turns),
        }


def unheld(frame, space: ContactSpace, friction: Friction, rows: ContactRows) -> Slip | None:
    """The slip of a free body the last solve found no balance for, else None.

    Called when the frictional solve did not settle. The same contacts are solved with
    each free body held by a spring in its rigid modes, softer in turn (:data:`SPRINGS`,
    down to ``SPRING`` of :mod:`contact.solver.delassus`), each a problem that has a
    solution: where the body is held the spring's share of its load falls with the
    spring's stiffness, where it is not the spring keeps carrying the load the contacts
    cannot. So the body slips where that share stays (:data:`PERSISTS`) from one spring
    to the next, or is still there at the softest; the load reported is the softest
    solved spring's share (it falls to the load not carried as the spring softens). The
    message names the body, that load (N) and the way it slips, or the moment (N m) and
    the axis it turns about where only a moment is left, and the friction available (the
    sum of ``mu N`` over its contacts). None where the springs' solves say neither.
    """
    sys_, mu, tangent = friction.system
    g, c, h = sys_.g, sys_.c, sys_.h
    if not g.shape[1]:
        return None
    if h is not None and sys_.aux is not None:
        # the springs hold the modes, their own stiffness left out (negative where a
        # squeezed body's forces drive its turn, it would undo a soft spring); a
        # border's auxiliaries keep their exact equations
        h = np.where(np.outer(sys_.aux, sys_.aux), h, 0.0)
    levels: list[tuple[float, FrictionResult, Slip]] = []
    for spring in SPRINGS:
        res = solve_friction(
            sys_.w, g, sys_.rhs, c, mu=mu, tangent=tangent, load_scale=sys_.load_scale,
            spring=spring, start=levels[-1][1].lam if levels else None, h=h, aux=sys_.aux,
        )
        if not res.solved:
            continue  # a softer one may settle
        carried = g.T @ res.lam - c - (h @ res.a if h is not None else 0.0)
        slip = _worst_slip(frame, space, rows, res, carried)  # the springs' load
        if slip is None:
            return None  # the contacts carry all but a spring's share: held
        levels.append((spring, res, slip))
    if len(levels) < 2:
        return None  # no two answers to tell a slip from a spring's share
    (_, _, before), (softest, _, now) = levels[-2:]
    if softest > SPRINGS[-1] and now.not_carried <= PERSISTS * before.not_carried:
        return None  # falling with the spring, the softer ones unsolved: undecided
    return now  # the softest spring's share: the load the contacts leave, from above


def _worst_slip(
    frame, space: ContactSpace, rows: ContactRows, res: FrictionResult, carried: NDArray
) -> Slip | None:
    """The free body whose spring carries the most of its loads (``carried``), or None.

    Its friction available is ``sum mu N`` (N) where a force is left, and ``sum mu N r``
    (N m, ``r`` each contact's distance from the axis through its centroid) where only a
    moment is: what its cones could carry against that motion.
    """
    net = space.net_wrenches(carried)  # what the springs hold
    worst: Slip | None = None
    for body in frame.bodies:
        if body.name not in net:
            continue
        f, moment = net[body.name]
        size = float(np.linalg.norm(f))
        mine = np.zeros(len(rows))
        for i, pair in enumerate(frame.pairs):
            if pair.slave is body or pair.master is body:
                mine[rows.pair == i] = pair.friction
        cones = mine * res.lam[: len(rows)]
        capacity = float(np.sum(cones))
        load = float(np.linalg.norm(body.loads.reshape(-1, 3).sum(axis=0)))
        scale = UNBALANCED * max(load, capacity, 1e-300)
        # a moment over the body's size weighs as a force: its turn at its surface
        centre = body.mesh.points.mean(axis=0)
        reach = float(np.linalg.norm(body.mesh.points - centre, axis=1).max(initial=0.0)) or 1.0
        turn = float(np.linalg.norm(moment))
        if size > scale:  # the net force the contacts leave: the way it slips
            slip = Slip(body.name, f / size, size, capacity)
        elif turn / reach > scale:
            axis = moment / turn
            arm = _arms(frame, rows, centre, axis)
            slip = Slip(body.name, axis, turn, float(np.sum(cones * arm)), turns=True)
        else:
            continue
        if worst is None or slip.not_carried > worst.not_carried:
            worst = slip
    return worst


def _arms(frame, rows: ContactRows, centre: NDArray, axis: NDArray) -> NDArray:
    """Each row's distance (m) from the axis ``axis`` through ``centre``, at its slave point."""
    d = rows.slave_points(frame.pairs) - centre
    return np.linalg.norm(d - np.outer(d @ axis, axis), axis=1)
