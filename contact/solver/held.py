"""Is a free body held: its slides, and the stop reasons of a body the contacts let go.

Frictionless contacts hold a free body only where their normals enclose it. Where they
do not (a ball pushed towards the open side of a hand, fingers closing on a ball with
nothing behind it), the linear solve slides or pushes the body rigidly until its
linearised contacts balance or open; where its loads (gravity) are out of balance in a
direction no contact holds (a ball on a tilted table, or with nothing under it), no
placement balances it. These functions tell such a frame apart from one whose contacts
hold the body, and say why it stopped: every reason starts with ``"not held: "``
(:func:`contact.solver.fields.held_verdict` reads it). A free body that touches nothing
at the end of a frame is never held, however little it moved.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

import fem

from .body import ElasticBody
from .delassus import BodyState

__all__ = [
    "HELD_COS",
    "JUMP",
    "MAX_TURN",
    "SLIDES",
    "end_gaps",
    "free_load",
    "holds",
    "slides",
    "slipping",
    "touches_nothing",
    "turned",
    "unbalanced",
    "way",
]

#: A solve that moves a free body rigidly by more than this many element sizes (the
#: frame's largest) jumped: new rows are linearised where it was before (a safety net
#: behind ``contactset.NEAR``: an obstacle further than that from the ball at the
#: frame's start).
JUMP = 0.5
#: Updates in a frame whose solve slides a free body so far that contacts leave their
#: facets, each caught by new contacts where it slid, before the frame stops as not held.
SLIDES = 3
#: A body that slid is held when the unit slide direction keeps at least this length
#: in the span of the normals of the rows that push it.
HELD_COS = 0.5
#: The largest rigid rotation (rad) of a free body that the linear, small-rotation model
#: describes: a rotation ``theta`` stretches the body by about ``theta^2 / 2`` (0.5 % here).
MAX_TURN = 0.1


def slides(
    bodies: Sequence[ElasticBody], states: Mapping[str, BodyState]
) -> dict[str, NDArray[np.float64]]:
    """Each free body's rigid translation in ``states`` (m)."""
    out = {}
    for b in bodies:
        rigid = states[b.name].rigid
        if b.solver.free_body and rigid.size:
            out[b.name] = (b.solver.modes[:, :3] @ rigid[:3]).reshape(-1, 3)[0]
    return out


def slipping(moves: Mapping[str, NDArray[np.float64]], broken: int) -> str:
    """The stop reason when contacts in the set have lost their masters.

    The linear solve slid a free body along the open direction of its contacts so far
    that ``broken`` contact nodes left their facets. Unless something it slid into holds
    it (:func:`holds`), the frame stops: the body slips out. ``moves``: the bodies'
    rigid translations (:func:`slides`).
    """
    sizes = [(float(np.linalg.norm(m)), n, m) for n, m in moves.items()]
    how = ""
    if sizes:
        dist, name, move = max(sizes, key=lambda m: m[0])
        d = move / max(dist, 1e-300)
        how = f"{name} slid {dist * 1e3:.3g} mm along [{d[0]:.2f}, {d[1]:.2f}, {d[2]:.2f}]; "
    return (
        f"not held: {how}{broken} contact(s) left their facets (frictionless contacts "
        "that do not enclose a body cannot hold it)"
    )


def touches_nothing(
    e: Mapping[str, sp.csr_matrix],
    lam: NDArray[np.float64],
    gap: NDArray[np.float64],
    tol: NDArray[np.float64],
    moves: Mapping[str, NDArray[np.float64]],
    still: Mapping[str, float],
    small: NDArray[np.float64] | None = None,
    resting: Mapping[str, NDArray[np.bool_]] | None = None,
) -> str:
    """The stop reason of a free body that no contact pushes at the end, or "" if none.

    Such a body is held by nothing: frictionless contacts that do not enclose it pushed
    it away until they opened (any place further along balances too), or nothing ever
    touched it. A body that did not move and rests on contacts at zero force (nothing
    loads it: two plates touching a ball before they press) is left alone; so is one
    that nothing loads or presses into and that touches at the end, wherever the solve
    placed it (weighted gaps are open where a ball touches a plate at one node: the
    solve sets it onto the nearest, at zero force). The reason gives the body's rigid
    motion in the frame's solve.

    Parameters
    ----------
    e : mapping of str to sparse matrix
        Each body's part ``E_b`` of the rows; with friction the normal rows come first,
        one for each entry of ``lam``.
    lam : ndarray, shape (m,)
        The normal rows' forces (N).
    gap : ndarray, shape (m,)
        The normal rows' linearised gaps at the end (m).
    tol : ndarray, shape (m,)
        The rows' penetration tolerances (m): a row within it of closing touches.
    moves : mapping of str to ndarray
        The free bodies' rigid translations (:func:`slides`).
    still : mapping of str to float
        Each free body's motion (m) below which it did not move.
    small : ndarray, shape (m,), optional
        Each row's force (N) at or below which it does not push: round-off (default 0).
    resting : mapping of str to ndarray of bool, optional
        The free bodies that nothing loads, each with the rows (m,) that pressed into it
        at the start (their linearised gap below the tolerance's negative).
    """
    m = lam.size
    small = np.zeros(m) if small is None else small
    resting = resting or {}
    for name, move in moves.items():
        eb = e.get(name)
        mine = eb[:m].getnnz(axis=1) > 0 if eb is not None and m else np.zeros(m, bool)
        if (mine & (lam > small)).any():
            continue
        dist = float(np.linalg.norm(move))
        rests = name in resting and not (mine & resting[name]).any()
        if (dist <= still[name] or rests) and (mine & (gap <= tol)).any():
            continue
        d = move / dist if dist > 0 else np.zeros(3)
        return (
            f"not held: {name} touches nothing (moved {dist * 1e3:.3g} mm along "
            f"{way(d)}); frictionless contacts hold a free "
            "body only where they enclose it"
        )
    return ""


def way(d: NDArray[np.float64]) -> str:
    """A direction as ``"(x, y, z)"`` to three decimals, with no ``-0.000``.

    A component that round-off leaves on either side of zero reads the same both ways,
    so that a stop reason does not depend on the machine.
    """
    r = np.round(np.asarray(d, dtype=np.float64), 3) + 0.0  # -0.0 + 0.0 is 0.0
    return f"({r[0]:.3f}, {r[1]:.3f}, {r[2]:.3f})"


def end_gaps(
    g0: NDArray[np.float64],
    e: Mapping[str, sp.csr_matrix],
    states: Mapping[str, BodyState],
) -> NDArray[np.float64]:
    """The linearised gaps ``g0 + sum_b E_b u_b`` of the first ``len(g0)`` rows (m)."""
    gap = np.array(g0, dtype=np.float64)
    for name, eb in e.items():
        if gap.size:
            gap += eb[: gap.size] @ states[name].u
    return gap


def unbalanced(net: Mapping[str, NDArray[np.float64]]) -> str:
    """The stop reason of free bodies whose loads the contacts cannot balance.

    ``net`` is each such body's net force, loads and contact forces together (N): the
    part of its loads no contact carries, and so the way it would move (slide or fall).
    The body with the largest is named.
    """
    name, force = max(net.items(), key=lambda kv: float(np.linalg.norm(kv[1])))
    size = float(np.linalg.norm(force))
    if size == 0.0:  # out of balance only in a turn (a moment no contact carries)
        return f"not held: {name} turns: no contact carries the moment of its loads"
    d = force / size
    return (
        f"not held: {name} moves along {way(d)}: {size:.4g} N "
        "of its loads is carried by no contact (frictionless contacts hold a free body "
        "only where they enclose it)"
    )


def free_load(body: ElasticBody, eb: sp.csr_matrix | None) -> NDArray[np.float64]:
    """The part of a free body's net load (N) in the translations rows ``eb`` leave free.

    The rows hold the body along the span of their directions (both ways: prescribed
    rows); the rest of its net load has nothing to carry it.
    """
    force = body.loads.reshape(-1, 3).sum(axis=0)
    if eb is None or not eb.shape[0]:
        return force
    # each row's value of a unit translation along x, y and z: its direction
    t = np.column_stack([np.asarray(eb[:, k::3].sum(axis=1)).ravel() for k in range(3)])
    _, sv, vt = np.linalg.svd(t, full_matrices=True)
    rank = int((sv > 1e-8 * sv.max()).sum()) if sv.size and sv.max() > 0 else 0
    free = vt[rank:]
    return free.T @ (free @ force)


def holds(
    bodies: Sequence[ElasticBody],
    e: Mapping[str, sp.csr_matrix],
    lam: NDArray[np.float64],
    moves: Mapping[str, NDArray[np.float64]],
) -> bool:
    """Whether the pushing rows hold every free body against its slide ``moves``.

    A body that slid so far that contacts left their facets is held once the normals of
    the rows that push it span the slide's direction: a wall or another finger caught
    it. Otherwise it slid out of reach and the forces that remain (none, or only those
    in other directions) do not say where it is. ``e`` and ``lam`` as for
    :func:`touches_nothing`.
    """
    modes = {b.name: b.solver.modes for b in bodies}
    for name, move in moves.items():
        dist = float(np.linalg.norm(move))
        if dist == 0.0:
            continue
        eb = e.get(name)
        if eb is None or not (lam > 0).any():
            return False
        t = eb[lam > 0] @ modes[name][:, :3]  # the pushing rows' directions
        _, sv, vt = np.linalg.svd(t, full_matrices=False)
        span = vt[sv > 1e-6 * sv.max()] if sv.size and sv.max() > 0 else np.zeros((0, 3))
        if np.linalg.norm(span @ (move / dist)) < HELD_COS:
            return False
    return True


def turned(bodies: Sequence[ElasticBody], states: Mapping[str, BodyState]) -> str:
    """The stop reason of a free body turned past :data:`MAX_TURN`, or "" if none.

    The rigid part of its displacement, ``t + omega x r`` about its centroid, fitted to its
    rigid-mode amplitudes: past ``MAX_TURN`` the linearised rotation stretches the body
    and its forces describe no real state (a ball spun by one frictional contact on a
    frictionless table), whatever the contact set did.
    """
    worst = (0.0, "")
    for b in bodies:
        rigid = states[b.name].rigid
        if not (b.solver.free_body and rigid.size) or b.turns_freely:
            continue
        _, omega = fem.rigid_part(b.mesh.points, b.solver.modes @ rigid)
        angle = float(np.linalg.norm(omega))
        if angle > max(MAX_TURN, worst[0]):
            worst = (angle, b.name)
    if not worst[1]:
        return ""
    return (
        f"{worst[1]} turned {np.degrees(worst[0]):.3g} deg, past the "
        f"{np.degrees(MAX_TURN):.3g} deg that the linear (small-rotation) model describes: "
        "its contacts hardly hold its rotation"
    )
