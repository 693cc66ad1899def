"""A scene set up for solving, frame by frame: scene -> bodies -> pose -> solve.

For every frame, after Gourret, Magnenat-Thalmann and Thalmann (1989, Fig. 9):

1. position (:meth:`GraspRun.angles`, :meth:`GraspRun.hand_body`,
   :meth:`GraspRun.object_body`): the hand's joint angles from the keyframes
   (Kochanek-Bartels), closed further by automatic flexion where the scene asks for it,
   and every flesh node mapped by JLD; the ball and the objects placed (each may follow
   a joint); the planes moved;
2. to 5. the contact iteration (:func:`contact.solver.iteration.solve_frame`), in contact
   space by default or as the paper's literal loop; each pair with its Coulomb
   coefficient (:meth:`contact.scene.Scene.friction`); by Newton's method around it
   where a body is neo-Hookean (:mod:`contact.solver.finite`).

:class:`GraspRun` keeps what lasts across frames: each linear object (the ball too) is
factored once per scene (again only when its placement turns it), the linear hand once
per pose, the previous pose warm-starts the next, a neo-Hookean body starts where the
last frame left it, and friction's anchors of the last frame solved are where the next
frame's slip is measured from: frames are solved in time order. At the scene's start it
refuses an object placed deep inside the skin, a plane or another object, and warns of a
shallow overlap (:func:`contact.run.startchecks.check_overlaps`). Writing is the caller's.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

import fem

from ..geometry.plane import Plane
from ..geometry.surfacequery import TriangleSurface
from ..hand.autoflex import auto_flex, mesh_distance
from ..hand.fingers import node_parts
from ..hand.keyframes import Keyframes
from ..hand.posing import HandPoser, Pose
from ..hand.shipped import load_hand
from ..holding import fingertargets as ft
from ..holding.fingerforce import FIRST_PRESS, drive
from ..objects.ball import Ball, make_ball, nodal_pressure
from ..objects.meshing import mesh_object
from ..objects.placed import SceneObject, body_pairs, from_ball, from_scene, plane_pairs
from ..scene.model import PlaneScene
from ..scene.spec import Scene
from ..solver.anchors import Anchors
from ..solver.body import ElasticBody
from ..solver.finite import FiniteBody, solve_finite_frame
from ..solver.iteration import solve_frame
from ..solver.pairs import ContactPair
from ..solver.results import FrameResult, IterationRecord
from ..solver.settings import ContactSettings
from .rolling import solve_rolled
from .startchecks import check_bones, check_overlaps
from .stepping import solve_stepped

__all__ = ["GraspRun"]

log = logging.getLogger(__name__)


@dataclass
class GraspRun:
    """A scene set up for solving: the bodies that last across frames.

    Parameters
    ----------
    scene : contact.scene.Scene
        The loaded scene.

    Attributes
    ----------
    ball : contact.objects.ball.Ball or None
        The ball's mesh, material and loads at its scene position (None: no ``[ball]``).
    objects : list of SceneObject
        The ball (first, when the scene has one) and the ``[[object]]`` meshes, at their
        scene placements.
    hand : contact.hand.shipped.Hand or None
        The shipped hand, with its poser and keyframes, when the scene has one.
    limits : dict of str to float
        Force limit of each bone that holds flesh nodes (N); empty without a hand.
    anchors : Anchors or None
        Where each frictional contact stuck at the end of the last frame solved (its
        :attr:`FrameResult.anchors`), carried into the next :meth:`frame`; None before the
        first frame and without friction. Set it to None to start a history afresh.
    positions : dict of str to ndarray
        Each force-driven plane's translation (m, shape (3,)) where the last frame solved
        left it: the next frame starts it there.
    placed_anew : dict of str to ndarray
        Each free linear object's placement anew (4x4) after it rolled, on top of its
        scene's (:func:`contact.run.rolling.solve_rolled`).
    """

    scene: Scene
    ball: Ball | None = field(init=False)
    objects: list[SceneObject] = field(init=False)
    _hand_body: ElasticBody | None = field(default=None, init=False)
    _hand_key: bytes = field(default=b"", init=False)
    _pose: Pose | None = field(default=None, init=False)
    _node_parts: NDArray[np.int64] | None = field(default=None, init=False, repr=False)
    # each force-driven joint's last search by frame, shared by restarts (--least-grip)
    _fingers: dict = field(default_factory=dict, init=False, repr=False)
    anchors: Anchors | None = field(default=None, init=False)
    positions: dict[str, NDArray[np.float64]] = field(default_factory=dict, init=False)
    last_time: float | None = field(default=None, init=False, repr=False)
    frame_time: float | None = field(default=None, init=False, repr=False)
    placed_anew: dict[str, NDArray[np.float64]] = field(default_factory=dict, init=False)
    _started: bool = field(default=False, init=False, repr=False)
    # the frame time whose input pose was checked against the bones (trials are not input)
    _bones_at: float | None = field(default=None, init=False, repr=False)
    # each finite body's last displacement (the hand's with its pose; an object's unturned)
    _u: dict[str, tuple] = field(default_factory=dict, init=False, repr=False)

    def __post_init__(self) -> None:
        sc = self.scene
        self.ball = None if sc.ball is None else make_ball(sc.ball)
        self.objects = []
        if self.ball is not None:
            self.objects.append(from_ball(self.ball, sc.follow))
        for i, o in enumerate(sc.objects):
            where = f"object[{i}]"
            mesh = mesh_object(o.mesh, o.mesh_size, where=f"{where}.mesh")
            self.objects.append(from_scene(o, mesh, where))
        self.hand = None
        self.poser = None
        self.nodal_pressure = False
        self.keyframes = None
        if sc.hand is not None:
            hs = sc.hand
            self.hand = load_hand(hs.resolution, hs.directory)
            self.poser = HandPoser(self.hand)
            self.keyframes = Keyframes(self.hand.skeleton, list(hs.keyframes))
            self.flesh = hs.flesh.elastic()
            self.flesh_finite = hs.flesh.finite
            # linear tetrahedra: averaged nodal pressures where they would lock
            self.nodal_pressure = nodal_pressure(
                True, hs.flesh.nu, hs.nodal_pressure, "hand.flesh"
            )
            names = self.hand.skeleton.bone_names
            self.bones = {n: self.hand.bone_nodes(n) for n in names if self.hand.bone_nodes(n).size}
            self.limits = hs.limits(list(self.bones))
        else:
            self.limits = {}

    # --- step 1: positioning -------------------------------------------------------

    def angles(self, t: float) -> dict[str, float]:
        """The hand's angles at time ``t``: keyframes, then automatic flexion.

        Each measures against the ball's placed contact facets, as the contact search does
        (:func:`contact.hand.autoflex.mesh_distance`): a press reaches a coarse ball's
        facets. Each outcome is kept in :attr:`auto_flexed` (joint to angle, the node
        that reached the ball, its distance, converged and why). A force-driven
        one stops at first contact; the angle it presses :data:`FIRST_PRESS` past that is
        kept for the force search (:meth:`_solve`).
        """
        assert self.keyframes is not None and self.hand is not None
        angles = self.keyframes.pose(t)
        self.auto_flexed: dict[str, dict] = {}
        self._pressed: dict[str, float] = {}
        ball = mesh_distance(self.object_surfaces(t))
        for af in self._flexions(t):
            res = auto_flex(
                self.hand,
                af.point,
                ball,
                af.joint,
                angles=angles,
                press=af.press,
                epsilon=af.epsilon,
                first_contact=af.first_contact,
            )
            if af.force is not None and res.converged:
                # force-driven: from first contact; the search's first trial presses past it
                deeper = auto_flex(
                    self.hand, af.point, ball, af.joint, angles=res.angles,
                    press=FIRST_PRESS, epsilon=af.epsilon, first_contact=af.first_contact,
                )  # fmt: skip
                self._pressed[af.joint] = deeper.angle
            if not res.converged:
                log.warning("t = %g: automatic flexion of %s: %s", t, af.joint, res.reason)
            self.auto_flexed[af.joint] = {
                "angle": res.angle,
                "node": res.node,
                "distance": res.distance,
                "converged": res.converged,
                "reason": res.reason,
            }
            angles = dict(res.angles)
        return angles

    def _flexions(self, t: float) -> list:
        """The scene's automatic flexions that apply at ``t``.

        A step of ``solver.substeps`` takes those of the frame it leads to.
        """
        t = self.frame_time if self.frame_time is not None else t
        return [
            af
            for af in self.scene.hand.auto_flexion  # type: ignore[union-attr]
            if af.applies(t)
        ]

    def placement(self, obj: SceneObject, t: float) -> NDArray[np.float64]:
        """The rigid placement of ``obj`` at ``t`` from its scene's (4x4): joint, then roll."""
        pose = self.keyframes.pose if self.keyframes is not None else None
        skeleton = self.hand.skeleton if self.hand is not None else None
        return self.placed_anew.get(obj.name, np.eye(4)) @ obj.transform(skeleton, pose, t)

    def ball_transform(self, t: float) -> NDArray[np.float64]:
        """Rigid placement of the first object (the ball) at ``t`` from its scene position."""
        return self.placement(self.objects[0], t)

    def object_surfaces(self, t: float) -> TriangleSurface:
        """Every object's contact surface placed for ``t``, as one: what a finger closes on."""
        parts = [o.surface(self.placement(o, t)) for o in self.objects]
        offsets = np.cumsum([0] + [len(p.points) for p in parts])
        return TriangleSurface(
            np.concatenate([p.points for p in parts]),
            np.concatenate([p.triangles + k for p, k in zip(parts, offsets)]),
            name=" and ".join(o.name for o in self.objects),
        )

    def object_body(self, obj: SceneObject, t: float) -> ElasticBody:
        """``obj`` placed for ``t``, with its loads (own, gravity, ``ball.load`` for the ball).

        The load is the scene's (a :meth:`restart` may change it), not the meshed ball's.
        """
        sc = self.scene
        load = None
        if obj.name == "ball" and sc.ball is not None and sc.ball.load:
            load = sc.ball.load_at
        tf = self.placement(obj, t)
        return obj.body(tf, t, sc.gravity, sc.solver.linear_solver, load)

    def ball_body(self, t: float) -> ElasticBody:
        """The first object (the ball) placed for ``t``."""
        return self.object_body(self.objects[0], t)

    def hand_body(self, angles: dict[str, float]) -> ElasticBody:
        """The hand posed for ``angles``, factored once per distinct pose."""
        assert self.poser is not None
        key = np.array(sorted(angles.items()), dtype=object).tobytes()
        if self._hand_body is not None and key == self._hand_key:
            return self._hand_body
        # the previous frame's pose warm-starts the flesh's relaxation (HandPoser.pose)
        pose = self.poser.pose(angles, start=self._pose)
        mesh = pose.mesh()
        prescribed = fem.node_dofs(self.hand.prescribed_nodes)  # type: ignore[union-attr]
        # a neo-Hookean hand is the finite solve's reference: no linear stiffness
        zero = sp.csr_matrix((mesh.n_dofs, mesh.n_dofs)) if self.flesh_finite else None
        self._hand_body = ElasticBody(
            "hand",
            mesh,
            self.flesh,
            prescribed=prescribed,
            supports=self.bones,
            backend=self.scene.solver.linear_solver,
            contact_faces=self.hand.skin_faces,  # type: ignore[union-attr]
            nodal_pressure=self.nodal_pressure,
            stiffness=zero,
        )
        self._hand_body.finite = self.flesh_finite
        self._hand_key = key
        self._pose = pose
        return self._hand_body

    def restart(self, scene: Scene) -> GraspRun:
        """A run of ``scene`` (this one with other forces) that starts its history afresh.

        The bodies built so far (the ball's and the hand's factorisations, the last pose)
        are shared: ``scene`` must differ from this run's only in its forces and loads.
        """
        out = GraspRun.__new__(GraspRun)
        out.__dict__.update(self.__dict__)
        out.scene = scene
        out.anchors, out.last_time, out._started, out._bones_at = None, None, False, None
        out.placed_anew, out.positions, out._u = {}, {}, {}
        return out

    # --- one frame -----------------------------------------------------------------

    def frame(
        self, t: float, callback: Callable[[IterationRecord], None] | None = None
    ) -> tuple[FrameResult, dict, list[Plane], list[ElasticBody]]:
        """Set up and solve the frame at time ``t``, from the last frame's anchors.

        With friction and ``solver.substeps = n > 1``, the steps of time between the last
        frame solved and ``t`` are solved first (``n - 1`` of them, not returned), each
        carrying the anchors to the next. A frame with a neo-Hookean body whose Newton
        does not converge (where no free body fell) is solved again from the last
        frame's state with its step of time cut in 2, then 4
        (:data:`contact.run.stepping.MAX_CUTS`): a smaller increment of the pose and the
        loads, as a finite-strain code cuts back its time step.

        Parameters
        ----------
        t : float
            Frame time.
        callback : callable, optional
            Called with each iteration's record (progress).

        Returns
        -------
        result : FrameResult
            The solve, with its set-up time under ``timings["setup"]``.
        extra : dict
            For the summary: the hand's angles, automatic flexions and smallest tet
            quality (empty without a hand).
        planes : list of Plane
            The planes at ``t``.
        bodies : list of ElasticBody
            The ball, then the hand.
        """
        return solve_stepped(self, t, callback)

    @property
    def finite(self) -> bool:
        """The scene has a neo-Hookean body."""
        return bool(self.hand and self.flesh_finite) or any(o.finite for o in self.objects)

    def history(self) -> tuple:
        """What a frame carries to the next: anchors, planes, pose, rolls, finite placements."""
        kept = (self.anchors, dict(self.positions), self._pose)
        return (*kept, dict(self.placed_anew), dict(self._u))

    def restore(self, kept: tuple) -> None:
        """Back to the :meth:`history` ``kept``."""
        self.anchors, self.positions, self._pose = kept[0], dict(kept[1]), kept[2]
        self.placed_anew, self._u = dict(kept[3]), dict(kept[4])

    def solve_at(
        self, t: float, callback: Callable[[IterationRecord], None] | None
    ) -> tuple[FrameResult, dict, list[Plane], list[ElasticBody]]:
        """Set up and solve the contact at time ``t``, carrying the anchors.

        With force-driven fingers, the frame is solved at the angles
        :func:`contact.holding.fingerforce.drive` tries, each trial from the same history.
        """
        t0 = time.perf_counter()
        angles = self.angles(t) if self.hand is not None else {}
        posing = time.perf_counter() - t0  # set-up too: the automatic flexions' search
        h = self.hand
        targets = ft.force_targets(h, self._flexions(t), self._pressed, self._parts) if h else []
        if not targets:
            out = solve_rolled(self, t, angles, callback)
            out[0].timings["setup"] += posing
            return out
        # every trial from the same history, its flesh relaxed from the same pose
        kept = self.history()

        def trial(pose: dict[str, float]) -> tuple[tuple, dict[str, float], str]:
            self.restore(kept)
            out = solve_rolled(self, t, pose, callback)
            res = out[0]
            forces = ft.finger_forces(res.contact_fields.get("hand"), self._parts(), targets)
            # a ball not held is an outcome; a frame stopped short says little of the force
            return out, forces, "" if res.converged or res.held is False else res.stop_reason

        pressed = ft.guess(self._fingers, t, angles, {**angles, **self._pressed}, targets)
        touching = dict(angles)
        out, angles, drives = drive(
            trial, touching, pressed, targets, lost=lambda o: o[0].held is False
        )
        ft.remember(self._fingers, t, touching, drives)
        result, extra, planes, bodies = out
        result.timings["setup"] += posing
        for j, d in drives.items():
            self.auto_flexed[j] = {**self.auto_flexed[j], "angle": d.angle, **d.record()}
        extra["auto_flexion"] = self.auto_flexed
        short = [d for d in drives.values() if not d.converged]
        if short:
            why = "finger force not reached: " + "; ".join(d.reason for d in short)
            stop = why if result.converged else f"{result.stop_reason}; {why}"
            below = result.converged and all(d.reached < d.force for d in short)
            result = dataclasses.replace(
                result, converged=False, stop_reason=stop, below_grip=below
            )
        return result, extra, planes, bodies

    def _parts(self) -> NDArray[np.int64]:
        """The hand part of every flesh node."""
        assert self.hand is not None
        if self._node_parts is None:
            self._node_parts = node_parts(self.hand.flesh, len(self.hand.part_names))
        return self._node_parts

    def solve_placed(
        self, t: float, angles: dict[str, float], callback: Callable[[IterationRecord], None] | None
    ) -> tuple[FrameResult, dict, list[Plane], list[ElasticBody]]:
        """Set up and solve the contact at time ``t``, the objects where they are placed now."""
        sc = self.scene
        t0 = time.perf_counter()
        objects = [self.object_body(o, t) for o in self.objects]
        bodies = list(objects)
        settings = sc.solver.settings(self.limits)
        extra: dict = {}
        hand = None
        if self.hand is not None:
            hand = self.hand_body(angles)
            if self._bones_at != t:
                check_bones(self.hand, self._pose, objects, t, self._starts(t))  # type: ignore[arg-type]
                self._bones_at = t
            bodies.append(hand)
            extra["angles"] = angles
            if self.auto_flexed:
                extra["auto_flexion"] = self.auto_flexed
            assert self._pose is not None
            extra["min_tet_quality"] = float(self._pose.min_quality)
        planes = [self._plane(p, t) for p in sc.planes]
        pairs = plane_pairs(objects, planes, sc.friction, settings.gaps)
        pairs += body_pairs(objects, hand, sc.friction, settings.gaps)
        setup = time.perf_counter() - t0
        # steps 2 to 5
        if not self._started:
            self._started = True
            check_overlaps(t, bodies, sc.planes, settings.gap_tolerance)
        if any(b.finite for b in bodies):
            result, extra["newton"] = self._solve_finite(
                t, bodies, pairs, planes, settings, callback
            )
        else:
            result = solve_frame(
                bodies, pairs, planes, settings, callback=callback, anchors=self.anchors
            )
        # carried as returned, converged or not: the history is what was solved
        self.anchors = result.anchors  # type: ignore[assignment]
        driven = {p.name for p in sc.planes if p.driven}
        for name in driven:
            self.positions[name] = result.plane_positions[name]
        planes = [pl.moved(self.positions[pl.name]) if pl.name in driven else pl for pl in planes]
        result.timings["setup"] = setup
        return result, extra, planes, bodies

    def _solve_finite(
        self,
        t: float,
        bodies: list[ElasticBody],
        pairs: list[ContactPair],
        planes: list[Plane],
        settings: ContactSettings,
        callback: Callable[[IterationRecord], None] | None,
    ) -> tuple[FrameResult, dict]:
        """Steps 2 to 5 by Newton's method on the neo-Hookean bodies (:mod:`contact.solver.finite`).

        Each starts where the last frame left it: an object turned with its placement,
        the hand when its pose is the same. The result's displacements are the totals
        from each body's reference; its timings the Newton loop's. Also Newton's figures.
        """
        turn = {o.name: self.placement(o, t)[:3, :3] for o in self.objects}
        follower = {o.name: o.follower for o in self.objects}
        solved = [FiniteBody.of(b, follower.get(b.name)) if b.finite else b for b in bodies]
        fr = solve_finite_frame(
            solved, pairs, planes, settings, start=self._starts(t), anchors=self.anchors,
            callback=callback,
        )  # fmt: skip
        for n in (b.name for b in bodies if b.finite):
            u = fr.displacement[n]
            self._u[n] = (self._hand_key, u) if n == "hand" else (None, u @ turn[n])
        newton = {"steps": fr.steps, "converged": fr.converged, "residual": fr.residual}
        return fr.frame_result(), newton

    def _starts(self, t: float) -> dict[str, NDArray[np.float64]]:
        """Where each finite body starts the frame at ``t``: where the last one left it.

        An object turned with its placement; the hand where its pose is the same.
        """
        turn = {o.name: self.placement(o, t)[:3, :3] for o in self.objects}
        last = {n: u for n, (k, u) in self._u.items() if n != "hand" or k == self._hand_key}
        return {n: u if n == "hand" else u @ turn[n].T for n, u in last.items()}

    def _plane(self, spec: PlaneScene, t: float) -> Plane:
        """The plane at ``t``: moved by its offsets, or a force-driven one where it was left.

        A force-driven plane whose force is 0 at ``t`` stays where it is.
        """
        if not spec.driven:
            return Plane(spec.point, spec.normal, motion=spec.offset(t), name=spec.name)
        force = spec.force_at(t)
        return Plane(
            spec.point,
            spec.normal,
            motion=self.positions.get(spec.name, np.zeros(3)),
            name=spec.name,
            force=force if force > 0 else None,
        )

