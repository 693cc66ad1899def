"""The scene's tables: one frozen dataclass per table of a scene file, with defaults and checks.

Each dataclass is the one source of its table's defaults and range checks
(``docs/scene.md`` documents them, and a test holds the two together); the ``[solver]``
table holds a :class:`~contact.solver.ContactSettings`, whose own defaults and checks
apply. A failed check raises :class:`SceneError` naming the field relative to its table,
``E = 0.0: must be positive``; the reader (:mod:`contact.scene.read`) prefixes the file
and the table's key path. The whole scene, which holds these tables, is
:class:`contact.scene.spec.Scene`.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

import fem
from fem.linsolve import BACKENDS

from ..errors import SceneError
from ..hand.autoflex import FINGERTIPS
from ..hand.shipped import HAND_DIR
from ..objects.ball import MAX_LOAD_FORCE
from ..solver import ContactSettings
from ._checks import check_friction, invalid

__all__ = [
    "CONTACT_KEYS",
    "FLESH",
    "LINEAR_SOLVERS",
    "RESERVED",
    "WINDOW_SIZE",
    "AutoFlex",
    "Follow",
    "HandScene",
    "Material",
    "OutputScene",
    "PlaneScene",
    "SolverScene",
]

#: Names ``solver.linear_solver`` accepts.
LINEAR_SOLVERS = ("auto", *BACKENDS)
#: The ``[solver]`` keys that are :class:`ContactSettings` fields (its support limits
#: come from ``[hand]``).
CONTACT_KEYS = tuple(f.name for f in fields(ContactSettings) if f.name != "support_limits")
#: Body names a plane may not take.
RESERVED = ("ball", "hand")
#: The least and largest picture side (px): a renderer may abort on a huge window.
WINDOW_SIZE = (64, 4096)
#: The largest force (N) a force-driven plane or finger, or the ball's load, may be given:
#: far above any grip.
MAX_FORCE = MAX_LOAD_FORCE


#: The material models a scene may choose (``model``): small-strain linear elasticity, or
#: the compressible neo-Hookean law of :mod:`fem.hyperelastic` with the same ``E, nu``.
MODELS = ("linear", "neo-hookean")


@dataclass(frozen=True)
class Material:
    """An elastic material: Young's modulus (Pa), Poisson's ratio, density (kg/m^3), model.

    Checked as :class:`fem.LinearElastic` checks it: ``E > 0``, ``-1 < nu < 0.5``,
    ``density >= 0``. ``model`` is one of :data:`MODELS`: ``"neo-hookean"`` bodies are
    solved at finite strain (:mod:`contact.solver.finite`), their small-strain limit the
    linear model.
    """

    E: float
    nu: float
    density: float = 1000.0
    model: str = "linear"

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise SceneError(f"model = {self.model!r}: must be one of {', '.join(MODELS)}")
        try:
            self.elastic()
        except fem.MaterialError as exc:
            raise SceneError(str(exc)) from None

    @property
    def finite(self) -> bool:
        """Solved at finite strain (neo-Hookean)."""
        return self.model == "neo-hookean"

    def elastic(self) -> fem.LinearElastic:
        """The material as :class:`fem.LinearElastic`."""
        return fem.LinearElastic(self.E, self.nu, self.density)


#: The flesh's material where ``hand.flesh`` says nothing.
FLESH = Material(5.0e4, 0.45, 1000.0)


@dataclass(frozen=True)
class AutoFlex:
    """An automatic flexion (:func:`contact.auto_flex`): bend ``joint`` until ``point`` touches.

    Attributes
    ----------
    joint : str
        The angle searched (``"index_pip"``, ``"thumb_cmc_pivot"``...).
    point : str or int
        A fingertip name (:data:`contact.hand.autoflex.FINGERTIPS`) or a flesh node index.
    epsilon : float
        Tolerance on the distance (m), positive.
    press : float
        Depth (m) to press past first contact, not negative.
    times : tuple of float or None
        Frame times at which it applies; None: every frame.
    first_contact : bool
        Stop at the first skin node the joint brings to the ball (``point`` or another,
        a finger's pad before its tip); False: ``point`` alone, as in Magnenat-Thalmann,
        Laperriere and Thalmann 1988.
    force : float or None
        A force-driven flexion (N, > 0; not with ``press``): the joint closes past first
        contact until the normal contact force on ``point``'s finger is ``force``.
    force_tolerance : float
        Relative accuracy of that force, in (0, 0.5]: about the jump of a finger's force
        as one more node enters the contact, on the coarse hand.
    """

    joint: str
    point: str | int
    epsilon: float = 1e-4
    press: float = 0.0
    times: tuple[float, ...] | None = None
    first_contact: bool = True
    force: float | None = None
    force_tolerance: float = 0.02

    def __post_init__(self) -> None:
        if isinstance(self.point, str) and self.point not in FINGERTIPS:
            raise invalid("point", self.point, f"unknown; expected one of {', '.join(FINGERTIPS)}")
        if not isinstance(self.point, str) and self.point < 0:
            raise invalid("point", self.point, "must be at least 0")
        if not self.epsilon > 0:
            raise invalid("epsilon", self.epsilon, "must be positive")
        if self.press < 0:
            raise invalid("press", self.press, "must not be negative")
        if self.force is not None:
            if not 0 < self.force <= MAX_FORCE:
                raise invalid("force", self.force, f"must lie in (0, {MAX_FORCE:g}] N")
            if self.press:
                raise invalid("force", self.force, "a flexion is driven by press or by force")
        if not 0 < self.force_tolerance <= 0.5:
            raise invalid("force_tolerance", self.force_tolerance, "must lie in (0, 0.5]")

    def applies(self, t: float) -> bool:
        """Whether it applies at frame time ``t`` (every frame where ``times`` is None)."""
        return self.times is None or any(abs(t - s) <= 1e-12 for s in self.times)


@dataclass(frozen=True)
class HandScene:
    """The ``[hand]`` table.

    Attributes
    ----------
    rig : Path
        The rig file (absolute).
    keyframes : tuple of dict
        ``{time, angles, tension, continuity, bias}`` per key, validated against the rig;
        as :class:`contact.Keyframes` takes them (defaults: :class:`contact.Key`).
    directory : Path
        Folder of the hand meshes (absolute; the shipped ``meshes/hand`` by default).
    resolution : {"coarse", "fine"}
    flesh : Material
    bone_force_limit : float or None
        Largest force (N) on any one bone, positive; None: no limit.
    bone_force_limits : dict of str to float
        Per-bone limits (N, positive) overriding ``bone_force_limit``.
    auto_flexion : tuple of AutoFlex
    nodal_pressure : bool or None
        The flesh's tetrahedra with averaged nodal pressures (no volumetric locking);
        None: where ``flesh.nu`` is above :data:`contact.objects.ball.LOCKING_NU`, as for a tet
        ball.
    friction : float or None
        Coulomb's coefficient of the skin against the ball, >= 0; None: the ball's.
    """

    rig: Path
    keyframes: tuple[dict, ...]
    directory: Path = HAND_DIR
    resolution: str = "coarse"
    flesh: Material = FLESH
    bone_force_limit: float | None = None
    bone_force_limits: dict[str, float] = field(default_factory=dict)
    auto_flexion: tuple[AutoFlex, ...] = ()
    nodal_pressure: bool | None = None
    friction: float | None = None

    def __post_init__(self) -> None:
        check_friction("friction", self.friction)
        if self.bone_force_limit is not None and not self.bone_force_limit > 0:
            raise invalid("bone_force_limit", self.bone_force_limit, "must be positive")
        for bone, limit in self.bone_force_limits.items():
            if not limit > 0:
                raise invalid(f"bone_force_limits.{bone}", limit, "must be positive")

    def limits(self, bone_names: Iterable[str]) -> dict[str, float]:
        """The force limit (N) of each bone: its override, else the global one, else none.

        Parameters
        ----------
        bone_names : iterable of str

        Returns
        -------
        dict of str to float
            Only the bones that have a limit.
        """
        out = {}
        for name in bone_names:
            if name in self.bone_force_limits:
                out[name] = self.bone_force_limits[name]
            elif self.bone_force_limit is not None:
                out[name] = self.bone_force_limit
        return out


@dataclass(frozen=True)
class PlaneScene:
    """A rigid plane: the ball side is where ``normal`` points.

    Attributes
    ----------
    name : str
        Not a body's name (:data:`RESERVED`).
    point : tuple of 3 floats
        A point of the plane at rest (m).
    normal : tuple of 3 floats
        Unit normal (the file's normal, normalised).
    offsets : tuple of (float, (float, float, float))
        ``(time, translation)`` keys, times increasing: the plane's rigid translation (m),
        piecewise linear between keys and constant outside; empty: the plane is fixed.
    friction : float or None
        Coulomb's coefficient of the plane against any body, >= 0; None: the ball's.
    force : tuple of (float, float)
        ``(time, N)`` keys, times increasing, forces >= 0 (N): a force-driven plane, which
        moves along its normal until the bodies push it back with that force (piecewise
        linear between keys, constant outside); empty: driven by ``offsets``.
    """

    name: str
    point: tuple[float, float, float]
    normal: tuple[float, float, float]
    offsets: tuple[tuple[float, tuple[float, float, float]], ...] = ()
    friction: float | None = None
    force: tuple[tuple[float, float], ...] = ()

    def __post_init__(self) -> None:
        check_friction("friction", self.friction)
        if self.name in RESERVED:
            raise invalid("name", self.name, f"reserved for a body ({', '.join(RESERVED)})")
        if self.force and self.offsets:
            raise invalid(
                "force", [list(k) for k in self.force],
                "a plane is driven by offsets or by a force, not both",
            )  # fmt: skip
        for j, (t, n) in enumerate(self.force):
            if not (np.isfinite(n) and 0.0 <= n <= MAX_FORCE):
                raise invalid(f"force[{j}]", [t, n], f"the force must lie in [0, {MAX_FORCE:g}] N")
            if j and not t > self.force[j - 1][0]:
                previous = self.force[j - 1][0]
                raise invalid(f"force[{j}]", [t, n], f"times must increase (previous {previous:g})")
        for j in range(1, len(self.offsets)):
            t, d = self.offsets[j]
            if not t > self.offsets[j - 1][0]:
                previous = self.offsets[j - 1][0]
                raise invalid(
                    f"offsets[{j}]", [t, *d], f"times must increase (previous {previous:g})"
                )

    @property
    def driven(self) -> bool:
        """True for a force-driven plane."""
        return bool(self.force)

    def force_at(self, time: float) -> float:
        """The force-driven plane's force (N) at ``time`` (0 for a plane driven by offsets)."""
        if not self.force:
            return 0.0
        t = [k[0] for k in self.force]
        return float(np.interp(time, t, [k[1] for k in self.force]))

    def offset(self, time: float) -> NDArray[np.float64]:
        """The plane's translation (m) at ``time``, shape (3,)."""
        if not self.offsets:
            return np.zeros(3)
        t = np.array([k[0] for k in self.offsets])
        d = np.array([k[1] for k in self.offsets])
        return np.array([np.interp(time, t, d[:, i]) for i in range(3)])


@dataclass(frozen=True)
class Follow:
    """The ball follows a hand joint from ``start`` to ``stop`` (:class:`ObjectAssociation`)."""

    joint: str
    start: float
    stop: float

    def __post_init__(self) -> None:
        if self.stop < self.start:
            raise invalid("stop", self.stop, f"must not be before start = {self.start:g}")


@dataclass(frozen=True)
class SolverScene:
    """The ``[solver]`` table: the contact settings and the linear solver.

    Attributes
    ----------
    contact : ContactSettings
        The contact iteration's settings (without support limits: those come from the
        hand); its defaults and checks are the scene's.
    linear_solver : str
        One of :data:`LINEAR_SOLVERS`: ``"auto"`` (the first available) or a backend of
        :mod:`fem.linsolve`.
    substeps : int
        With friction, each frame after the first is solved in this many equal steps of
        time from the frame before (the steps between carry the stick anchors and are
        not written), so that a squeeze and a tangential load that change together
        slip along the way, not only at the frame's end. >= 1.
    """

    contact: ContactSettings = field(default_factory=ContactSettings)
    linear_solver: str = "auto"
    substeps: int = 1

    def __post_init__(self) -> None:
        if isinstance(self.substeps, bool) or not isinstance(self.substeps, int) or (
            self.substeps < 1
        ):
            raise invalid("substeps", self.substeps, "must be an integer >= 1")
        if self.linear_solver not in LINEAR_SOLVERS:
            raise invalid(
                "linear_solver",
                self.linear_solver,
                f"unknown; expected one of {', '.join(LINEAR_SOLVERS)}",
            )

    def settings(self, support_limits: Mapping[str, float]) -> ContactSettings:
        """The contact settings, with the force limit of each support group (bone)."""
        return replace(self.contact, support_limits=dict(support_limits))

    def echo(self) -> dict:
        """The table as the file lays it out: :data:`CONTACT_KEYS`, then the scene's own."""
        return {
            **{k: getattr(self.contact, k) for k in CONTACT_KEYS},
            "linear_solver": self.linear_solver,
            "substeps": self.substeps,
        }


@dataclass(frozen=True)
class OutputScene:
    """The ``[output]`` table.

    Attributes
    ----------
    directory : Path
        Results folder, as written (relative to the current working directory).
    pictures : bool
        Write PNG pictures of the stress.
    gif : bool
        Write an animated GIF of the frames.
    window_size : (int, int)
        Picture size in pixels, each side within :data:`WINDOW_SIZE`.
    """

    directory: Path = Path("results")
    pictures: bool = True
    gif: bool = True
    window_size: tuple[int, int] = (1024, 768)

    def __post_init__(self) -> None:
        lo, hi = WINDOW_SIZE
        for i, v in enumerate(self.window_size):
            if not lo <= v <= hi:
                raise invalid(f"window_size[{i}]", v, f"must lie in [{lo}, {hi}] pixels")
