"""Contact of one elastic body with rigid planes: an active set on the contact nodes.

This is the iteration of Gourret, Magnenat-Thalmann and Thalmann (1989, Fig. 9) where the
obstacles are rigid: step 2 repels the nodes behind a plane onto it, step 3 solves the body
with them prescribed (frictionless: their normal displacement only) and reads their
reactions from equation (8); a rigid obstacle does not deform, so step 5 changes nothing
and the loop reduces to updating the contact set. Contact memory: a node in contact stays
prescribed onto the plane, even where a gap would open, until its reaction pulls; then it
is released. The extra prescribed DOFs are imposed on the body's one factorisation through
a Schur complement (fem.StaticSolver): nothing is refactored inside the loop.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

import fem

from ..errors import ContactError
from ..geometry.plane import Plane
from ..solver.body import ElasticBody
from ..solver.results import ContactResult, IterationRecord
from ..solver.settings import ContactSettings
from ..solver.zone import slave_zone

__all__ = ["solve_rigid_contact"]

log = logging.getLogger(__name__)


def _rows(pairs: NDArray[np.int64], planes: Sequence[Plane], n_dofs: int) -> sp.csr_matrix:
    """Constraint rows ``n_j . u_i`` for contact pairs ``(node i, plane j)``."""
    m = len(pairs)
    normals = np.array([p.normal for p in planes])[pairs[:, 1]]  # (m, 3)
    rows = np.repeat(np.arange(m), 3)
    cols = (3 * pairs[:, 0][:, None] + np.arange(3)).ravel()
    return sp.csr_matrix((normals.ravel(), (rows, cols)), shape=(m, n_dofs))


def solve_rigid_contact(
    body: ElasticBody,
    planes: Sequence[Plane],
    *,
    max_iterations: int = 50,
    gap_tolerance: float = ContactSettings.gap_tolerance,
    force_tolerance: float = 1e-9,
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
        A free node counts as penetrating when it is behind a plane by more than this
        fraction of its local element size (the square root of its tributary area); at
        the start, nodes that touch a plane within it are taken in contact too.
    force_tolerance : float
        A contact node is released when it pulls by more than this fraction of the
        largest contact force.

    Returns
    -------
    ContactResult
        Never raises on non-convergence: ``converged`` is False and ``stop_reason`` says
        why, with the last state kept.

    Raises
    ------
    ContactError
        If nothing holds a free body (no contact and its loads are not in balance).
    """
    if max_iterations < 1:
        raise ContactError(f"max_iterations must be at least 1, got {max_iterations}")
    t0 = time.perf_counter()
    mesh = body.mesh
    x = mesh.points
    cand = body.surface_nodes
    n = mesh.n_points
    local = np.sqrt(np.maximum(body.node_areas, 1e-300))
    tol_gap = gap_tolerance * local
    # gaps of every candidate against every plane in the undeformed position: (c, p)
    g0 = np.stack([p.signed_distance(x[cand]) for p in planes], axis=1) if planes else None
    if g0 is None:
        g0 = np.zeros((cand.size, 0))
    normals = np.array([p.normal for p in planes]).reshape(-1, 3)
    if g0.size:
        # the contact zone, for partial solves (:mod:`contact.solver.zone`)
        zone = np.zeros(cand.size, dtype=bool)
        for g in g0.T:  # each plane's, where it comes within a few elements
            if g.min() < 3.0 * float(local[cand].max()):
                zone |= slave_zone(x, cand, g, g < tol_gap[cand], local[cand])
        body.mark_zone(cand[zone], g0.min(axis=1)[zone])

    # step 2: nodes behind a plane, or touching it within the tolerance, are repelled
    # onto it and prescribed there: (k, 2) pairs of candidate index and plane
    active = np.argwhere(g0 < tol_gap[cand][:, None])
    history: list[IterationRecord] = []
    seen: set[bytes] = set()
    u_prev = np.zeros(n * 3)
    stop = "iteration limit"
    converged = False
    sol = None
    forces = np.zeros(0)
    solved = active
    for it in range(1, max_iterations + 1):
        key = active[np.lexsort(active.T[::-1])].tobytes() if len(active) else b""
        if key in seen:
            stop = "cycling"
            break
        seen.add(key)
        pairs = np.column_stack([cand[active[:, 0]], active[:, 1]]) if len(active) else None
        try:
            if pairs is None:
                sol = body.solver.solve(body.loads)
            else:
                rows = _rows(pairs, planes, 3 * n)
                sol = body.solver.solve(
                    body.loads, extra=rows, extra_values=-g0[active[:, 0], active[:, 1]]
                )
        except fem.LoadError as exc:
            raise ContactError(
                f"{body.name}: nothing holds it: {exc} (is it touching a plane?)"
            ) from None
        forces = sol.extra_reactions  # along each plane's normal: > 0 pushes the body off
        u = sol.u.reshape(-1, 3)
        gaps = g0 + u[cand] @ normals.T
        if len(active):
            gaps[active[:, 0], active[:, 1]] = np.inf  # on the plane by construction
        penetrating = np.argwhere(gaps < -tol_gap[cand][:, None])
        scale = max(float(np.abs(forces).max()) if forces.size else 0.0, 1e-300)
        pulling = forces < -force_tolerance * scale
        change = float(np.abs(sol.u - u_prev).max())
        u_prev = sol.u
        depth = float(max(-gaps.min(), 0.0)) if gaps.size else 0.0
        total = (
            (forces[:, None] * normals[active[:, 1]]).sum(axis=0) if len(active) else np.zeros(3)
        )
        history.append(
            IterationRecord(
                iteration=it,
                n_contacts=len(active),
                added=len(penetrating),
                released=int(pulling.sum()),
                max_change=change,
                max_penetration=depth,
                total_force=total,
            )
        )
        log.debug(
            "%s: iteration %d, %d contacts, +%d -%d, change %.3g m",
            body.name,
            it,
            len(active),
            len(penetrating),
            int(pulling.sum()),
            change,
        )
        solved = active
        if not len(penetrating) and not pulling.any():
            converged, stop = True, "converged"
            break
        keep = active[~pulling] if len(active) else active
        active = (
            np.unique(np.concatenate([keep, penetrating]), axis=0) if len(penetrating) else keep
        )
    if sol is None:  # the first contact set repeated nothing: cannot happen
        raise ContactError(f"{body.name}: the contact solve made no iteration")
    active = solved  # the state reported is the last one solved
    contact = np.zeros((n, 3))
    plane_forces = {p.name: np.zeros(3) for p in planes}
    if len(active):
        f_vec = forces[:, None] * normals[active[:, 1]]
        np.add.at(contact, cand[active[:, 0]], f_vec)
        for j, p in enumerate(planes):
            plane_forces[p.name] = -f_vec[active[:, 1] == j].sum(axis=0)
    u = sol.u.reshape(-1, 3)
    final_gaps = g0 + u[cand] @ normals.T
    return ContactResult(
        converged=converged,
        stop_reason=stop,
        iterations=len(history),
        history=tuple(history),
        displacement=u,
        contact_force=contact,
        obstacle_forces=plane_forces,
        contact_nodes=np.unique(cand[active[:, 0]]) if len(active) else np.zeros(0, np.int64),
        max_penetration=float(max(-final_gaps.min(), 0.0)) if final_gaps.size else 0.0,
        timings={"solve": time.perf_counter() - t0},
    )
