"""The whole scene: its tables, the friction of each interface, its echo for ``summary.json``.

Coulomb friction is given per body: ``friction`` on a plane, on the hand and on the ball.
An interface takes its master's coefficient where the master's table gives one, else the
ball's (:meth:`Scene.friction`), the same both ways across one interface.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from ..ball import BallSpec
from ..errors import SceneError
from ._checks import as_dict, check_friction, invalid
from .model import Follow, HandScene, OutputScene, PlaneScene, SolverScene

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
    ball : BallSpec
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
    ball_friction : float
        ``ball.friction``: Coulomb's coefficient of the ball against a plane or the hand
        that gives none, >= 0.

    Raises
    ------
    SceneError
        On a bad ``ball.friction``, or friction with ``solver.algorithm = "seed"`` (the
        seed's loop has no tangential law); the message names the key path from the top.
    """

    path: Path
    name: str
    ball: BallSpec
    hand: HandScene | None
    planes: tuple[PlaneScene, ...]
    follow: Follow | None
    frames: tuple[float, ...]
    gravity: tuple[float, float, float] | None
    solver: SolverScene
    output: OutputScene
    description: str = ""
    ball_friction: float = 0.0

    def __post_init__(self) -> None:
        check_friction("ball.friction", self.ball_friction)
        frictional = [(key, mu) for _, key, mu in self.interfaces() if mu > 0]
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

    def interfaces(self) -> list[tuple[str, str, float]]:
        """Each body the ball can touch, with the key path that gives its coefficient.

        Returns
        -------
        list of (str, str, float)
            ``(body, key path, mu)`` for the planes in file order, then the hand: the body's
            own ``friction`` where its table gives one (``plane[0].friction``), else the
            ball's (``ball.friction``).
        """
        own = [(p.name, f"plane[{i}].friction", p.friction) for i, p in enumerate(self.planes)]
        if self.hand is not None:
            own.append(("hand", "hand.friction", self.hand.friction))
        return [
            (body, "ball.friction", self.ball_friction) if mu is None else (body, key, mu)
            for body, key, mu in own
        ]

    @property
    def frictional(self) -> bool:
        """True when some interface has friction: every frame then depends on those before."""
        return any(mu > 0 for _, _, mu in self.interfaces())

    def friction(self, body: str) -> float:
        """Coulomb's coefficient between the ball and ``body``, the same both ways.

        Parameters
        ----------
        body : str
            ``"hand"`` or a plane's name: the master of the ball's pair, and the slave of
            the hand's pair against the ball.

        Returns
        -------
        float
            ``body``'s ``friction`` where its table gives one, else ``ball.friction``.

        Raises
        ------
        KeyError
            When the scene has no such body.
        """
        for name, _, mu in self.interfaces():
            if name == body:
                return float(mu)
        raise KeyError(f"the scene has no hand or plane {body!r}")

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
        if (self.gravity is None or not any(self.gravity)) and not self.ball.load:
            raise SceneError(
                "--least-grip: nothing to hold: the free ball has no load (set scene.gravity "
                "or ball.load)"
            )
        if not self.frictional:
            raise SceneError(
                "--least-grip: the scene has no friction: nothing holds the ball by its grip "
                "(set ball.friction, hand.friction or a plane's friction)"
            )
        return peaks

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
        ball = {
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
