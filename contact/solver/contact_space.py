"""Steps 3 to 5 in contact space: the fixed point of a contact set, solved directly.

The default algorithm. For a set of candidate rows (:class:`contact.solver.rows.ContactRows`)
the fixed point of steps 3 to 5 of Gourret, Magnenat-Thalmann and Thalmann (1989) is
solved at once with the Delassus operator of every body
(:class:`contact.solver.delassus.ContactSpace`): the unilateral solve
(:mod:`contact.solver.lcp`) closes the rows that must push and leaves the others open at
zero force, so a row that pulls is opened there, at no cost in back-solves, and is taken
again there if the linearised gaps need it.

The outer loop only brings geometry (step 2): it measures the deformed bodies, adds a row
for each node found inside its master, linearises stale rows again
(:class:`contact.solver.contactset.ContactSet`), and stops when the measure finds nothing
new. The set of rows only grows within a frame (rows left far behind by a body that moved
off are dropped), so the outer loop cannot cycle by releasing and taking the same
contacts in turn, as it would where rows both ways meet (two-pass node-to-surface contact
over-constrains there). A free body that the contacts let slide or push away, whose
loads they cannot balance, or that touches nothing at the end stops the frame as not
held (:mod:`contact.solver.held`), with the last state kept.
"""

from __future__ import annotations

import logging
import time
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

import fem

from . import contactset, held
from .anchors import Anchors, end_anchors
from .contactset import set_key
from .coulomb import friction_state, unheld
from .delassus import ContactSpace
from .frame import FrameState
from .results import FrameResult, IterationRecord
from .rows import ContactRows
from .tangential import Friction

__all__ = ["LCP_TOLERANCE", "solve_contact_space"]

log = logging.getLogger(__name__)

#: The unilateral solve leaves a row open when its linearised gap is at least minus this
#: fraction of the penetration tolerance (``gap_tolerance`` times the element size): the
#: rest of the tolerance is for the linearisation's error, so that the nonlinear measure
#: does not find the node inside and take it again.
LCP_TOLERANCE = 0.5


def solve_contact_space(
    frame: FrameState,
    anchors: Anchors | None = None,
    search_from: dict[str, NDArray[np.float64]] | None = None,
    slip_from: bool = False,
    prox: dict[str, float] | None = None,
) -> FrameResult:
    """Resolve the frame's contacts in contact space (see the module docstring).

    Parameters
    ----------
    frame : FrameState
        The frame, its zones marked and its bodies factored.
    anchors : Anchors, optional
        The frictional contacts' stick anchors from the previous frame.
    search_from : dict of str to ndarray, optional
        Without friction, displacements ``(N, 3)`` of some bodies at which the first
        contact set is measured instead of at rest (a Newton step's linear bodies where the
        last step left them, so that a contact it closed is a candidate again).
    slip_from : bool
        With friction, give the anchors slip was measured from (``FrameResult.slip_from``).
    prox : dict of str to float, optional
        With friction, springs on these free bodies' modes (a Newton step's damping,
        :class:`~contact.solver.delassus.ContactSpace`).

    Returns
    -------
    FrameResult
        The closed rows and their forces at the last solve, whether the frame converged
        and why it stopped (``"converged"``, ``"cycling"``, ``"iteration limit"``, not
        held, ...).
    """
    st = frame.settings
    contacts = frame.contacts
    friction = Friction(frame, anchors)
    space = ContactSpace(
        frame.bodies, rotations=friction.active, planes=frame.driven.planes,
        prox=prox if friction.active else None,
    )  # fmt: skip
    u = friction.start()
    if search_from and not friction.active:  # where given for a body of this mesh
        u = {n: search_from[n] if n in search_from and search_from[n].shape == v.shape else v
             for n, v in u.items()}  # fmt: skip
    # step 2 (first time): every node inside or near its master, as candidates
    rows, _, _ = contacts.new_rows(ContactRows(), u, touching=True, near=contactset.NEAR)
    if friction.active:
        friction.register(rows, u)
    tangential: dict | None = None
    fres = None
    history: list[IterationRecord] = []
    seen: set[bytes] = set()
    stop, converged = "iteration limit", False
    prev = np.zeros(sum(b.mesh.n_dofs for b in frame.bodies))
    solved, lam, states = rows, np.zeros(0), {}
    start: NDArray[np.float64] | None = None
    slides = 0
    slid: tuple[str, dict[str, NDArray[np.float64]]] | None = None
    last_u = u
    last_moves: dict[str, NDArray[np.float64]] = {}
    unbalanced = ""
    slip = None
    for it in range(1, st.max_iterations + 1):
        key = set_key(rows)
        if key in seen:
            stop = "cycling"
            break
        seen.add(key)
        t = time.perf_counter()
        start = frame.driven.pressed(rows, start)
        if friction.active:
            # steps 3 and 4 with Coulomb friction: normal and tangential rows at once
            fres, states, e, _, tangent = friction.solve(space, rows, start, tangential)
            lam_all = fres.lam
            lam = lam_all[: len(rows)]
            steps, settled = fres.iterations, fres.solved
        else:
            # step 4: each body's part E_b of the rows; a force lambda acts as E_b^T lambda
            e = frame.matrices(rows)
            # step 3: the forces that close the rows, with every body's compliance at once
            tol = LCP_TOLERANCE * frame.row_tol(rows)
            try:
                res, states = space.solve_unilateral(e, rows.g0, tol, start)
            except fem.LoadError:
                # loads out of balance where no contact holds (a ball on a tilted table,
                # or over none): it slides or falls; the state kept is the contacts'
                res, states, net = space.solve_held(e, rows.g0, tol)
                unbalanced = held.unbalanced(net)
            lam = lam_all = res.lam
            steps, settled = res.steps, res.solved
        frame.timings["contact solve"] += time.perf_counter() - t
        solved = rows
        closed = lam > 0
        n_closed = int(closed.sum())
        was = start > 0 if start is not None else np.zeros(len(rows), dtype=bool)
        opened = int((was & ~closed).sum())
        # step 5: every body's displacements under those forces (the solve's states)
        u = {b.name: states[b.name].u.reshape(-1, 3) for b in frame.bodies}
        frame.driven.moved(states)  # the force-driven planes, where the solve put them
        flat = np.concatenate([states[b.name].u for b in frame.bodies])
        change = float(np.abs(flat - prev).max())
        prev = flat
        moves = held.slides(frame.bodies, states)
        jump = max(
            (float(np.linalg.norm(m - last_moves.get(n, 0.0))) for n, m in moves.items()),
            default=0.0,
        )
        before = (last_u, jump) if jump > held.JUMP * frame.margin else None
        last_u, last_moves = u, moves
        # step 2: measure the deformed bodies; rows added, renewed or left behind
        grown, added, depth = contacts.new_rows(rows, u, False, idle=~closed, before=before)
        if unbalanced and added:
            # what it falls or slides into may hold it: solved with the others next
            unbalanced = ""
        if unbalanced:
            frame.record(
                history,
                iteration=it,
                contacts=n_closed,
                added=0,
                released=opened,
                change=change,
                depth=depth,
                e=e,
                lam=lam_all,
                supports=frame.supports(states),
                normal_rows=len(rows),
            )
            stop = unbalanced
            break
        if contacts.broken and not friction.active:
            slides += 1
            slid = slid or (held.slipping(moves, contacts.broken), moves)
            if not added or slides > held.SLIDES:
                # nothing the body slid into holds it (or it keeps sliding): it slips out
                frame.record(
                    history,
                    iteration=it,
                    contacts=n_closed,
                    added=0,
                    released=0,
                    change=change,
                    depth=depth,
                    e=e,
                    lam=lam_all,
                    normal_rows=len(rows),
                )
                stop = slid[0]
                break
            # it slid into something (a wall, another finger) that may hold it: the rows
            # it left are dropped, those it now penetrates are solved with the others
            log.debug("contact space: %d contacts left their facets", contacts.broken)
            grown = contacts.without_broken(grown)
        elif contacts.broken:
            # with friction a body is held by its cones or not at all: rows it left far
            # behind are dropped, the solve says whether what is left holds it
            grown = contacts.without_broken(grown)
        frame.record(
            history,
            iteration=it,
            contacts=n_closed,
            added=added,
            released=opened,
            change=change,
            depth=depth,
            e=e,
            lam=lam_all,
            supports=frame.supports(states),
            normal_rows=len(rows),
        )
        log.debug(
            "contact space: iteration %d, %d rows (%d closed, %d opened), +%d, %d LCP steps",
            it,
            len(rows),
            n_closed,
            opened,
            added,
            steps,
        )
        if not settled:
            if fres is not None:
                slip = unheld(frame, space, friction, rows)
                stop = slip.reason if slip is not None else (
                    f"friction did not settle in {steps} Newton steps "
                    f"(residual {fres.residual:.2g})"
                )
            else:
                stop = f"the contact forces did not settle in {steps} steps"
            break
        if not added:
            converged, stop = True, "converged"
            if not friction.active and slid is not None:
                if not held.holds(frame.bodies, e, lam, slid[1]):
                    converged, stop = False, slid[0]
            # a frictional solve that settled holds every free body it touches
            if converged and (out := frame.untouched(rows, e, lam, states)):
                converged, stop = False, out
            break
        start = carried(rows, lam, grown)
        if friction.active:
            tangential = friction.carry(rows, lam_all, tangent)
            friction.register(grown, u)
        rows = grown
    keep = lam > 0
    state = None
    u_end = {b.name: states[b.name].u.reshape(-1, 3) for b in frame.bodies} if states else u
    if friction.active and fres is not None:
        state = friction_state(friction, solved, fres, tangent, keep)
        ends = friction.anchors_after(solved, fres.status, tangent, u_end)
    else:
        ends = end_anchors(frame, solved.select(keep), u_end)
    res = frame.result(
        converged=converged,
        stop=stop,
        history=history,
        rows=solved.select(keep),
        lam=lam[keep],
        states=states,
        friction=state,
        anchors=ends,
        slip=None if slip is None else slip.record(),
    )
    if friction.active and slip_from:
        res = replace(res, slip_from=friction.measured_from())
    return res


def carried(rows: ContactRows, lam: NDArray[np.float64], grown: ContactRows) -> NDArray[np.float64]:
    """The forces of ``rows`` carried over to ``grown``, by contact.

    A renewed row keeps its node's (largest) force; a new one starts at zero. The
    unilateral solve of the grown set starts from them.
    """
    out = np.zeros(len(grown))
    if not len(rows) or not len(grown):
        return out
    n = int(max(rows.node.max(), grown.node.max())) + 1
    code = rows.pair * n + rows.node
    order = np.lexsort((-lam, code))  # the largest force of a node's rows first
    uniq, first = np.unique(code[order], return_index=True)
    best = lam[order][first]
    new = grown.pair * n + grown.node
    pos = np.searchsorted(uniq, new)
    pos = np.minimum(pos, uniq.size - 1)
    hit = uniq[pos] == new
    out[hit] = best[pos[hit]]
    return out
