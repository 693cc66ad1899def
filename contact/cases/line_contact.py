"""A long cylinder compressed between two rigid frictionless plates: Hertz line contact.

A cylinder of radius ``R`` (axis z) lies between the plates ``y = -R`` and ``y = R``,
which approach by ``delta`` in total; in the middle of a long cylinder the state is plane
strain. Each contact is Hertz's two-dimensional one, of half-width ``b = sqrt(4 P' R /
(pi E*))`` and peak pressure ``p0 = 2 P' / (pi b)`` for the force per length ``P'`` and
``E* = E / (1 - nu^2)``; the approach of the plates is (Johnson 1985, ch. 5, the
compression of a cylinder between plates; Puttock and Thwaite 1969)::

    delta = (2 P' / (pi E*)) (2 ln(4 R / b) - 1)

It follows from the stress on the loaded diameter, that of the disc under two diametral
forces (Hertz 1883; Timoshenko and Goodier 1951: two Flamant fields and a uniform tension
``P' / (pi R)``) with each point force's field replaced by the Hertz half-plane field
under its contact (McEwen 1949: ``sigma_yy = -p0 b / sqrt(b^2 + s^2)``, ``sigma_xx = -p0
((b^2 + 2 s^2) / sqrt(b^2 + s^2) - 2 s) / b`` at depth ``s``), exact to order ``(b /
R)^2``: the integrals over the diameter are ``-(2 P' / pi) ln(4 R / b)`` and ``-P' / pi``
per contact, and the plane-strain ``epsilon_yy`` integrates to ``-delta``. The check
compares the force per length at a prescribed approach with the root of that relation
(monotone for ``b < 4 R / e``): the approach is the compression of the whole diameter, so
it needs the contact zone and the body resolved, and the comparison is exact in the limit
of a fine mesh and small ``b / R``.

The model is the quarter ``x, y >= 0`` of a slab of thickness ``H``: rollers on both end
faces (``u_z = 0``: exact plane strain), the symmetry planes ``x = 0`` and ``y = 0`` held
normally (the bottom plate is the mirror of the top one), the top plate coming down by
``delta / 2``; ``P' = 2 F / H`` for the plate's force ``F`` on the half contact. The
quarter disc is the face ``y = 0`` of :func:`fem.generators.graded_ball_mesh`'s octant,
graded toward the pole (the contact line), extruded along z.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.optimize as so

import fem
from fem.generators import graded_ball_mesh

from ..errors import ContactError
from ..geometry.plane import Plane
from ..solver.body import ElasticBody
from ..solver.results import ContactResult
from .hertz_theory import effective_modulus
from .rigid import solve_rigid_contact

__all__ = [
    "LineContactCheck",
    "LineContactSolution",
    "cylinder_between_plates",
    "line_contact_check",
    "quarter_cylinder_mesh",
]


@dataclass(frozen=True)
class LineContactSolution:
    """A cylinder compressed between two rigid frictionless plates (plane strain, SI).

    Attributes
    ----------
    force : float
        Force per unit length ``P'`` (N/m).
    radius : float
        ``R`` (m).
    modulus : float
        ``E*`` (Pa).
    half_width : float
        ``b = sqrt(4 P' R / (pi E*))`` (m).
    peak_pressure : float
        ``p0 = 2 P' / (pi b)`` (Pa).
    approach : float
        ``delta = (2 P' / (pi E*)) (2 ln(4 R / b) - 1)`` (m): how far the plates close in.
    """

    force: float
    radius: float
    modulus: float
    half_width: float
    peak_pressure: float
    approach: float


def _solution(force: float, radius: float, es: float) -> LineContactSolution:
    b = math.sqrt(4.0 * force * radius / (math.pi * es))
    delta = 2.0 * force / (math.pi * es) * (2.0 * math.log(4.0 * radius / b) - 1.0)
    return LineContactSolution(force, radius, es, b, 2.0 * force / (math.pi * b), delta)


def cylinder_between_plates(
    radius: float,
    E: float,
    nu: float,
    *,
    force: float | None = None,
    approach: float | None = None,
) -> LineContactSolution:
    """The line contact of a cylinder between plates, for a force per length or an approach.

    Parameters
    ----------
    radius, E, nu : float
        The cylinder (m, Pa, -); plane strain.
    force : float, optional
        Force per unit length ``P'`` (N/m).
    approach : float, optional
        Total approach ``delta`` of the plates (m); ``P'`` is then the root of the
        relation, sought where ``b <= R``.

    Returns
    -------
    LineContactSolution
    """
    es = effective_modulus(E, nu)
    if not radius > 0 or (force is None) == (approach is None):
        raise ContactError("give a positive radius and exactly one of force and approach")
    if force is not None:
        if not force > 0:
            raise ContactError(f"force must be positive, got {force!r}")
        return _solution(force, radius, es)
    top = 0.25 * math.pi * es * radius  # b = R
    if not 0 < approach < _solution(top, radius, es).approach:  # type: ignore[operator]
        raise ContactError(f"approach must give b < R, got {approach!r}")
    p = so.brentq(
        lambda f: _solution(f, radius, es).approach - approach, 1e-12 * top, top, xtol=1e-15 * top
    )
    return _solution(float(p), radius, es)


def quarter_cylinder_mesh(
    radius: float,
    fine_size: float,
    fine_extent: float,
    *,
    thickness: float | None = None,
    layers: int = 1,
    coarse_size: float | None = None,
    growth: float = 1.25,
) -> fem.Mesh:
    """Bricks of the quarter cylinder ``x, y >= 0, x^2 + y^2 <= R^2, 0 <= z <= H``.

    Graded toward the line ``(0, R, z)``: the quarter disc is the face ``y = 0`` of the
    octant of :func:`fem.generators.graded_ball_mesh` (its pole turned to ``+y``), with
    its grading parameters, extruded by ``layers`` cells.

    Parameters
    ----------
    radius : float
        ``R`` (m).
    fine_size, fine_extent, coarse_size, growth : float
        As for :func:`fem.generators.graded_ball_mesh` (``fine_extent`` its
        ``fine_radius``).
    thickness : float, optional
        ``H`` (m); ``fine_size * layers`` by default.
    layers : int
        Cells along z.

    Returns
    -------
    fem.Mesh
        Hexahedra with positive Jacobians.
    """
    if layers < 1:
        raise ContactError(f"layers must be at least 1, got {layers!r}")
    h = fine_size * layers if thickness is None else float(thickness)
    ball = graded_ball_mesh(
        radius, fine_size, fine_extent, coarse_size=coarse_size, growth=growth, part="octant"
    )
    p = ball.points
    quads = ball.boundary.faces["quad"]
    quads = quads[(np.abs(p[quads, 1]) <= 1e-9 * radius).all(axis=1)]
    used = np.unique(quads)
    renum = np.full(len(p), -1, dtype=np.int64)
    renum[used] = np.arange(used.size)
    xy = np.column_stack([p[used, 0], -p[used, 2]])  # the pole (0, 0, -R) to (0, R)
    quads = renum[quads]
    c = xy[quads]
    area2 = c[..., 0] * np.roll(c[..., 1], -1, axis=1) - np.roll(c[..., 0], -1, axis=1) * c[..., 1]
    cw = area2.sum(axis=1) < 0
    quads[cw] = quads[cw][:, ::-1]  # counter-clockwise seen from +z: the bricks' bottoms
    n = used.size
    zs = np.linspace(0.0, h, layers + 1)
    pts = np.concatenate([np.column_stack([xy, np.full(n, z)]) for z in zs])
    hexes = np.concatenate([np.hstack([quads + k * n, quads + (k + 1) * n]) for k in range(layers)])
    return fem.Mesh(pts, {"hexahedron": hexes})


@dataclass(frozen=True)
class LineContactCheck:
    """A quarter cylinder slab against the plate, measured against the line contact.

    Attributes
    ----------
    mesh : fem.Mesh
    body : ElasticBody
    plate : Plane
    result : ContactResult
    force : float
        The FE force per length ``P' = 2 F / H`` (N/m).
    theory : LineContactSolution
        For the prescribed approach.
    half_width : float
        The FE contact half-width from the second moment of the nodal forces across
        the patch, ``b^2 = 4 (sum f x^2 / sum f - h^2 / 6)``, ``h`` the fine size (the
        linear interpolation's excess of ``x^2``; the Hertz profile has ``b^2 / 4``).
    seconds : dict of str to float
        ``mesh``, ``body`` and ``contact`` times.
    """

    mesh: fem.Mesh
    body: ElasticBody
    plate: Plane
    result: ContactResult
    force: float
    theory: LineContactSolution
    half_width: float
    seconds: dict[str, float] = field(default_factory=dict)

    @property
    def error(self) -> float:
        """Relative error of the force per length at the prescribed approach."""
        return self.force / self.theory.force - 1.0

    @property
    def half_width_error(self) -> float:
        """Relative error of the half-width against the theory's for the FE force."""
        b = math.sqrt(4.0 * self.force * self.theory.radius / (math.pi * self.theory.modulus))
        return self.half_width / b - 1.0


def line_contact_check(
    radius: float = 1.0,
    E: float = 1.0,
    nu: float = 0.3,
    *,
    approach: float,
    fine_size: float,
    fine_extent: float | None = None,
    layers: int = 1,
    coarse_size: float | None = None,
    growth: float = 1.25,
) -> LineContactCheck:
    """Compress the quarter cylinder slab and compare its force per length (module notes).

    Parameters
    ----------
    radius, E, nu : float
        The cylinder (m, Pa, -).
    approach : float
        Total approach of the two plates (m); ``b / R`` of about 0.05 to 0.1 is the
        regime of the theory.
    fine_size : float
        Cell size at the contact line (m).
    fine_extent : float, optional
        Extent of the fine zone: ``1.5 b`` of the theory by default, within
        ``[fine_size, 0.4 R]``.
    layers : int
        Cells along the axis (the slab is ``layers * fine_size`` thick).
    coarse_size, growth : float
        Grading (see :func:`quarter_cylinder_mesh`).

    Returns
    -------
    LineContactCheck
    """
    theory = cylinder_between_plates(radius, E, nu, approach=approach)
    fe = 1.5 * theory.half_width if fine_extent is None else fine_extent
    fe = min(max(fe, fine_size), 0.4 * radius)
    t0 = time.perf_counter()
    mesh = quarter_cylinder_mesh(
        radius, fine_size, fe, layers=layers, coarse_size=coarse_size, growth=growth
    )
    t1 = time.perf_counter()
    p = mesh.points
    tol = 1e-9 * radius
    h = float(p[:, 2].max())
    ends = np.flatnonzero((np.abs(p[:, 2]) <= tol) | (np.abs(p[:, 2] - h) <= tol))
    held = np.concatenate(
        [
            3 * np.flatnonzero(np.abs(p[:, 0]) <= tol),
            3 * np.flatnonzero(np.abs(p[:, 1]) <= tol) + 1,
            3 * ends + 2,
        ]
    )
    body = ElasticBody("cylinder", mesh, fem.LinearElastic(E, nu), prescribed=np.unique(held))
    t2 = time.perf_counter()
    plate = Plane([0, radius, 0], [0, -1, 0], motion=[0, -0.5 * approach, 0], name="plate")
    result = solve_rigid_contact(body, [plate])
    t3 = time.perf_counter()
    force = 2.0 * float(result.obstacle_forces["plate"][1]) / h
    f = result.contact_force[:, 1]
    moment = float((f * p[:, 0] ** 2).sum() / f.sum())
    b_fe = math.sqrt(max(4.0 * (moment - fine_size**2 / 6.0), 0.0))
    secs = {"mesh": t1 - t0, "body": t2 - t1, "contact": t3 - t2}
    return LineContactCheck(mesh, body, plate, result, force, theory, b_fe, secs)
