"""The whole scene: its tables, the friction of each interface, its echo for ``summary.json``.

Coulomb friction is given per body: ``friction`` on a plane, on the hand, on the ball and
on each ``[[object]]``. An interface with a plane or the hand takes that body's
coefficient where its table gives one, else the object's; between two objects, the first
one's, else the other's (:meth:`Scene.friction`); the same both ways across one interface.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from ..errors import SceneError
from ..objects.ball import BallSpec
from ._checks import as_dict, check_friction, invalid
from .model import Follow, HandScene, OutputScene, PlaneScene, SolverScene
from .objects import ObjectScene

__all__ = ["Scene"]


@dataclass(frozen=True)
class Scene:
    """A validated scene (see :func:`contact.scene.load_scene`).

    Attributes
    ----------
    path : Path
        The scene file (absolute).
    name : str
        ``scene.name``, default the file's stem.
    ball : BallSpec or None
        The ``[ball]`` table; None when the scene has only ``[[object]]`` tables.
    hand : HandScene or None
    planes : tuple of PlaneScene
    follow : Follow or None
    frames : tuple of float
        Times to compute, increasing.
    gravity : (float, float, float) or None
        m/s^2; None: no gravity.
    solver : SolverScene
    output : OutputScene
    description : str
        ``scene.description``.
    ball_friction : float or None
        ``ball.friction``: Coulomb's coefficient of the ball against a plane, the hand or
        an object that gives none, >= 0; None where not given (then 0).
    objects : tuple of ObjectScene
        The ``[[object]]`` tables, in file order.

    Raises
    ------
    SceneError
        On a bad ``ball.friction``, or friction with ``solver.algorithm = "seed"`` (the
        seed's loop has no tangential law); the message names the key path from the top.
    """

    path: Path
    name: str
    ball: BallSpec | None
    hand: HandScene | None
    planes: tuple[PlaneScene, ...]
    follow: Follow | None
    frames: tuple[float, ...]
    gravity: tuple[float, float, float] | None
    solver: SolverScene
    output: OutputScene
    description: str = ""
    ball_friction: float | None = None
    objects: tuple[ObjectScene, ...] = ()

    def __post_init__(self) -> None:
        check_friction("ball.friction", self.ball_friction)
        if not self.object_names:
            raise SceneError("missing: a scene needs a [ball] table or [[object]] tables")
        frictional = [
            (key, mu) for o in self.object_names for _, key, mu in self.interfaces(o) if mu > 0
        ]
        if frictional and self.solver.contact.algorithm == "seed":
            key, mu = frictional[0]
            raise invalid(
                "solver.algorithm",
                "seed",
                f'the seed loop takes no friction ({key} = {mu:g}): use "contact-space" '
                "or set every friction to 0",
            )
        driven = [i for i, p in enumerate(self.planes) if p.driven]
        if driven and self.solver.contact.algorithm == "seed":
            raise invalid(
                "solver.algorithm",
                "seed",
                f"the seed loop takes no force-driven plane (plane[{driven[0]}].force): "
                'use "contact-space"',
            )

    @property
    def object_names(self) -> list[str]:
        """The free or held objects' body names: ``"ball"`` (when the scene has one) first."""
        return (["ball"] if self.ball is not None else []) + [o.name for o in self.objects]

    @property
    def free_objects(self) -> list[str]:
        """The objects held by their contacts alone: neither fixed nor following a joint."""
        out = ["ball"] if self.ball is not None and self.follow is None else []
        return out + [o.name for o in self.objects if not o.fixed and o.follow is None]

    def _own(self, obj: str) -> tuple[str, float | None]:
        """An object's own ``friction`` key path and value (None: not given)."""
        if obj == "ball" and self.ball is not None:
            return "ball.friction", self.ball_friction
        for i, o in enumerate(self.objects):
            if o.name == obj:
                return f"object[{i}].friction", o.friction
        raise KeyError(f"the scene has no object {obj!r}")

    def interfaces(self, obj: str | None = None) -> list[tuple[str, str, float]]:
        """Each body the object ``obj`` can touch, with the key path that gives its coefficient.

        Parameters
        ----------
        obj : str, optional
            An object's name (:attr:`object_names`); default the first (the ball).

        Returns
        -------
        list of (str, str, float)
            ``(body, key path, mu)`` for the planes in file order, then the hand, then the
            other objects. Against a plane or the hand: the body's own ``friction`` where its
            table gives one (``plane[0].friction``), else the object's (``ball.friction``),
            else 0. Between two objects: the one first in :attr:`object_names`'s where it
            gives one, else the other's, else 0.
        """
        obj = self.object_names[0] if obj is None else obj
        key, mine = self._own(obj)
        mine_or_0 = 0.0 if mine is None else mine
        own = [(p.name, f"plane[{i}].friction", p.friction) for i, p in enumerate(self.planes)]
        if self.hand is not None:
            own.append(("hand", "hand.friction", self.hand.friction))
        out = [(body, key, mine_or_0) if mu is None else (body, k, mu) for body, k, mu in own]
        names = self.object_names
        for other in names:
            if other == obj:
                continue
            k2, theirs = self._own(other)
            first, second = ((key, mine), (k2, theirs))
            if names.index(other) < names.index(obj):
                first, second = second, first
            given = first if first[1] is not None else second
            out.append((other, given[0], 0.0 if given[1] is None else float(given[1])))
        return out

    @property
    def frictional(self) -> bool:
        """True when some interface has friction: every frame then depends on those before."""
        return any(mu > 0 for obj in self.object_names for _, _, mu in self.interfaces(obj))

    def friction(self, body: str, obj: str | None = None) -> float:
        """Coulomb's coefficient between the object ``obj`` and ``body``, the same both ways.

        Parameters
        ----------
        body : str
            ``"hand"``, a plane's or another object's name.
        obj : str, optional
            An object's name; default the first (the ball).

        Returns
        -------
        float
            As :meth:`interfaces` gives it.

        Raises
        ------
        KeyError
            When the scene has no such body.
        """
        for name, _, mu in self.interfaces(obj):
            if name == body:
                return float(mu)
        raise KeyError(f"the scene has no hand, plane or object {body!r}")

    @property
    def grip(self) -> dict[str, float]:
        """Each force-driven element's own peak force (N), by name: what ``--least-grip`` scales.

        Raises
        ------
        SceneError
            When the scene has nothing force-driven to scale, nothing to hold (no gravity),
            or no friction to hold it with.
        """
        peaks = {p.name: max(n for _, n in p.force) for p in self.planes if p.driven}
        for a in self.hand.auto_flexion if self.hand is not None else ():
            if a.force is not None:
                peaks[a.joint] = max(peaks.get(a.joint, 0.0), a.force)
        if not peaks:
            raise SceneError(
                "--least-grip: the scene has nothing force-driven to scale (give a "
                "[[plane]] force = [[t, N], ...] or a [[hand.auto_flexion]] force = N)"
            )
        loaded = self.ball is not None and self.ball.load
        if (self.gravity is None or not any(self.gravity)) and not loaded:
            raise SceneError(
                "--least-grip: nothing to hold: no free object has a load (set scene.gravity "
                "or ball.load)"
            )
        if not self.frictional:
            raise SceneError(
                "--least-grip: the scene has no friction: nothing holds the ball by its grip "
                "(set ball.friction, hand.friction or a plane's friction)"
            )
        return peaks

    def grip_at(self, time: float) -> dict[str, float]:
        """Each force-driven element's own force (N) at ``time``, by name (as :attr:`grip`).

        A finger's is that of its flexion applying at ``time``, 0 where none does.
        """
        out = {p.name: p.force_at(time) for p in self.planes if p.driven}
        for a in self.hand.auto_flexion if self.hand is not None else ():
            if a.force is not None:
                out[a.joint] = max(out.get(a.joint, 0.0), a.force if a.applies(time) else 0.0)
        return out

    def grip_scaled(self, s: float) -> Scene:
        """A copy with every force-driven plane's and finger's force times ``s`` (> 0).

        Elements driven by positions (offsets, angles, press depths) are unchanged.

        Raises
        ------
        SceneError
            As :attr:`grip` (nothing to scale or hold); a scaled force past the largest
            allowed names its plane.
        """
        self.grip  # noqa: B018 (the checks)
        if not (s > 0 and s < float("inf")):
            raise SceneError(f"--least-grip: the grip scale {s!r} must be a finite number > 0")
        planes = []
        for i, p in enumerate(self.planes):
            try:
                planes.append(replace(p, force=tuple((t, n * s) for t, n in p.force)))
            except SceneError as exc:
                raise SceneError(f"plane[{i}] ({p.name}) scaled by {s:g}: {exc}") from None
        if self.hand is None:
            return replace(self, planes=tuple(planes))
        flexions = []
        for i, a in enumerate(self.hand.auto_flexion):
            try:
                flexions.append(a if a.force is None else replace(a, force=a.force * s))
            except SceneError as exc:
                raise SceneError(
                    f"hand.auto_flexion[{i}] ({a.joint}) scaled by {s:g}: {exc}"
                ) from None
        hand = replace(self.hand, auto_flexion=tuple(flexions))
        return replace(self, planes=tuple(planes), hand=hand)

    def echo(self) -> dict:
        """The whole scene with its defaults filled in, JSON-serialisable, in the file's layout.

        Paths are strings; ``None`` stands for an absent optional value.
        """
        b = self.ball
        ball = None if b is None else {
            "radius": b.radius,
            "kind": b.kind,
            "thickness": b.thickness,
            "pressure": b.pressure,
            "element": b.element,
            "mesh_size": b.mesh_size,
            "mesh": None if b.mesh is None else str(b.mesh),
            "center": list(b.center),
            "material": {"E": b.E, "nu": b.nu, "density": b.density},
            "nodal_pressure": b.nodal_pressure,
            "friction": self.ball_friction,
            "load": [list(k) for k in b.load],
            "follow": None if self.follow is None else as_dict(self.follow),
        }
        hand = None
        if self.hand is not None:
            h = self.hand
            hand = {
                "rig": str(h.rig),
                "directory": str(h.directory),
                "resolution": h.resolution,
                "flesh": as_dict(h.flesh),
                "bone_force_limit": h.bone_force_limit,
                "bone_force_limits": dict(h.bone_force_limits),
                "keyframe": [{**k, "angles": dict(k["angles"])} for k in h.keyframes],
                "auto_flexion": [
                    {**as_dict(a), "times": None if a.times is None else list(a.times)}
                    for a in h.auto_flexion
                ],
                "nodal_pressure": h.nodal_pressure,
                "friction": h.friction,
            }
        return {
            "path": str(self.path),
            "scene": {
                "name": self.name,
                "description": self.description,
                "gravity": None if self.gravity is None else list(self.gravity),
            },
            "ball": ball,
            "object": [
                {
                    **as_dict(o),
                    "mesh": str(o.mesh),
                    "center": list(o.center),
                    "rotation": list(o.rotation),
                    "material": as_dict(o.material),
                    "follow": None if o.follow is None else as_dict(o.follow),
                }
                for o in self.objects
            ],
            "hand": hand,
            "plane": [
                {
                    "name": p.name,
                    "point": list(p.point),
                    "normal": list(p.normal),
                    "offsets": [[t, *d] for t, d in p.offsets],
                    "force": [list(k) for k in p.force],
                    "friction": p.friction,
                }
                for p in self.planes
            ],
            "frames": {"times": list(self.frames)},
            "solver": self.solver.echo(),
            "output": {
                "directory": str(self.output.directory),
                "pictures": self.output.pictures,
                "gif": self.output.gif,
                "window_size": list(self.output.window_size),
            },
        }
