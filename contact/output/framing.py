"""Where the pictures look: the grasp's box, the main view and one view per body.

Every frame of a run is drawn with the same cameras, so that frames compare:

- the *focus box* holds the held body (the ball) in every frame and every contact node
  of every body in every frame (the hand's contact zone), padded by :data:`_PAD`; the
  main view fits this box, so that planes and the far parts of the hand do not decide
  the framing. It keeps a given camera's view direction; by default it looks across the
  *grasp axis* (from the held body to the other bodies' parts in the box: from the
  ball to the palm), from the side of :data:`DEFAULT_VIEW` and a little from the ball's
  side (:data:`_TILT`), so that the ball, the hand around it and the gap between them
  show; looking down :data:`DEFAULT_VIEW` would show the back of the hand over the ball;
  and where the other bodies hide the ball's contacts from there (a pinch seen from the
  back of the index), it turns to the direction nearest it from which they are seen
  (:func:`clear_direction`);
- each body's own view looks at the body's part inside the focus box from the side of the
  other bodies (from the ball onto the hand's palmar skin), where its contacts and their
  stress are; the held body's (the ball's) view, which carries the force arrows, looks
  from the main view's direction, so that the arrows are seen side on
  (:func:`held_view`).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

log = logging.getLogger(__name__)

__all__ = [
    "DEFAULT_VIEW",
    "View",
    "body_views",
    "clear_direction",
    "focus_box",
    "grasp_axis",
    "held_view",
    "main_view",
    "view_from",
    "visible",
]

#: Main camera when none is given: the direction from the focus to the eye, and view up:
#: obliquely from ``(+x, -y, +z)`` with ``z`` up.
DEFAULT_VIEW = ((1.0, -1.6, 1.0), (0.0, 0.0, 1.0))
#: Padding of the focus box, as a fraction of its largest side on each side.
_PAD = 0.12
#: How far the default main view turns from across the grasp axis toward the ball's side
#: (the tangent of the angle).
_TILT = 0.35


@dataclass(frozen=True)
class View:
    """A camera: eye position, focal point, view up, and the box it must show.

    Attributes
    ----------
    position, focus, up : tuple of float
    box : list of float
        ``[xmin, xmax, ymin, ymax, zmin, zmax]`` fitted by the camera.
    """

    position: tuple[float, float, float]
    focus: tuple[float, float, float]
    up: tuple[float, float, float]
    box: list[float]

    @property
    def camera(self) -> list[tuple[float, float, float]]:
        """Pyvista's camera position ``[position, focal point, view up]``."""
        return [self.position, self.focus, self.up]


def view_from(
    focus: NDArray[np.float64], direction: NDArray[np.float64], span: float, box: NDArray
) -> View:
    """A view of ``box`` ``(2, 3)`` at ``focus`` from three ``span`` along unit ``direction``."""
    return View(tuple(focus + 3 * span * direction), tuple(focus), _up(direction), _flat(box))


def _box(points: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.array([points.min(axis=0), points.max(axis=0)])


def focus_box(
    bodies: Sequence[Sequence[NDArray[np.float64]]],
    contacts: Sequence[NDArray[np.float64]],
    held: int,
) -> NDArray[np.float64]:
    """The box around the held body and every contact node, padded.

    Parameters
    ----------
    bodies : sequence of sequence of ndarray (N, 3)
        Per body, its deformed points in every frame.
    contacts : sequence of ndarray (k, 3)
        Contact nodes (deformed) of every body and frame.
    held : int
        Which of ``bodies`` is held (:func:`contact.output.picturedata.held_body`).

    Returns
    -------
    ndarray (2, 3)
        Lower and upper corner.
    """
    pts = [_box(np.concatenate(bodies[held])), *(c for c in contacts if len(c))]
    lo = np.min([p.min(axis=0) for p in pts], axis=0)
    hi = np.max([p.max(axis=0) for p in pts], axis=0)
    pad = _PAD * float((hi - lo).max())
    return np.array([lo - pad, hi + pad])


def _flat(box: NDArray[np.float64]) -> list[float]:
    return [float(v) for v in box.T.ravel()]


def _up(direction: NDArray[np.float64]) -> tuple[float, float, float]:
    """``z`` up unless looking along ``z``, then ``y``."""
    z = np.array([0.0, 0.0, 1.0])
    return (0.0, 1.0, 0.0) if abs(float(direction @ z)) > 0.95 else (0.0, 0.0, 1.0)


#: Directions the main view may take to see the held body's contacts (a Fibonacci
#: sphere), and how many of them at most are tested against each frame.
_DIRECTIONS = 64
_SAMPLE = 60
#: A contact point is hidden by a surface nearer the eye by more than this fraction of
#: the focus box (the touching surface itself does not hide it).
_DEPTH = 0.03
#: Directions whose share of contacts seen is within this of the best are equal: the one
#: nearest the grasp-axis view is taken.
_EQUAL = 0.05


def visible(
    points: NDArray[np.float64],
    direction: NDArray[np.float64],
    triangles: NDArray[np.float64],
    depth: float = 0.0,
) -> NDArray[np.bool_]:
    """Which ``points (k, 3)`` no triangle ``(t, 3, 3)`` hides, seen from along ``direction``.

    An orthographic view (the main view's eye is three box sizes away): a point is hidden
    where a triangle covers its projection nearer the eye by more than ``depth``.
    """
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    e1 = np.cross(d, [1.0, 0.0, 0.0] if abs(d[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(d, e1)
    basis = np.stack([e1, e2], axis=1)
    if not len(points) or not len(triangles):
        return np.ones(len(points), dtype=bool)
    p, z = points @ basis, points @ d  # (k, 2), (k,)
    t, tz = triangles @ basis, triangles @ d  # (t, 3, 2), (t, 3)
    a, b, c = t[:, 0], t[:, 1], t[:, 2]
    area = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    ok = np.abs(area) > 1e-30
    a, b, c, tz, area = a[ok], b[ok], c[ok], tz[ok], area[ok]

    def edge(u, v):  # (k, t): twice the signed area of (u, v, p) over the triangle's
        return (
            (v[:, 0] - u[:, 0])[None] * (p[:, 1, None] - u[:, 1][None])
            - (v[:, 1] - u[:, 1])[None] * (p[:, 0, None] - u[:, 0][None])
        ) / area[None]

    w0, w1, w2 = edge(b, c), edge(c, a), edge(a, b)
    inside = (w0 >= 0) & (w1 >= 0) & (w2 >= 0)
    front = w0 * tz[None, :, 0] + w1 * tz[None, :, 1] + w2 * tz[None, :, 2] > z[:, None] + depth
    return ~(inside & front).any(axis=1)


def clear_direction(
    contacts: Sequence[NDArray[np.float64]],
    occluders: Sequence[NDArray[np.float64]],
    preferred: NDArray[np.float64],
    span: float,
) -> NDArray[np.float64]:
    """The direction (to the eye) from which most of the held body's contacts are seen.

    ``contacts[i]`` and ``occluders[i]`` are frame ``i``'s contact points ``(k, 3)`` and
    the other bodies' surface triangles ``(t, 3, 3)``; each direction of a Fibonacci
    sphere is scored by the share of every frame's contacts it sees, and of those within
    :data:`_EQUAL` of the best the one nearest ``preferred`` is taken.
    """
    pairs = [(c, o) for c, o in zip(contacts, occluders, strict=True) if len(c)]
    if not pairs:
        return preferred
    rng = np.random.default_rng(0)
    pairs = [
        (c[rng.choice(len(c), _SAMPLE, replace=False)] if len(c) > _SAMPLE else c, o)
        for c, o in pairs
    ]
    i = np.arange(_DIRECTIONS) + 0.5
    polar = np.arccos(1 - 2 * i / _DIRECTIONS)
    turn = np.pi * (1 + 5**0.5) * i
    dirs = np.column_stack(
        [np.cos(turn) * np.sin(polar), np.sin(turn) * np.sin(polar), np.cos(polar)]
    )
    dirs = np.vstack([preferred / np.linalg.norm(preferred), dirs])
    score = np.array([
        np.mean([visible(c, d, o, _DEPTH * span).mean() for c, o in pairs]) for d in dirs
    ])  # fmt: skip
    near = dirs @ (preferred / np.linalg.norm(preferred))
    good = score >= score.max() - _EQUAL
    best = np.flatnonzero(good)[np.argmax(near[good])]
    log.debug(
        "main view: %.0f %% of the contacts seen (%.0f %% from the grasp-axis view)",
        100 * score[best],
        100 * score[0],
    )
    return dirs[best]


def main_view(
    box: NDArray[np.float64],
    camera: tuple | None = None,
    axis: NDArray[np.float64] | None = None,
    sight: tuple | None = None,
) -> View:
    """The main view of the focus box, fitted to it.

    Parameters
    ----------
    box : ndarray (2, 3)
        The focus box.
    camera : tuple, optional
        pyvista camera position ``(position, focal point, view up)``: its direction kept.
    axis : ndarray (3,), optional
        The grasp axis (:func:`grasp_axis`): without a camera, the view looks across it.
    sight : (contacts, occluders), optional
        Without a camera, the held body's contact points and the other bodies' triangles
        per frame (:func:`clear_direction`): the view turns, as little as it may, to
        where the contacts are seen rather than the back of a finger.

    Returns
    -------
    View
    """
    centre = box.mean(axis=0)
    span = float((box[1] - box[0]).max()) or 1.0
    if camera is not None:
        pos, foc, up = (np.asarray(v, dtype=np.float64) for v in camera)
        d = pos - foc
    else:
        d, up = (np.asarray(v, dtype=np.float64) for v in DEFAULT_VIEW)
        d = d / np.linalg.norm(d)
        if axis is not None:
            across = d - (d @ axis) * axis
            if np.linalg.norm(across) < 0.1:  # looking along the axis: turn to x
                across = np.array([1.0, 0.0, 0.0]) - axis[0] * axis
            d = across / np.linalg.norm(across) - _TILT * axis
        if sight is not None:
            d = clear_direction(sight[0], sight[1], d / np.linalg.norm(d), span)
        up = np.asarray(_up(d / np.linalg.norm(d)))
    d = d / (np.linalg.norm(d) or 1.0)
    return View(tuple(centre + 3 * span * d), tuple(centre), tuple(map(float, up)), _flat(box))


def grasp_axis(
    bodies: Sequence[Sequence[NDArray[np.float64]]], box: NDArray[np.float64], held: int
) -> NDArray[np.float64] | None:
    """Unit vector from the held body's centre to the other bodies' parts in the box.

    Parameters
    ----------
    bodies : sequence of sequence of ndarray (N, 3)
        Per body, its deformed points in every frame.
    box : ndarray (2, 3)
        The focus box.
    held : int
        Which of ``bodies`` is held.

    Returns
    -------
    ndarray (3,) or None
        None with a single body, or when no other body reaches into the box.
    """
    if len(bodies) < 2:
        return None
    pts = [np.concatenate(frames) for frames in bodies]
    lo, hi = box
    others = [p[np.all((p >= lo) & (p <= hi), axis=1)] for j, p in enumerate(pts) if j != held]
    others = [o for o in others if len(o)]
    if not others:
        return None
    d = np.concatenate(others).mean(axis=0) - pts[held].mean(axis=0)
    n = float(np.linalg.norm(d))
    return d / n if n > 0 else None


def body_views(
    bodies: Sequence[Sequence[NDArray[np.float64]]], box: NDArray[np.float64]
) -> list[View]:
    """Each body's view: its part in the focus box, seen from the other bodies' side.

    Parameters
    ----------
    bodies : sequence of sequence of ndarray (N, 3)
        Per body, its deformed points in every frame.
    box : ndarray (2, 3)
        The focus box.

    Returns
    -------
    list of View
        One per body; a body with no point in the box is seen whole, a body alone from
        the default direction.
    """
    parts, centres = [], []
    for frames in bodies:
        pts = np.concatenate(frames)
        inside = np.all((pts >= box[0]) & (pts <= box[1]), axis=1)
        part = pts[inside] if inside.any() else pts
        parts.append(part)
        centres.append(part.mean(axis=0))
    views = []
    for k, part in enumerate(parts):
        others = [c for j, c in enumerate(centres) if j != k]
        d = np.mean(others, axis=0) - centres[k] if others else np.asarray(DEFAULT_VIEW[0])
        n = float(np.linalg.norm(d))
        d = d / n if n > 0 else np.asarray(DEFAULT_VIEW[0]) / np.linalg.norm(DEFAULT_VIEW[0])
        b = _box(part)
        span = float((b[1] - b[0]).max()) or 1.0
        c = b.mean(axis=0)
        views.append(view_from(c, d, span, b))
    return views


def held_view(main: View, frames: Sequence[NDArray[np.float64]], reach: float) -> View:
    """The held body alone, from the main view's direction, with room for the arrows.

    Parameters
    ----------
    main : View
        The main view.
    frames : sequence of ndarray (N, 3)
        The body's deformed points in every frame.
    reach : float
        The longest arrow, as a fraction of the body's size: the box is padded by it.

    Returns
    -------
    View
    """
    b = _box(np.concatenate(frames))
    c = b.mean(axis=0)
    pad = reach * float((b[1] - b[0]).max())
    d = np.asarray(main.position) - np.asarray(main.focus)
    return View(tuple(c + d), tuple(c), main.up, _flat(np.array([b[0] - pad, b[1] + pad])))
