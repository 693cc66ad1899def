"""Finite-strain frames: Newton's method on equilibrium, each linearisation solved in contact space.

A neo-Hookean body (:class:`FiniteBody`, the law of :mod:`fem.hyperelastic`) is in balance
at displacements ``u`` when ``f_int(u) = f_ext(u) + E(u)^T lambda``, its contacts closed
where they push. Each Newton step linearises every such body at its current placement
``x = X + u``: an :class:`~contact.solver.body.ElasticBody` whose mesh is the deformed one
(so that the contact search, the gaps and the normals are measured there), whose
stiffness is the tangent ``K_T(u)`` (with a follower pressure's) and whose loads are the
forces out of balance ``f_ext(u) - f_int(u)``. The linear frame
(:func:`contact.solver.iteration.solve_frame`) solves its contacts: its displacements are
the step ``du``, its contact forces the total ones. The step is shortened where it would
turn a cell inside out. Newton stops where the error a step leaves (from its rate,
:class:`~.newtonrate.StepErrors`) is round-off of the body's size and the forces out of
balance, contact forces included, round-off of the frame's largest force.

Linear bodies may take part: each linearisation solves them whole, as a frame does.

A compressed body's full tangent is not positive definite on its own: a column fixed at
its base sways, a free body's turn moves its forces. Every body takes its full tangent; a
supported one plus springs along its last contacts closed on planes (:func:`_springs`),
which change nothing of a step along those rows. Where the full tangent cannot be
factored or its linear frame fails, the step takes the material tangent
(:func:`fem.finite_strain` with ``tangent="material"``), whose null space is exactly the
rigid modes. A free body's full tangent does not vanish on its turns: with friction its
frames border it with its turn stiffness (:class:`fem.TurningInverse`,
:meth:`contact.solver.delassus.ContactSpace.border`); one whose steps still shrink only
at a linear rate takes the material tangent (:func:`contact.solver.newtonrate.linear_rate`).
A free body's step turns it by a finite rotation, at most :data:`MAX_TURN` (:func:`_turned`).
Newton stops as stalled where its residual no longer halves (:data:`STALL`). Friction's
slip is measured from the previous frame's anchors and from where the frame's steps first
met each contact, in every step (:meth:`contact.solver.anchors.Anchors.keeping`); without
friction, once a contact flips (:class:`~.newtonrate.Flips`) each step searches from where
the last left the linear bodies. Force-driven planes are placed by every step's solve.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

import fem
from fem.follower import follower_pressure

from ..errors import ContactError
from ..geometry.plane import Plane
from .anchors import Anchors
from .body import ElasticBody
from .damping import Damping
from .iteration import solve_frame
from .newtonrate import ANDERSON_FROM, Flips, StepErrors, anderson, linear_rate, slow
from .pairs import ContactPair
from .results import FrameResult, IterationRecord
from .settings import ContactSettings

__all__ = ["FiniteBody", "FiniteFrame", "solve_finite_frame"]

log = logging.getLogger(__name__)

#: Newton steps a frame may take.
MAX_NEWTON = 30
#: A step leaving an error below this fraction of the body's size (``StepErrors``), with
#: the residual below :data:`RESIDUAL` of the forces, has converged.
STEP_TOL = 1e-9
RESIDUAL = 1e-8
#: Halvings of a step that would turn a cell inside out.
HALVINGS = 20
#: The largest turn (rad) of a free body in one Newton step: a longer step is shortened.
MAX_TURN = 0.1
#: Newton stops as stalled where the residual's least value over its last ``STALL``
#: steps is not half the least before them: a cycling contact set, a linear rate too
#: slow to finish (a frame is then cut into smaller steps of time by the run).
STALL = 6


@dataclass(frozen=True)
class FiniteBody:
    """A neo-Hookean body: its reference mesh, materials, supports and loads.

    Parameters are those of :class:`~contact.solver.body.ElasticBody` (the materials'
    ``E, nu`` give the law's ``lambda, mu``), and ``follower``: a pressure on faces that
    follows their deformation, ``(faces, pressure)`` with the faces counter-clockwise
    seen from where it pushes (a hollow ball's inner surface, closed).
    """

    name: str
    mesh: fem.Mesh
    materials: fem.LinearElastic | Mapping[int, fem.LinearElastic]
    prescribed: NDArray[np.int64] | None = None
    loads: NDArray[np.float64] | None = None
    follower: tuple[fem.BoundaryFaces | Mapping[str, ArrayLike], float] | None = None
    contact_faces: fem.BoundaryFaces | None = None
    supports: Mapping[str, ArrayLike] = field(default_factory=dict)

    @classmethod
    def of(
        cls,
        body: ElasticBody,
        follower: tuple[fem.BoundaryFaces, float] | None = None,
    ) -> FiniteBody:
        """The neo-Hookean body of ``body``'s mesh, materials, supports and loads."""
        pres = np.flatnonzero(body.fixed_dofs)
        return cls(
            body.name, body.mesh, body.materials, prescribed=pres if pres.size else None,
            loads=body.loads, follower=follower, contact_faces=body.contact_faces,
            supports=body.supports,
        )  # fmt: skip

    @property
    def free(self) -> bool:
        """True when nothing but contacts holds the body."""
        return self.prescribed is None

    def linearised(
        self, u: NDArray[np.float64], springs: sp.spmatrix | None = None, full: bool = True
    ) -> ElasticBody:
        """The body linearised at displacements ``u`` (see the module docstring).

        ``springs``: a stiffness added to the tangent (the last closed contacts', see
        :func:`_springs`). ``full``: the full tangent (with a follower pressure's), else
        the material tangent alone, positive semidefinite with the rigid modes of the
        placement as its null space.
        """
        state = fem.finite_strain(
            self.mesh, self.materials, u, tangent="full" if full else "material"
        )
        f_ext = np.zeros(self.mesh.n_dofs) if self.loads is None else self.loads.copy()
        k = state.stiffness
        if self.follower is not None:
            f_p, k_p = follower_pressure(self.mesh, *self.follower, u, closed=True)
            f_ext += f_p
            if full:
                k = (k + k_p).tocsr()
        if springs is not None and springs.nnz and not self.free:
            k = (k + springs).tocsr()
        placed = fem.Mesh(self.mesh.points + u.reshape(-1, 3), self.mesh.cells, self.mesh.regions)
        body = ElasticBody(
            self.name, placed, self.materials, prescribed=self.prescribed,
            loads=f_ext - state.force, contact_faces=self.contact_faces,
            supports=self.supports, stiffness=k,
        )  # fmt: skip
        body.turns_freely = True
        return body


@dataclass(frozen=True)
class FiniteFrame:
    """A finite-strain frame's answer.

    Attributes
    ----------
    result : FrameResult
        The last linearisation's frame: its contacts and forces are the frame's, its
        displacements the last step's.
    displacement : dict of str to ndarray
        Each body's displacement ``(N, 3)`` from its reference (m).
    steps : int
        Newton steps.
    converged : bool
    stop_reason : str
        ``"converged"``, or why Newton stopped (a linearisation's own stop reason, or
        the step limit with the last residual).
    residual : float
        The last largest force out of balance over the frame's largest force.
    timings : dict of str to float
        Seconds in linearising (the tangents' assembly), in the linear frames, and in
        checking the steps (residuals, cells turned inside out).
    """

    result: FrameResult
    displacement: dict[str, NDArray[np.float64]]
    steps: int
    converged: bool
    stop_reason: str
    residual: float
    timings: dict[str, float] = field(default_factory=dict)

    def frame_result(self) -> FrameResult:
        """The frame as a linear frame reads: total displacements, Newton's verdict and timings."""
        res = self.result
        held = res.held if self.converged or res.held is False else None  # short: unknown
        return replace(
            res, displacement={**res.displacement, **self.displacement},
            converged=self.converged, held=held,
            stop_reason=res.stop_reason if self.converged else self.stop_reason,
            timings={**self.timings, "total": sum(self.timings.values())},
        )  # fmt: skip


def solve_finite_frame(
    bodies: Sequence[FiniteBody | ElasticBody],
    pairs: Sequence[ContactPair],
    planes: Sequence[Plane] = (),
    settings: ContactSettings | None = None,
    *,
    start: Mapping[str, ArrayLike] | None = None,
    max_steps: int = MAX_NEWTON,
    anchors: Anchors | None = None,
    callback: Callable[[IterationRecord], None] | None = None,
) -> FiniteFrame:
    """Resolve one frame's contacts with finite-strain bodies by Newton's method.

    Parameters
    ----------
    bodies : sequence of FiniteBody or ElasticBody
    pairs : sequence of ContactPair
        As for :func:`~contact.solver.iteration.solve_frame`, naming these bodies.
    planes : sequence of Plane
    settings : ContactSettings, optional
    start : mapping of str to array_like, optional
        Finite bodies' displacements to start from (the last frame's), zero otherwise.
    max_steps : int
    anchors : Anchors, optional
        The previous frame's stick anchors (its ``result.anchors``), for friction. Every
        Newton step measures slip from them and from where the frame's steps first met
        each new contact, the finite bodies placed at the frame's start.
    callback : callable, optional
        Called with each linear frame's iteration records (progress).

    Raises
    ------
    ContactError
        Where the first linearisation's tangent cannot be factored (a body that is not
        stable at its starting placement). A later step's that cannot stops the frame
        where the step before left it, not converged.
    """
    finite = [b for b in bodies if isinstance(b, FiniteBody)]
    u = {
        b.name: np.asarray((start or {}).get(b.name, np.zeros(b.mesh.n_dofs)), float).ravel()
        for b in finite
    }
    size = {b.name: float(np.ptp(b.mesh.points, axis=0).max()) for b in finite}
    # every step measures slip from the frame's start and the anchors its steps met
    anchors = (anchors or Anchors()).starting(u, {b.name: b.mesh.points for b in finite})
    res, residual, stop = None, np.inf, "iteration limit"
    last: FrameResult | None = None
    near: dict[str, NDArray] = {}
    flips = Flips()
    springs: dict[str, sp.csr_matrix] = {}
    history: list[tuple[NDArray, NDArray]] = []
    lin: dict[str, ElasticBody] = {}
    clock = {"linearise": 0.0, "linear frames": 0.0, "checks": 0.0}
    rigid = {p.name for p in pairs if p.rigid}
    material_until, slow_full = 0, set()
    last_move: dict[str, list[float]] = {b.name: [] for b in finite}
    residuals: list[float] = []
    swung = 0
    damping = Damping()  # the free bodies' steps' springs (contact.solver.damping)
    errors = StepErrors()
    free = [b.name for b in finite if b.free]
    step = 0
    while step < max_steps:
        step += 1
        full = {b.name: step > material_until and b.name not in slow_full for b in finite}

        # the last step's bodies and their factorisations go before the next are made
        # (no cycle holds them: tests/solver/test_no_cycles.py)
        lin = now = paired = None  # type: ignore[assignment]
        t0 = time.perf_counter()
        lin = {b.name: b.linearised(u[b.name], springs.get(b.name), full[b.name]) for b in finite}
        t1 = time.perf_counter()
        clock["linearise"] += t1 - t0
        now = [lin.get(b.name, b) for b in bodies]
        paired = [
            replace(p, slave=lin.get(p.slave.name, p.slave),
                    master=lin.get(p.master.name, p.master) if not p.rigid else p.master)
            for p in pairs
        ]  # fmt: skip
        try:
            res = solve_frame(
                now, paired, planes, settings, anchors=anchors, callback=callback,
                search_from=near, slip_from=True,
                prox=damping.springs(free),
            )  # fmt: skip
        except fem.SolverError as exc:
            res, stop = None, f"a finite body's tangent could not be factored at this strain: {exc}"
        finally:
            t2 = time.perf_counter()
            clock["linear frames"] += t2 - t1
        unsettled = res is not None and not res.converged and res.held is not False
        if unsettled and res.friction is not None and free and damping.unsettled():
            # a free body friction does not place (a ball pinched at two points, nearly
            # free to swing about them): the step again, damped
            log.debug("Newton step %d: %s: damped by %g", step, res.stop_reason, damping.prox)
            step -= 1
            continue
        if any(full.values()) and (res is None or not (res.converged or res.held is False)):
            # the full tangent is not positive definite here (a compressed body, a
            # pressure not yet carried): this step and the next take the material one
            log.debug("Newton step %d: the full tangent failed (%s): material tangent",
                      step, stop if res is None else res.stop_reason)
            material_until, step = step + 1, step - 1
            continue
        if res is None:
            res = last  # a later step's tangent failed: the frame stops at the last step's
            break
        # each free body's step's rigid part (t, omega), at its placement
        parts = {b.name: fem.rigid_part(b.mesh.points + u[b.name].reshape(-1, 3),
                                        res.displacement[b.name].reshape(-1, 3))
                 for b in finite if b.free}  # fmt: skip
        motion = max((_motion(*parts[n], size[n]) for n in parts), default=0.0)
        if res.converged and res.friction is not None and damping.too_far(motion):
            # a free body far from its balance: the step again, damped to move it less
            log.debug("Newton step %d: moves %.3g: damped by %g", step, motion, damping.prox)
            step -= 1
            continue
        last = res
        # frictionless, once a contact flips: the next step's first search looks at the
        # linear bodies where this one left them (what it closed stays a candidate)
        if flips.add(res.contacts):
            near = {b.name: res.displacement[b.name] for b in bodies if b.name not in u}
        springs = {b.name: _springs(b, res, lin[b.name], rigid) for b in finite}
        if res.slip_from is not None:
            anchors = anchors.keeping(res.slip_from)
        if not res.converged:
            if res.held is False and res.friction is not None and free and damping.unheld(res, u):
                # not held where it is: followed, damped, toward where its contacts may be
                log.debug("Newton step %d: %s: damped by %g", step, res.stop_reason,
                          damping.prox)  # fmt: skip
                step -= 1
                continue
            stop = res.stop_reason
            log.debug("Newton step %d: the linear frame stopped: %s", step, stop)
            break
        moves, left = {}, {}
        steps_now = {b.name: res.displacement[b.name].ravel() for b in finite}
        # mixing takes up the material tangent's linear rate; the full tangent's own steps
        # are left whole (mixed, a squeezed ball's cycle between contact sets grows)
        on_material = [b.name for b in finite if b.free and not full[b.name]]
        mixed = anderson(history, u, steps_now, on_material)
        if step < ANDERSON_FROM or not slow(history):
            mixed = {}
        out_of_balance, scale = 0.0, 1e-300
        damp = damping.prox
        for b in finite:
            du = steps_now[b.name]
            moves[b.name] = float(np.abs(du).max(initial=0.0)) / size[b.name]
            if b.name in mixed:
                target = mixed[b.name] - u[b.name]
            elif b.free:
                target, short = _turned(b, u[b.name], du, parts[b.name])
                if short:
                    swung = step  # the body is still on its way
            else:
                target = du
            u[b.name], f_int = _stepped(b, u[b.name], target)
            held = b.free and res.friction is None  # frictionless: its turn held
            forces = res.contact_force[b.name]
            r_b, scale_b = _residual(b, u[b.name], f_int, forces, held)
            out_of_balance, scale = max(out_of_balance, r_b), max(scale, scale_b)
            if own := not damp and motion <= MAX_TURN:  # a Newton step's own rate
                last_move[b.name].append(moves[b.name])
            plain = own and b.name not in mixed and not (b.free and short) and flips.steady
            left[b.name] = errors.left(b.name, step, moves[b.name], plain)
            if b.free and full[b.name] and b.follower is None and linear_rate(last_move[b.name]):
                slow_full.add(b.name)
        # over the frame's largest force: a body that carries nothing (a finger a step
        # touched and the next let go) relaxes to rest with no force of its own to scale by
        residual = out_of_balance / scale
        damping.taken(motion, residual)
        clock["checks"] += time.perf_counter() - t2
        log.debug(
            "Newton step %d: step/size %s, residual %.3g, %d contacts, %s, damped %g",
            step, {k: f"{v:.3g}" for k, v in moves.items()}, residual,
            len(res.contacts.get("node", ())), res.stop_reason, damp,
        )  # fmt: skip
        if max(left.values(), default=0.0) <= STEP_TOL and residual <= RESIDUAL:
            stop = "converged"
            return FiniteFrame(res, _all(bodies, u, res), step, True, stop, residual, clock)
        residuals.append(residual)
        stalled = min(residuals[-STALL:]) > 0.5 * min(residuals[:-STALL], default=np.inf)
        if len(residuals) > 2 * STALL and step - swung > STALL and stalled:
            stop = f"Newton stalled at residual {residual:.2g} after {step} steps"
            break
    if damping.verdict is not None and res is not None and res.held is not False:
        # a body not held, followed, stopped short of a verdict: the last one found
        res, u = damping.verdict
        stop = res.stop_reason
    if res is None:
        raise ContactError(stop)
    if stop == "iteration limit":
        stop = f"Newton did not converge in {max_steps} steps (residual {residual:.2g})"
    return FiniteFrame(res, _all(bodies, u, res), step, False, stop, residual, clock)


def _springs(
    body: FiniteBody, res: FrameResult, lin: ElasticBody, rigid: set[str]
) -> sp.csr_matrix:
    """Springs along the normals of ``body``'s contacts closed on planes, for the next step.

    A compressed body's tangent alone is not positive definite (a column fixed at its
    base sways); its contacts hold it, but its compliance is factored without them. A
    spring ``k n n^T`` at each node the last solve closed on a plane (``k`` the
    stiffness's largest diagonal entry, ``rigid`` the names of the pairs with a plane)
    holds it there. The step it changes is only the part along a closed row, which that
    row fixes anyway, so the step is Newton's; the springs' force is a step's, so nothing
    of them is left at convergence (``du = 0``). Against another body a row fixes the two
    bodies' relative motion only: a spring there would hold the node against the other
    body's motion, and no spring is put.
    """
    c = res.contacts
    n = body.mesh.n_dofs
    pairs = [str(p) for p in c.get("pair", [])]
    mine = np.array([p in rigid and p.split("/")[0] == body.name for p in pairs], bool)
    if not mine.any():
        return sp.csr_matrix((n, n))
    nodes = np.asarray(c["node"])[mine]
    normal = np.asarray(c["normal"], float)[mine]
    k = float(lin.stiffness.diagonal().max())
    blocks = k * normal[:, :, None] * normal[:, None, :]
    dofs = 3 * nodes[:, None] + np.arange(3)
    at = (np.repeat(dofs, 3, axis=1).ravel(), np.tile(dofs, 3).ravel())
    return sp.csr_matrix((blocks.ravel(), at), shape=(n, n))


def _motion(t: NDArray, omega: NDArray, size: float) -> float:
    """A step's rigid motion (:func:`fem.rigid_part` ``t, omega``) for a body of ``size``.

    Its turn (rad), or its move over the body's half size ``size / 2`` where that is more.
    """
    return max(float(np.linalg.norm(omega)), 2.0 * float(np.linalg.norm(t)) / size)


def _turned(
    body: FiniteBody, u: NDArray, du: NDArray, part: tuple[NDArray, NDArray] | None = None
) -> tuple[NDArray, bool]:
    """A free body's step with its rigid turn taken as a finite rotation; and shortened.

    The linearised step turns the body by ``omega x r``, which stretches it by about
    ``|omega|^2 / 2``: a strain the next step must undo. The step's rigid part
    ``t + omega x (x - c)`` (:func:`fem.rigid_part`, about the centroid ``c`` of the
    placement ``x``) is taken as ``x -> c + t + R(omega) (x - c + d)`` instead
    (:func:`fem.turned_placement`), ``d`` the rest of the step: the same to first order,
    no stretch from the turn. A step that turns the body by more than :data:`MAX_TURN`
    is shortened to it, and says so. ``part``: that rigid part where it is known.
    """
    x = body.mesh.points + u.reshape(-1, 3)
    d = du.reshape(-1, 3)
    t, omega = fem.rigid_part(x, d) if part is None else part
    angle = float(np.linalg.norm(omega))
    short = angle > MAX_TURN
    if short:
        # a body far from its balance (a ball that swings to hang below a pinch): the
        # linearisation is trusted for MAX_TURN at a time
        d, t, omega = d * (MAX_TURN / angle), t * (MAX_TURN / angle), omega * (MAX_TURN / angle)
    rest = d - t - np.cross(omega, x - x.mean(axis=0))
    tf = fem.turned_placement(x, t, omega)
    return ((x + rest) @ tf[:3, :3].T + tf[:3, 3] - x).ravel(), short


def _stepped(body: FiniteBody, u: NDArray, du: NDArray) -> tuple[NDArray, NDArray]:
    """``u + du`` and the internal forces there (the residual's, computed once).

    ``du`` is halved until no cell of ``body`` turns inside out.
    """
    for _ in range(HALVINGS):
        try:
            f_int = fem.finite_strain(body.mesh, body.materials, u + du, stiffness=False).force
        except fem.MaterialError:
            du = du / 2
            continue
        return u + du, f_int
    return u, fem.finite_strain(body.mesh, body.materials, u, stiffness=False).force


def _residual(
    body: FiniteBody, u: NDArray, f_int: NDArray, contact: NDArray, held: bool = False
) -> tuple[float, float]:
    """The free DOFs' largest force out of balance at ``u``, and the body's largest force.

    ``f_int`` the internal forces there, ``contact`` the contact forces. ``held``: a free
    body whose turn the linear frames hold (frictionless contacts, which the linear model
    lets turn a ball no more than they can): the moment they hold it with is a support's
    reaction, left out as the prescribed DOFs' are.
    """
    f_ext = np.zeros_like(f_int) if body.loads is None else body.loads.copy()
    if body.follower is not None:
        f_ext += follower_pressure(body.mesh, *body.follower, u)[0]
    r = f_int - f_ext - np.asarray(contact, float).ravel()
    if body.prescribed is not None:
        r[body.prescribed] = 0.0
    if held:
        turns = fem.rigid_body_modes(body.mesh.points + u.reshape(-1, 3))[:, 3:]
        r -= turns @ (turns.T @ r)
    scale = max(float(np.abs(f_int).max()), float(np.abs(f_ext).max(initial=0.0)),
                float(np.abs(contact).max(initial=0.0)))
    return float(np.abs(r).max()), scale


def _all(bodies, u, res: FrameResult) -> dict[str, NDArray[np.float64]]:
    """Every body's displacement: the finite ones' totals, the linear ones' last solve."""
    return {
        b.name: u[b.name].reshape(-1, 3) if b.name in u else res.displacement[b.name]
        for b in bodies
    }
