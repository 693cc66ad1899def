"""Is a free body held: its slides, and the stop reasons of a body the contacts let go.

Frictionless contacts hold a free body only where their normals enclose it. Where they
do not (a ball pushed towards the open side of a hand, fingers closing on a ball with
nothing behind it), the linear solve slides or pushes the body rigidly until its
linearised contacts balance or open. These functions tell such a frame apart from one
whose contacts hold the body, and say why it stopped.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from .body import ElasticBody
from .delassus import BodyState

__all__ = [
    "HELD_COS",
    "JUMP",
    "PUSHED_OUT",
    "SLIDES",
    "holds",
    "pushed_out",
    "slides",
    "slipping",
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
#: A free body that moved rigidly by more than this many of its element sizes and that
#: no contact pushes at the end was pushed out of contact (not held).
PUSHED_OUT = 0.5


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


def pushed_out(
    e: Mapping[str, sp.csr_matrix],
    lam: NDArray[np.float64],
    moves: Mapping[str, NDArray[np.float64]],
    local: Mapping[str, NDArray[np.float64]],
) -> str:
    """The stop reason of a free body the contacts pushed off, or "" if none was.

    A free body that moved rigidly by more than ``PUSHED_OUT`` of its element size and
    that no contact pushes at the end was pushed out of contact: frictionless contacts
    that do not enclose it push it away until they open. Any place further along
    balances too, so the frame does not say where it is.

    Parameters
    ----------
    e : mapping of str to sparse matrix
        Each body's part ``E_b`` of the rows.
    lam : ndarray, shape (m,)
        The rows' forces.
    moves : mapping of str to ndarray
        The bodies' rigid translations (:func:`slides`).
    local : mapping of str to ndarray
        Each body's element size at every node (m).
    """
    for name, move in moves.items():
        dist = float(np.linalg.norm(move))
        if dist <= PUSHED_OUT * float(local[name].max()):
            continue  # a nudge (a ball settling in a frictionless bowl)
        eb = e.get(name)
        if eb is not None and (lam > 0).any() and eb[lam > 0].nnz:
            continue
        d = move / dist
        return (
            f"not held: {name} pushed out of contact, {dist * 1e3:.3g} mm along "
            f"[{d[0]:.2f}, {d[1]:.2f}, {d[2]:.2f}], and no contact holds it "
            "(frictionless contacts hold a free body only where they enclose it)"
        )
    return ""


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
    :func:`pushed_out`.
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
