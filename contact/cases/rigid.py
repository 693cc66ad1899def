"""Contact of one elastic body with rigid frictionless planes, through the frame's solve.

The iteration of Gourret, Magnenat-Thalmann and Thalmann (1989, Fig. 9) where the
obstacles are rigid: a rigid obstacle does not deform, so their step 5 changes nothing
and the loop reduces to finding the contact set. :func:`solve_rigid_contact` is
:func:`contact.solver.iteration.solve_frame` with the body, its planes and no friction,
in contact space (the default): one frictionless-contact path for the analytic cases
(Hertz, the block, the line contact), the plates and the CLI, so that every improvement
of the frame's solve reaches all of them. Its result is the one body's view of the
frame's (:class:`~contact.solver.results.ContactResult`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..errors import ContactError
from ..geometry.plane import Plane
from ..solver.body import ElasticBody
from ..solver.iteration import solve_frame
from ..solver.pairs import ContactPair
from ..solver.results import ContactResult
from ..solver.settings import ContactSettings

__all__ = ["solve_rigid_contact"]


def solve_rigid_contact(
    body: ElasticBody,
    planes: Sequence[Plane],
    *,
    max_iterations: int = 50,
    gap_tolerance: float = ContactSettings.gap_tolerance,
    force_tolerance: float = ContactSettings.force_tolerance,
    weighted: bool = False,
) -> ContactResult:
    """Resolve the contact of an elastic body with rigid frictionless planes.

    Parameters
    ----------
    body : ElasticBody
        The deformable body (a free ball, or one with supports), with its known loads.
    planes : sequence of Plane
        Rigid planes, each already moved to the frame's position.
    max_iterations : int
        Limit on the contact-set updates.
    gap_tolerance : float
        A node counts as penetrating when it is behind a plane by more than this fraction
        of its local element size (``ContactSettings.gap_tolerance``).
    force_tolerance : float
        ``ContactSettings.force_tolerance``: a contact pulling by less than this fraction
        of the largest force is not released.
    weighted : bool
        Weighted gaps over the body's smoothed faces (one mortar row per covered node,
        :mod:`contact.solver.planemortar`) instead of a row per node.

    Returns
    -------
    ContactResult
        Never raises on non-convergence: ``converged`` is False and ``stop_reason`` says
        why, with the last state kept.

    Raises
    ------
    ContactError
        If nothing holds a free body (its loads out of balance and no contact holds it).
    """
    if max_iterations < 1:
        raise ContactError(f"max_iterations must be at least 1, got {max_iterations}")
    settings = ContactSettings(
        max_iterations=max_iterations,
        gap_tolerance=gap_tolerance,
        force_tolerance=force_tolerance,
    )
    pairs = [ContactPair(body, p, mortar=weighted) for p in planes]
    res = solve_frame([body], pairs, list(planes), settings)
    if res.stop_reason.startswith("not held"):
        raise ContactError(f"{body.name}: nothing holds it: {res.stop_reason}")
    u = res.displacement[body.name]
    force = res.contact_force[body.name]
    nodes = np.flatnonzero(np.abs(force).sum(axis=1) > 0)
    timings = dict(res.timings)
    timings["solve"] = timings.get("total", sum(res.timings.values()))
    return ContactResult(
        converged=res.converged,
        stop_reason=res.stop_reason,
        iterations=res.iterations,
        history=res.history,
        displacement=u,
        contact_force=force,
        obstacle_forces={k: np.asarray(v) for k, v in res.obstacle_forces.items()},
        contact_nodes=nodes,
        max_penetration=res.max_penetration,
        timings=timings,
    )
