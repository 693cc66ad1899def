"""What a frame's record may rest on: a diverged iterate solves nothing, a bone limit stops nothing.

A diverged seed loop (the Dirichlet-Neumann reading of Gourret, Magnenat-Thalmann and
Thalmann 1989, Fig. 9, with the ball the stiffer side) ends on an iterate that is no
solution: none of its displacements or forces is reported. The frame's record holds the
bodies at rest instead (:func:`rest_states`: zero displacements, no contacts, zero contact
and bone forces) and its stop reason says what diverged (:func:`divergence`).

A bone over its force limit does not stop a solve: the frame is solved as without the
limit, stays converged, and ``over_limit`` names the bone (:func:`over_limit`); the
verdict calls it unrealistic.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from .body import ElasticBody
from .delassus import BodyState

__all__ = ["divergence", "over_limit", "rest_states"]


def rest_states(bodies: Sequence[ElasticBody]) -> dict[str, BodyState]:
    """Every body at rest: zero displacements and reactions (the record of no solution)."""
    return {
        b.name: BodyState(np.zeros(b.mesh.n_dofs), np.zeros(b.mesh.n_dofs), np.zeros(0))
        for b in bodies
    }


def divergence(
    bodies: Sequence[ElasticBody],
    states: Mapping[str, BodyState],
    extent: float,
    iteration: int,
) -> str:
    """The stop reason of a diverged iterate: which node of which body moved how far.

    Parameters
    ----------
    bodies : sequence of ElasticBody
    states : mapping of str to BodyState
        The diverged iterate.
    extent : float
        The scene's largest bounding-box side (m): no linear solution moves a node further.
    iteration : int
        The iteration that diverged, from 1.

    Returns
    -------
    str
        ``"diverged: ..."``, naming the body, the node and its displacement (or that it is
        not finite).
    """
    worst = (-1.0, "", -1)
    for b in bodies:
        u = np.linalg.norm(states[b.name].u.reshape(-1, 3), axis=1)
        u = np.where(np.isfinite(u), u, np.inf)
        k = int(np.argmax(u)) if u.size else -1
        if k >= 0 and u[k] > worst[0]:
            worst = (float(u[k]), b.name, k)
    size, name, node = worst
    moved = "to a non-finite position" if not np.isfinite(size) else f"by {size:.3g} m"
    return (
        f"diverged: iteration {iteration} of the seed loop moved node {node} of {name} "
        f"{moved}, more than the scene's extent {extent:.3g} m (the Dirichlet body is the "
        "stiffer side: try the contact-space algorithm)"
    )


def over_limit(
    limits: Mapping[str, float], supports: Mapping[str, Mapping[str, NDArray]]
) -> dict[str, tuple[float, float]]:
    """Support groups whose force magnitude passes its limit: name -> (force, limit) (N)."""
    out = {}
    for forces in supports.values():
        for name, f in forces.items():
            limit = limits.get(name)
            mag = float(np.linalg.norm(f))
            if limit is not None and mag > limit:
                out[name] = (mag, float(limit))
    return out
