"""Keyframed joint angles, interpolated by Kochanek-Bartels splines.

Magnenat-Thalmann, Laperrière and Thalmann 1988 (section 2) give key values for each joint
angle and compute the in-betweens with the splines of their reference 18: Kochanek and
Bartels, "Interpolating splines with local tension, continuity and bias control", SIGGRAPH
1984. Each key ``i`` carries a tension ``T``, a continuity ``C`` and a bias ``B`` (all 0 by
default, which gives the Catmull-Rom spline). With ``d0 = P[i] - P[i-1]`` and ``d1 = P[i+1]
- P[i]`` the tangents arriving at and leaving key ``i`` are::

    TS[i] = (1-T)(1-C)(1+B)/2 d0 + (1-T)(1+C)(1-B)/2 d1      (incoming, "source")
    TD[i] = (1-T)(1+C)(1+B)/2 d0 + (1-T)(1-C)(1-B)/2 d1      (outgoing, "destination")

scaled for unequal key spacing by ``2 dt[i] / (dt[i-1] + dt[i])`` (outgoing) and
``2 dt[i-1] / (dt[i-1] + dt[i])`` (incoming), as the paper does for frame counts, and the
span from key ``i`` to ``i+1`` is the cubic Hermite curve through ``P[i]``, ``P[i+1]`` with
tangents ``TD[i]`` and ``TS[i+1]``. At the first and last key the missing neighbour is the
reflection of the other one (``P[-1] = 2 P[0] - P[1]``), a natural end.

Each angle is its own channel: its keys are the keyframes that give it. An angle that no
keyframe gives stays at 0 (rest). Before the first key and after the last, an angle holds
its end value. The spline can overshoot a key value; where it leaves the joint's limits it
is clamped, and every clamp is reported.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import RigError
from .skeleton import Skeleton

__all__ = ["Clamp", "Key", "Keyframes", "kb_tangents", "kochanek_bartels"]


@dataclass(frozen=True)
class Key:
    """One keyframe: a time, angles (degrees) by name, and the spline's shape there.

    Attributes
    ----------
    time : float
        Seconds (any increasing unit).
    angles : dict of str to float
        Degrees by angle name (``"index_pip"``, ``"index_mcp_pivot"``).
    tension, continuity, bias : float
        Kochanek-Bartels parameters at this key, each in [-1, 1].
    """

    time: float
    angles: dict[str, float]
    tension: float = 0.0
    continuity: float = 0.0
    bias: float = 0.0


@dataclass(frozen=True)
class Clamp:
    """An interpolated angle that overshot its joint's limit and was clamped."""

    angle: str
    time: float
    value: float
    """The spline's value (degrees)."""
    limit: float
    """The limit it was clamped to (degrees)."""

    def __str__(self) -> str:
        return (
            f"{self.angle} at t = {self.time:g}: interpolated {self.value:.3f} deg clamped "
            f"to its limit {self.limit:g}"
        )


def kb_tangents(
    times: ArrayLike,
    values: ArrayLike,
    tension: ArrayLike = 0.0,
    continuity: ArrayLike = 0.0,
    bias: ArrayLike = 0.0,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Incoming and outgoing Kochanek-Bartels tangents at every key.

    Parameters
    ----------
    times : array_like, shape (K,)
        Strictly increasing key times.
    values : array_like, shape (K,)
        Key values.
    tension, continuity, bias : array_like, shape (K,) or scalar

    Returns
    -------
    incoming, outgoing : ndarray, shape (K,)
        ``TS`` and ``TD`` of the module docstring, per unit of the local span parameter.
    """
    t = np.asarray(times, dtype=np.float64)
    p = np.asarray(values, dtype=np.float64)
    k = len(p)
    tn, c, b = (
        np.broadcast_to(np.asarray(v, dtype=np.float64), (k,)) for v in (tension, continuity, bias)
    )
    if k == 1:
        return np.zeros(1), np.zeros(1)
    ext = np.concatenate([[2.0 * p[0] - p[1]], p, [2.0 * p[-1] - p[-2]]])
    text = np.concatenate([[2.0 * t[0] - t[1]], t, [2.0 * t[-1] - t[-2]]])
    d0 = ext[1:-1] - ext[:-2]
    d1 = ext[2:] - ext[1:-1]
    dt0 = text[1:-1] - text[:-2]
    dt1 = text[2:] - text[1:-1]
    ts = (1 - tn) * (1 - c) * (1 + b) / 2 * d0 + (1 - tn) * (1 + c) * (1 - b) / 2 * d1
    td = (1 - tn) * (1 + c) * (1 + b) / 2 * d0 + (1 - tn) * (1 - c) * (1 - b) / 2 * d1
    ts = ts * 2.0 * dt0 / (dt0 + dt1)
    td = td * 2.0 * dt1 / (dt0 + dt1)
    return ts, td


def kochanek_bartels(
    times: ArrayLike,
    values: ArrayLike,
    at: ArrayLike,
    tension: ArrayLike = 0.0,
    continuity: ArrayLike = 0.0,
    bias: ArrayLike = 0.0,
) -> NDArray[np.float64]:
    """Evaluate the Kochanek-Bartels spline through keys at times ``at``, vectorised.

    Parameters
    ----------
    times : array_like, shape (K,)
        Strictly increasing key times.
    values : array_like, shape (K,)
    at : array_like
        Times to evaluate; outside the keys the end values hold.
    tension, continuity, bias : array_like, shape (K,) or scalar

    Returns
    -------
    ndarray, shape of ``at``
    """
    t = np.asarray(times, dtype=np.float64)
    p = np.asarray(values, dtype=np.float64)
    q = np.asarray(at, dtype=np.float64)
    if len(p) == 1:
        return np.full(q.shape, p[0])
    ts, td = kb_tangents(t, p, tension, continuity, bias)
    i = np.clip(np.searchsorted(t, q, side="right") - 1, 0, len(t) - 2)
    u = np.clip((q - t[i]) / (t[i + 1] - t[i]), 0.0, 1.0)
    u2, u3 = u * u, u * u * u
    h00 = 2 * u3 - 3 * u2 + 1
    h10 = u3 - 2 * u2 + u
    h01 = -2 * u3 + 3 * u2
    h11 = u3 - u2
    return h00 * p[i] + h10 * td[i] + h01 * p[i + 1] + h11 * ts[i + 1]


@dataclass
class Keyframes:
    """Validated keyframes of a hand: angles at any time, with the clamps reported.

    Parameters
    ----------
    skeleton : Skeleton
        Names and limits of the angles.
    keys : sequence of Key or mapping
        Keyframes in time order; a mapping has ``time``, ``angles`` and optionally
        ``tension``, ``continuity``, ``bias``.

    Raises
    ------
    RigError
        Naming the key (index and time) and the joint: an unknown angle, a key angle
        outside its limits, key times that do not increase, or a spline parameter
        outside [-1, 1].

    Examples
    --------
    >>> kf = Keyframes(sk, [{"time": 0, "angles": {"index_mcp": 0}},
    ...                     {"time": 1, "angles": {"index_mcp": 45}}])  # doctest: +SKIP
    >>> kf.angles(0.5)["index_mcp"]  # doctest: +SKIP
    22.5
    """

    skeleton: Skeleton
    keys: Sequence[Key | Mapping]
    clamps: list[Clamp] = field(default_factory=list, init=False)

    def __post_init__(self) -> None:
        keys = [k if isinstance(k, Key) else _key(k, i) for i, k in enumerate(self.keys)]
        if not keys:
            raise RigError("keyframes: at least one key is required")
        limits = self.skeleton.limits
        for i, k in enumerate(keys):
            where = f"keyframe {i} (t = {k.time:g})"
            if not np.isfinite(k.time):
                raise RigError(f"{where}: time must be finite")
            if i and not k.time > keys[i - 1].time:
                raise RigError(
                    f"{where}: key times must increase (previous key at t = {keys[i - 1].time:g})"
                )
            for name in ("tension", "continuity", "bias"):
                v = getattr(k, name)
                if not (np.isfinite(v) and -1.0 <= v <= 1.0):
                    raise RigError(f"{where}: {name} = {v!r} must lie in [-1, 1]")
            for name, value in k.angles.items():
                if name not in limits:
                    raise RigError(
                        f"{where}: unknown joint angle {name!r} (angles: {', '.join(limits)})"
                    )
                lo, hi = limits[name]
                if not (np.isfinite(value) and lo <= value <= hi):
                    raise RigError(
                        f"{where}: joint angle {name} = {value:g} deg is outside its "
                        f"limits [{lo:g}, {hi:g}]"
                    )
        self.keys = keys
        self._channels: dict[str, tuple[NDArray, ...]] = {}
        for name in limits:
            at = [k for k in keys if name in k.angles]
            if at:
                self._channels[name] = tuple(
                    np.array(v, dtype=np.float64)
                    for v in (
                        [k.time for k in at],
                        [k.angles[name] for k in at],
                        [k.tension for k in at],
                        [k.continuity for k in at],
                        [k.bias for k in at],
                    )
                )

    @property
    def times(self) -> NDArray[np.float64]:
        """Key times."""
        return np.array([k.time for k in self.keys])

    @property
    def animated(self) -> list[str]:
        """Names of the angles some key gives."""
        return list(self._channels)

    def angles(self, time: ArrayLike, report: bool = True) -> dict[str, NDArray[np.float64]]:
        """Every angle (degrees) at ``time``, clamped to its joint's limits.

        Parameters
        ----------
        time : float or array_like
            Times to evaluate; arrays give arrays.
        report : bool
            Record each clamp in :attr:`clamps` and warn (``RuntimeWarning``) naming it.

        Returns
        -------
        dict of str to ndarray
            Keyed by every angle of the skeleton; unanimated angles are 0.
        """
        q = np.asarray(time, dtype=np.float64)
        out: dict[str, NDArray[np.float64]] = {}
        for name, (lo, hi) in self.skeleton.limits.items():
            ch = self._channels.get(name)
            if ch is None:
                out[name] = np.zeros(q.shape)
                continue
            v = kochanek_bartels(ch[0], ch[1], q, ch[2], ch[3], ch[4])
            c = np.clip(v, lo, hi)
            bad = np.flatnonzero((c != v).ravel())
            if report and len(bad):
                for j in bad:
                    clamp = Clamp(
                        name,
                        float(np.ravel(q)[j] if q.ndim else q),
                        float(v.ravel()[j]),
                        float(c.ravel()[j]),
                    )
                    self.clamps.append(clamp)
                    warnings.warn(str(clamp), RuntimeWarning, stacklevel=2)
            out[name] = c
        return out

    def pose(self, time: float) -> dict[str, float]:
        """The angles at one time as plain floats (for :func:`contact.pose_hand`)."""
        return {k: float(v) for k, v in self.angles(float(time)).items()}


def _key(data: Mapping, i: int) -> Key:
    if not isinstance(data, Mapping):
        raise RigError(f"keyframe {i}: must be a table with time and angles")
    unknown = set(data) - {"time", "angles", "tension", "continuity", "bias"}
    if unknown:
        raise RigError(f"keyframe {i}: unknown key {sorted(unknown)[0]!r}")
    if "time" not in data or "angles" not in data:
        raise RigError(f"keyframe {i}: time and angles are required")
    time = data["time"]
    if isinstance(time, bool) or not isinstance(time, (int, float)):
        raise RigError(f"keyframe {i}: time = {time!r} must be a number")
    angles = data["angles"]
    if not isinstance(angles, Mapping):
        raise RigError(f"keyframe {i} (t = {time:g}): angles must be a table")
    values = {}
    for name, v in angles.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise RigError(f"keyframe {i} (t = {time:g}): angle {name} = {v!r} must be a number")
        values[str(name)] = float(v)
    extra = {}
    for name in ("tension", "continuity", "bias"):
        if name in data:
            v = data[name]
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise RigError(f"keyframe {i} (t = {time:g}): {name} = {v!r} must be a number")
            extra[name] = float(v)
    return Key(float(time), values, **extra)
