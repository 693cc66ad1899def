"""Friction verified: a hemisphere sheared on a rigid table, against Cattaneo-Mindlin.

The model (:func:`squeezed_hemisphere`) is the lower half of a ball of radius ``R`` whose
equator face is held (all three directions: a rigid cap driven by the load frame), meshed
fine at its pole (:func:`fem.generators.graded_ball_mesh`). Frame 1 raises the table
``z = 0`` by ``depth`` at ``mu = 0``: a Hertz contact, with the radial slip of the squeeze
already done, so the normal and tangential problems start uncoupled. Later frames move the
table along x by a shift ``s`` with friction on, carrying the anchors from frame to frame;
the tangential load ``Q`` is what the table then gives the ball. Being displacement
driven, a load is reached by a secant search on ``s`` (:meth:`Hemisphere.load`), each trial
solved from the same anchors.

The hemisphere's own shear adds ``C Q`` to ``s``, linear in ``Q``: at ``Q = 0`` it is gone,
so the shift left after loading to ``Q*`` and unloading (Mindlin and Deresiewicz 1953) is
the contact's alone, against the analytic residual of :mod:`contact.cases.mindlin_theory`.
The stick radius is read from the nodes' stick/slip status (:func:`measure_stick_zone`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

import fem
from fem.generators import graded_ball_mesh

from ..errors import ContactError
from ..geometry.plane import Plane
from ..solver.anchors import Anchors
from ..solver.body import ElasticBody
from ..solver.iteration import solve_frame
from ..solver.pairs import ContactPair
from ..solver.results import FrameResult
from ..solver.settings import ContactSettings
from .contact_patch import interpolation_excess
from .mindlin_theory import MindlinSolution, mindlin_sphere_on_plane

__all__ = [
    "CattaneoCheck",
    "Hemisphere",
    "MindlinDeresiewiczCheck",
    "StickZone",
    "cattaneo_check",
    "measure_stick_zone",
    "mindlin_deresiewicz_check",
    "squeezed_hemisphere",
]

#: Tangential load a search stops within, as a fraction of ``mu P``.
LOAD_TOLERANCE = 1e-5
#: Trials a search makes at most.
MAX_TRIALS = 12


@dataclass(frozen=True)
class StickZone:
    """Stick and slip of the contact nodes against one plane, with the patch's loads.

    Attributes
    ----------
    force : float
        Normal force ``P`` on the ball (N).
    load : float
        Tangential force ``Q`` on the ball along the load direction (N).
    stick_outer : float
        Radius of the outermost stick node (m).
    slip_inner : float
        Radius of the innermost slip node (m); ``inf`` where none slips.
    stick_radius : float
        ``(stick_outer + slip_inner) / 2``: the stick radius from the status (m).
    stick_radius_area : float
        ``sqrt(A_stick / pi)``, ``A_stick`` the stick nodes' tributary area (m).
    contact_radius_area : float
        ``sqrt(A / pi)`` over every closed contact node (m).
    load_radius : float
        Second-moment radius of the normal forces, ``sqrt(5/2 sum n r^2 / sum n)`` with
        the interpolation excess removed (m): the Hertz radius on the FE forces.
    traction_radius : float
        The same of the tangential forces along the load (m); NaN where they add up to
        next to nothing (``Q = 0``).
    stick, slip : int
        Counts of stick and slip nodes.
    """

    force: float
    load: float
    stick_outer: float
    slip_inner: float
    stick_radius: float
    stick_radius_area: float
    contact_radius_area: float
    load_radius: float
    traction_radius: float
    stick: int
    slip: int


def _facing(mesh: fem.Mesh, normal: NDArray, nodes: NDArray[np.int64]) -> list[NDArray]:
    """Boundary faces touching ``nodes`` whose outward normal is within 60 deg of ``-normal``."""
    on = np.zeros(mesh.n_points, dtype=bool)
    on[nodes] = True
    out = []
    for f in mesh.boundary.faces.values():
        x = mesh.points[f]
        if f.shape[1] == 4:
            nf = np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 1])
        else:
            nf = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
        cos = -(nf @ normal) / np.linalg.norm(nf, axis=1)
        out.append(f[(cos > 0.5) & on[f].any(axis=1)])
    return out


def measure_stick_zone(
    mesh: fem.Mesh,
    result: FrameResult,
    body: str,
    plane: Plane,
    direction: NDArray | tuple[float, float, float] = (1.0, 0.0, 0.0),
    center: NDArray | tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> StickZone:
    """Read the stick zone and the patch's radii from a frame's nodal contact fields.

    ``r`` is each closed contact node's undeformed distance from the axis through
    ``center`` along the plane's normal. Stick and slip come from ``contact_status`` (the
    slip increment of this frame: a node that stuck since the anchors of the previous
    frame sticks). The tributary areas and interpolation excess are those of
    :func:`contact.cases.contact_patch.interpolation_excess` on the faces facing the plane.

    Raises
    ------
    ContactError
        If no node sticks, or fewer than three nodes are closed.
    """
    fields = result.contact_fields[body]
    status = fields["contact_status"]
    nodes = np.flatnonzero(status > 0)
    if nodes.size < 3:
        raise ContactError(f"{plane.name}: {nodes.size} closed contact nodes, too few to measure")
    nrm = plane.normal
    ctr = np.asarray(center, dtype=np.float64)
    d = mesh.points[nodes] - ctr
    r2 = np.einsum("ij,ij->i", d, d) - (d @ nrm) ** 2
    r = np.sqrt(r2)
    area, excess = interpolation_excess(mesh, _facing(mesh, nrm, nodes), ctr, nrm)
    n = fields["normal_force"][nodes]
    t = fields["tangential_force"][nodes] @ np.asarray(direction, dtype=np.float64)
    stick = status[nodes] == 1
    if not stick.any():
        raise ContactError(f"{plane.name}: no node sticks")
    outer = float(r[stick].max())
    inner = float(r[~stick].min()) if (~stick).any() else math.inf
    edge = outer if math.isinf(inner) else 0.5 * (outer + inner)
    rc2 = r2 - excess[nodes]
    spread = math.nan  # a self-equilibrated traction (Q = 0) has no moment radius
    if t.sum() > 1e-3 * np.abs(t).sum():
        spread = math.sqrt(2.5 * float(t @ rc2) / float(t.sum()))
    return StickZone(
        force=float(n.sum()),
        load=float(t.sum()),
        stick_outer=outer,
        slip_inner=inner,
        stick_radius=edge,
        stick_radius_area=math.sqrt(float(area[nodes][stick].sum()) / math.pi),
        contact_radius_area=math.sqrt(float(area[nodes].sum()) / math.pi),
        load_radius=math.sqrt(2.5 * float(n @ rc2) / float(n.sum())),
        traction_radius=spread,
        stick=int(stick.sum()),
        slip=int((~stick).sum()),
    )


@dataclass
class Hemisphere:
    """A hemisphere squeezed on a rigid table at ``mu = 0`` (frame 1), ready to shear.

    Attributes
    ----------
    body : ElasticBody
        The lower half ball, equator face held.
    radius, E, nu, friction, depth : float
        The ball, Coulomb's ``mu`` of the shear frames, the table's rise (m).
    squeezed : FrameResult
        Frame 1.
    theory : MindlinSolution
        Cattaneo-Mindlin for frame 1's normal force.
    solves : int
        Frictional frames solved so far (search trials included).
    """

    body: ElasticBody
    radius: float
    E: float
    nu: float
    friction: float
    depth: float
    squeezed: FrameResult = field(init=False)
    theory: MindlinSolution = field(init=False)
    solves: int = 0

    def table(self, shift: float = 0.0) -> Plane:
        """The table raised by ``depth`` and moved by ``shift`` along x."""
        return Plane([0, 0, 0], [0, 0, 1], motion=[shift, 0, self.depth], name="table")

    def solve(self, shift: float, anchors: Anchors | None, friction: float) -> FrameResult:
        """One frame with the table at ``shift``; raises ContactError unless converged."""
        table = self.table(shift)
        pair = ContactPair(self.body, table, friction=friction)
        res = solve_frame([self.body], [pair], [table], ContactSettings(), anchors=anchors)
        if not res.converged:
            raise ContactError(f"shift {shift:.6g}: {res.stop_reason}")
        if friction > 0:
            self.solves += 1
        return res

    def zone(self, result: FrameResult) -> StickZone:
        """The stick zone of a frame (:func:`measure_stick_zone`, load along +x)."""
        return measure_stick_zone(self.body.mesh, result, self.body.name, self.table())

    def tangential_load(self, result: FrameResult) -> float:
        """``Q``: the force along x the table gives the ball (N)."""
        return -float(result.obstacle_forces["table"][0])

    def load(
        self, target: float, anchors: Anchors, known: list[tuple[float, float]], guess: float
    ) -> tuple[float, FrameResult]:
        """The shift at which the table gives the load ``target``, and its frame.

        A secant search on ``Q(s)`` (monotone), every trial solved from ``anchors``;
        ``known`` holds points ``(s, Q)`` already solved from them, ``guess`` a first shift.

        Raises
        ------
        ContactError
            If ``MAX_TRIALS`` trials do not bring ``Q`` within ``LOAD_TOLERANCE mu P``.
        """
        tol = LOAD_TOLERANCE * self.theory.limit
        pts = list(known)
        s = guess
        for _ in range(MAX_TRIALS):
            res = self.solve(s, anchors, self.friction)
            q = self.tangential_load(res)
            if abs(q - target) <= tol:
                return s, res
            pts.append((s, q))
            (s0, q0), (s1, q1) = sorted(pts, key=lambda p: abs(p[1] - target))[:2]
            s = s1 + (target - q1) * (s1 - s0) / (q1 - q0)
        raise ContactError(f"no shift gives Q = {target:.6g} within {MAX_TRIALS} trials")


def squeezed_hemisphere(
    radius: float = 1.0,
    E: float = 1.0,
    nu: float = 0.45,
    *,
    friction: float = 0.5,
    depth: float = 0.01,
    fine_size: float,
    fine_radius: float | None = None,
    coarse_size: float | None = None,
    growth: float = 1.25,
) -> Hemisphere:
    """Mesh the hemisphere, hold its equator and squeeze it on the table at ``mu = 0``.

    Parameters
    ----------
    radius, E, nu : float
        The ball (m, Pa). ``nu = 0.45`` keeps Dundurs' coupling small (``beta`` 0.09).
    friction : float
        Coulomb's ``mu`` of the shear frames.
    depth : float
        How far the table rises (m): ``a`` is about ``sqrt(depth R)``.
    fine_size : float
        Cell size at the pole (m): ``a / fine_size`` cells across the contact radius.
    fine_radius : float, optional
        Radius of the fine zone, ``1.3 sqrt(depth R)`` by default (at most ``0.4 R``).
    coarse_size, growth : float
        Grading of the mesh (:func:`fem.generators.graded_ball_mesh`).

    Returns
    -------
    Hemisphere
    """
    if not 0 < depth < 0.1 * radius:
        raise ContactError(f"depth must lie in (0, 0.1 radius), got {depth!r}")
    fr = min(1.3 * math.sqrt(depth * radius), 0.4 * radius) if fine_radius is None else fine_radius
    mesh = graded_ball_mesh(
        radius,
        fine_size,
        max(fr, fine_size),
        coarse_size=coarse_size,
        growth=growth,
        part="half",
        center=(0.0, 0.0, radius),
    )
    cap = np.flatnonzero(np.abs(mesh.points[:, 2] - radius) <= 1e-9 * radius)
    body = ElasticBody("ball", mesh, fem.LinearElastic(E, nu), prescribed=fem.node_dofs(cap))
    model = Hemisphere(body, radius, E, nu, friction, depth)
    model.squeezed = model.solve(0.0, None, 0.0)
    force = -float(model.squeezed.obstacle_forces["table"][2])
    model.theory = mindlin_sphere_on_plane(force, friction, radius, E, nu)
    return model


def _guess(model: Hemisphere, load: float) -> float:
    """A first shift for ``load``: the contact's analytic shift (the bulk's adds to it)."""
    return model.theory.shift(min(load, 0.99 * model.theory.limit))


@dataclass(frozen=True)
class CattaneoCheck:
    """The hemisphere sheared to ``Q = ratio mu P`` in one frame from the squeeze.

    Attributes
    ----------
    ratio : float
        ``Q / (mu P)`` aimed at.
    shift : float
        The table's shift that gives it (m).
    result : FrameResult
    zone : StickZone
    theory : MindlinSolution
        Cattaneo-Mindlin for the frame's own normal force.
    """

    ratio: float
    shift: float
    result: FrameResult
    zone: StickZone
    theory: MindlinSolution

    @property
    def stick_ratio(self) -> float:
        """Measured ``c / a`` (status edge), ``a`` Hertz's radius for the frame's force."""
        return self.zone.stick_radius / self.theory.hertz.contact_radius

    @property
    def stick_ratio_theory(self) -> float:
        """``(1 - Q / (mu P))^(1/3)`` for the frame's own ``Q`` and ``P``."""
        return self.theory.stick_radius(self.zone.load) / self.theory.hertz.contact_radius

    @property
    def stick_error(self) -> float:
        """Relative error of the status-edge stick radius."""
        return self.stick_ratio / self.stick_ratio_theory - 1.0

    @property
    def area_error(self) -> float:
        """Relative error of the stick radius from the stick nodes' area."""
        return self.zone.stick_radius_area / self.theory.stick_radius(self.zone.load) - 1.0

    @property
    def traction_error(self) -> float:
        """Relative error of ``traction_radius / load_radius`` against the analytic ratio.

        How the tangential traction spreads over the patch, measured on the FE forces.
        """
        hz = self.theory.hertz
        theory = self.theory.traction_radius(self.zone.load) / hz.contact_radius
        return self.zone.traction_radius / self.zone.load_radius / theory - 1.0


def cattaneo_check(model: Hemisphere, ratio: float) -> CattaneoCheck:
    """Shear the squeezed hemisphere to ``Q = ratio mu P`` and measure its stick zone."""
    if not 0 < ratio < 1:
        raise ContactError(f"ratio must lie in (0, 1), got {ratio!r}")
    target = ratio * model.theory.limit
    anchors = model.squeezed.anchors
    shift, res = model.load(target, anchors, [(0.0, 0.0)], _guess(model, target))
    zone = model.zone(res)
    theory = mindlin_sphere_on_plane(zone.force, model.friction, model.radius, model.E, model.nu)
    return CattaneoCheck(ratio, shift, res, zone, theory)


@dataclass(frozen=True)
class MindlinDeresiewiczCheck:
    """Loading to ``Q*`` and back to ``Q = 0``, frame by frame, carrying the anchors.

    Attributes
    ----------
    peak : float
        ``Q* / (mu P)``.
    peak_shift, residual_shift : float
        The table's shift at ``Q*`` and where ``Q`` is back to 0 (m).
    peak_zone, end_zone : StickZone
        Stick zones of the loading frame and of the unloading frame (stick there: stuck
        since the peak).
    theory : MindlinSolution
        For the squeeze's normal force.
    """

    peak: float
    peak_shift: float
    residual_shift: float
    peak_zone: StickZone
    end_zone: StickZone
    theory: MindlinSolution

    @property
    def residual_theory(self) -> float:
        """Mindlin-Deresiewicz's residual shift for the reached ``Q*`` (m)."""
        return self.theory.residual_shift(self.peak_zone.load)

    @property
    def residual_error(self) -> float:
        """Relative error of the residual shift."""
        return self.residual_shift / self.residual_theory - 1.0

    @property
    def end_stick_ratio(self) -> float:
        """Measured radius of what stuck since the peak over Hertz's ``a``."""
        return self.end_zone.stick_radius / self.theory.hertz.contact_radius

    @property
    def end_stick_ratio_theory(self) -> float:
        """``(1 - Q* / (2 mu P))^(1/3)``."""
        q = self.peak_zone.load
        return self.theory.unloading_stick_radius(0.0, q) / self.theory.hertz.contact_radius


def mindlin_deresiewicz_check(model: Hemisphere, peak: float = 0.9) -> MindlinDeresiewiczCheck:
    """Load the squeezed hemisphere to ``Q* = peak mu P`` (frame 2), unload to 0 (frame 3)."""
    if not 0 < peak < 1:
        raise ContactError(f"peak must lie in (0, 1), got {peak!r}")
    th = model.theory
    target = peak * th.limit
    s_peak, top = model.load(target, model.squeezed.anchors, [(0.0, 0.0)], _guess(model, target))
    q_peak = model.tangential_load(top)
    # the shear of the bulk is linear and leaves with Q: start at the contact's residual
    s_end, end = model.load(0.0, top.anchors, [(s_peak, q_peak)], th.residual_shift(q_peak))
    return MindlinDeresiewiczCheck(peak, s_peak, s_end, model.zone(top), model.zone(end), th)
