"""Steps 3 to 5 as the seed's literal Dirichlet-Neumann loop.

Fig. 9 of Gourret, Magnenat-Thalmann and Thalmann (1989) read literally: an iteration
between one *Dirichlet* body (the ball) and the others (the hand):

3. solve the ball with its contact rows prescribed against the others' current
   positions; its reactions are the contact forces (their equations 7 and 8; a free ball
   through its rigid modes, whose amplitudes place it);
4. dispatch each reaction, reversed, onto the master facet's nodes with the barycentric
   weights (action equals reaction by construction);
5. solve the others under these forces (bones prescribed); the ball keeps step 3's
   state; relax the others' answer (none, a fixed factor, or Aitken's).

Step 2 (repel) measures the deformed bodies and takes or releases contacts between
loops (:class:`contact.solver.contactset.ContactSet`). The loop converges only where the
ball is the softer side (the others then act as a mould stiffer than it); the default
algorithm is :mod:`contact.solver.contact_space`. A free ball that its rows do not hold
against its loads, or that touches nothing at the end, stops the frame as not held
(:mod:`contact.solver.held`). A loop that diverges reports no force or displacement of its
last iterate (:mod:`contact.solver.verdicts`); a bone over its limit does not stop it.
"""

from __future__ import annotations

import logging
import time

import numpy as np
from numpy.typing import NDArray

import fem

from ..errors import ContactError
from . import held
from .delassus import BodyState, ContactSpace
from .frame import FrameState
from .results import FrameResult, IterationRecord
from .rows import ContactRows
from .verdicts import divergence, rest_states

__all__ = ["solve_seed"]

log = logging.getLogger(__name__)


def solve_seed(frame: FrameState, dirichlet: str) -> FrameResult:
    """Resolve the frame's contacts by the seed's Dirichlet-Neumann loop.

    Parameters
    ----------
    frame : FrameState
        The frame, its zones marked and its bodies factored.
    dirichlet : str
        The body solved with its contacts prescribed (step 3).

    Returns
    -------
    FrameResult
        The last contact set and its forces; ``stop_reason`` ``"converged"``,
        ``"iteration limit"``, not held, or singular rows. ``"diverged: ..."`` (what moved
        how far) reports the bodies at rest, without contacts or forces: the diverged
        iterate solves nothing (:mod:`contact.solver.verdicts`).

    Raises
    ------
    ContactError
        If ``dirichlet`` is not a body of the frame or a pair does not involve it.
    """
    st = frame.settings
    names = [b.name for b in frame.bodies]
    if dirichlet not in names:
        raise ContactError(f"the seed loop's Dirichlet body {dirichlet!r} is not in {names}")
    ball = frame.bodies[names.index(dirichlet)]
    others = [b for b in frame.bodies if b is not ball]
    for p in frame.pairs:
        if p.slave is not ball and p.master is not ball:
            raise ContactError(
                f"the seed loop resolves contacts with {dirichlet!r} only; pair {p.name} "
                "does not involve it (use the contact-space algorithm)"
            )
    space = ContactSpace(frame.bodies)
    states = rest_states(frame.bodies)
    u = {b.name: np.zeros((b.mesh.n_points, 3)) for b in frame.bodies}
    # step 2 (first time): nodes penetrating or touching in the posed position
    rows, _, _ = frame.contacts.new_rows(ContactRows(), u, touching=True)
    history: list[IterationRecord] = []
    stop, converged = "iteration limit", False
    omega = 1.0 if st.relaxation == "none" else st.relaxation_factor
    residual_prev: NDArray | None = None
    lam = np.zeros(0)
    solved = rows
    for it in range(1, st.max_iterations + 1):
        t = time.perf_counter()
        e = frame.matrices(rows)
        # step 3: the ball with its contact rows prescribed against the others' positions
        g = rows.g0.copy()
        for b in others:
            if b.name in e:
                g += e[b.name] @ states[b.name].u
        eb = e.get(ball.name)
        try:
            if eb is None or not len(rows):
                sol = ball.solver.solve(ball.loads)
                lam = np.zeros(0)
            else:
                sol = ball.solver.solve(ball.loads, extra=eb, extra_values=-g)
                lam = sol.extra_reactions
        except fem.LoadError:
            # its loads out of balance where no row holds it: it slides or falls
            stop = held.unbalanced({ball.name: held.free_load(ball, eb)})
            if lam.size != len(solved):  # nothing solved yet: report no contact
                solved, lam = ContactRows(), np.zeros(0)
            break
        except fem.SolverError as exc:
            # rows from both directions prescribe the ball twice where the surfaces meet
            # node to node: its own compliance on them is singular (the sum of both
            # bodies', which the contact-space solve uses, is not)
            stop = f"singular contact rows on {ball.name}: {exc}"
            if lam.size != len(solved):  # nothing solved yet: report no contact
                solved, lam = ContactRows(), np.zeros(0)
            break
        frame.timings["contact solve"] += time.perf_counter() - t
        t = time.perf_counter()
        new_states = {ball.name: BodyState(sol.u, sol.reactions, sol.rigid)}
        # steps 4 and 5: the reactions, reversed, dispatched onto the others; solve them
        residuals = []
        for b in others:
            eo = e.get(b.name)
            forces = eo.T @ lam if eo is not None and lam.size else np.zeros(b.mesh.n_dofs)
            answer = space.state(b, forces, np.zeros(6) if b.solver.free_body else np.zeros(0))
            residuals.append(answer.u - states[b.name].u)
            new_states[b.name] = answer
        if others:
            # step 5: relax the others' answer
            r = np.concatenate(residuals)
            if st.relaxation == "aitken" and residual_prev is not None:
                dr = r - residual_prev
                denom = float(dr @ dr)
                if denom > 0:
                    omega = float(np.clip(-omega * (residual_prev @ dr) / denom, 0.01, 1.0))
            residual_prev = r
            for b, res in zip(others, residuals, strict=True):
                old = states[b.name]
                full = new_states[b.name]
                uu = old.u + omega * res
                reac = old.reactions + omega * (full.reactions - old.reactions)
                new_states[b.name] = BodyState(uu, reac, full.rigid)
        frame.timings["bodies"] += time.perf_counter() - t
        flat_new = np.concatenate([new_states[b.name].u for b in frame.bodies])
        flat_old = np.concatenate([states[b.name].u for b in frame.bodies])
        change = float(np.abs(flat_new - flat_old).max())
        size = max(float(np.abs(flat_new).max()), 1e-300)
        states = new_states
        solved = rows
        if not np.isfinite(size) or size > frame.extent:
            # a linear solution moving a node further than the scene is wide: the
            # Dirichlet-Neumann iteration diverges (the ball is the stiffer side); its
            # history keeps how it grew, the result none of its forces
            stop = divergence(frame.bodies, states, frame.extent, it)
            frame.record(
                history,
                iteration=it,
                contacts=len(rows),
                added=0,
                released=0,
                change=change,
                depth=np.nan,
                e=e,
                lam=lam,
                relaxation=omega,
            )
            states, solved, lam = rest_states(frame.bodies), ContactRows(), np.zeros(0)
            break
        u = {name: s.u.reshape(-1, 3) for name, s in states.items()}
        scale = frame.force_scale(lam)
        pulling = lam < -st.force_tolerance * scale
        # step 2: contacts that pull released, new penetrations taken
        grown, added, depth = frame.contacts.new_rows(rows, u, False, pulling)
        supports = frame.supports(states)
        frame.record(
            history,
            iteration=it,
            contacts=len(rows),
            added=added,
            released=int(pulling.sum()),
            change=change,
            depth=depth,
            e=e,
            lam=lam,
            relaxation=omega,
            supports=supports,
        )
        log.debug("seed: iteration %d, %d contacts, change %.3g", it, len(rows), change)
        if it > 1 and change <= st.tolerance * size and not added and not pulling.any():
            converged, stop = True, "converged"
            if out := frame.untouched(rows, e, lam, states):
                converged, stop = False, out
            break
        rows = grown
    return frame.result(
        converged=converged,
        stop=stop,
        history=history,
        rows=solved,
        lam=lam,
        states=states,
    )
