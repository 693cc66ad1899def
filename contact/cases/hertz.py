"""The Hertz verification case: an elastic ball pressed between two rigid plates.

:func:`hertz_check` presses a graded ball (whole, or its octant with three symmetry planes)
between rigid frictionless plates, solves the contact and measures the table's contact
patch (:mod:`contact.cases.contact_patch`) against the analytic solution for the patch's
own total force (:mod:`contact.cases.hertz_theory`). The names of both are re-exported here.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

import fem
from fem.generators import graded_ball_mesh

from ..errors import ContactError
from ..geometry.plane import Plane
from ..solver.body import ElasticBody
from ..solver.results import ContactResult
from .contact_patch import (
    ContactPatch,
    HertzErrors,
    interpolation_excess,
    measure_contact_patch,
    moment_radius,
)
from .hertz_theory import HertzSolution, effective_modulus, hertz_sphere_on_plane
from .rigid import solve_rigid_contact

__all__ = [
    "HERTZ_MODELS",
    "ContactPatch",
    "HertzCheck",
    "HertzErrors",
    "HertzSolution",
    "effective_modulus",
    "hertz_check",
    "hertz_sphere_on_plane",
    "interpolation_excess",
    "measure_contact_patch",
    "moment_radius",
]


#: Models of the Hertz scene: the whole ball between two plates, or its octant (three
#: symmetry planes, one plate); the fraction of a contact patch each holds.
HERTZ_MODELS: dict[str, float] = {"full": 1.0, "octant": 0.25}


@dataclass(frozen=True)
class HertzCheck(HertzErrors):
    """An elastic ball pressed between two rigid frictionless plates, against Hertz.

    Attributes
    ----------
    model : str
        ``"full"`` or ``"octant"`` (see :func:`hertz_check`).
    mesh : fem.Mesh
    body : ElasticBody
    planes : tuple of Plane
        The table (first) and, for the full model, the plate.
    result : ContactResult
    patch : ContactPatch
        The table's patch, forces of the whole patch.
    hertz : HertzSolution
        Hertz for the patch's own total force.
    seconds : dict of str to float
        ``mesh``, ``body`` (assembly and factorisation) and ``contact`` times.
    """

    model: str
    mesh: fem.Mesh
    body: ElasticBody
    planes: tuple[Plane, ...]
    result: ContactResult
    patch: ContactPatch
    hertz: HertzSolution
    seconds: dict[str, float] = field(default_factory=dict)


def _symmetry_dofs(mesh: fem.Mesh, center: NDArray, tol: float) -> NDArray[np.int64]:
    """Normal DOFs of the nodes on the octant's planes x = 0, y = 0, z = 0 (about centre)."""
    d = mesh.points - center
    dofs = [3 * np.flatnonzero(np.abs(d[:, k]) <= tol) + k for k in range(3)]
    return np.concatenate(dofs)


def hertz_check(
    radius: float = 1.0,
    E: float = 1.0,
    nu: float = 0.3,
    *,
    depth: float,
    fine_size: float,
    fine_radius: float | None = None,
    model: str = "octant",
    growth: float = 1.25,
    coarse_size: float | None = None,
    edge_cells: float = 2.0,
    bbar: bool = True,
) -> HertzCheck:
    """Press a ball between two plates and measure its contact patch against Hertz.

    The ball of :func:`fem.generators.graded_ball_mesh` (fine near its poles on the z
    axis) rests with its centre at ``(0, 0, radius)`` on the table ``z = 0``; the table
    rises by ``depth`` and the plate on top (``z = 2 radius``) comes down by ``depth``.
    ``model="full"`` meshes the whole free ball with both plates. ``model="octant"`` meshes
    the eighth ``x, y >= 0, z <= radius`` and replaces the rest by its exact symmetry
    (frictionless symmetry planes: zero normal displacement on ``x = 0``, ``y = 0`` and the
    equator ``z = radius``), so only the table presses it: the same solution for an eighth
    of the DOFs, with the body held (no rigid modes left).

    Parameters
    ----------
    radius, E, nu : float
        The ball (m, Pa).
    depth : float
        How far each plate advances (m): ``a/R`` is about ``sqrt(depth / R)``.
    fine_size : float
        Cell size at the poles (m).
    fine_radius : float, optional
        Radius of the fine zone (m); ``1.3 sqrt(depth R)`` (30 % beyond the expected
        contact radius), at most ``0.4 R``, by default.
    model : {"octant", "full"}
    growth, coarse_size : float
        Grading of the mesh (see :func:`fem.generators.graded_ball_mesh`).
    edge_cells : float
        Passed to :func:`measure_contact_patch`.
    bbar : bool
        The ball's bricks with their mean dilatation (default) or fully integrated (the
        discrete model of codes without B-bar, for a like-for-like comparison).

    Returns
    -------
    HertzCheck
    """
    if model not in HERTZ_MODELS:
        raise ContactError(f"model must be one of {sorted(HERTZ_MODELS)}, got {model!r}")
    if not 0 < depth < 0.2 * radius:
        raise ContactError(f"depth must lie in (0, 0.2 radius), got {depth!r}")
    fr = min(1.3 * math.sqrt(depth * radius), 0.4 * radius) if fine_radius is None else fine_radius
    fr = max(fr, fine_size)
    center = np.array([0.0, 0.0, radius])
    t0 = time.perf_counter()
    part = "octant" if model == "octant" else "full"
    mesh = graded_ball_mesh(
        radius, fine_size, fr, coarse_size=coarse_size, growth=growth, part=part, center=center
    )
    t1 = time.perf_counter()
    pres = _symmetry_dofs(mesh, center, 1e-9 * radius) if model == "octant" else None
    body = ElasticBody("ball", mesh, fem.LinearElastic(E, nu), prescribed=pres, bbar=bbar)
    t2 = time.perf_counter()
    planes = [Plane([0, 0, 0], [0, 0, 1], motion=[0, 0, depth], name="table")]
    if model == "full":
        planes.append(Plane([0, 0, 2 * radius], [0, 0, -1], motion=[0, 0, -depth], name="plate"))
    result = solve_rigid_contact(body, planes)
    t3 = time.perf_counter()
    frac = HERTZ_MODELS[model]
    patch = measure_contact_patch(
        mesh,
        result,
        planes[0],
        center=np.zeros(3) if model == "octant" else None,
        fraction=frac,
        edge_cells=edge_cells,
    )
    hz = hertz_sphere_on_plane(patch.force, radius, E, nu)
    secs = {"mesh": t1 - t0, "body": t2 - t1, "contact": t3 - t2}
    return HertzCheck(model, mesh, body, tuple(planes), result, patch, hz, secs)
