"""Automatic flexion: bend one joint until a hand point touches an object.

The AUTO_F commands of Magnenat-Thalmann, Laperrière and Thalmann 1988 (section 7) take a
keyframe, a hand vertex, an object's facet and a joint, and find the flexion angle ``alpha``
with ``|DIST(alpha) - DIST| < epsilon`` by a dichotomous search instead of inverse
kinematics. Only the contact point is mapped at each step (the JLD mapping of its segment);
with ``first_contact`` also the skin nodes the joint moves, and the first of them to reach
the object stops the search. Here the object is any signed distance (negative inside);
:func:`sphere_distance` and :func:`plane_distance` build the usual ones,
:func:`mesh_distance` measures against a meshed surface as the contact search does (a coarse
ball's facets lie inside its sphere between their nodes) and :func:`surface_distance` wraps
a closed pyvista surface.

A scene can ask for a further press: ``target = -press`` finds the angle at which the point
lies ``press`` inside the undeformed object; the contact iteration then resolves that
interpenetration (the ball deforms, the flesh is pushed back).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import RigError
from ..geometry.surfacequery import TriangleSurface
from .jld import JLDMap
from .shipped import Hand

if TYPE_CHECKING:
    import pyvista

__all__ = [
    "FINGERTIPS",
    "AutoFlexResult",
    "auto_flex",
    "expected_halvings",
    "fingertip_node",
    "mesh_distance",
    "plane_distance",
    "sphere_distance",
    "surface_distance",
]

#: Named fingertips: the distal bone of each finger.
FINGERTIPS = {
    "thumb": "thumb_distal",
    "index": "index_distal",
    "middle": "middle_distal",
    "ring": "ring_distal",
    "little": "little_distal",
}

#: Boundary nodes tested at a time (farthest along the bone first) by :func:`fingertip_node`.
_CHUNK = 256

Distance = Callable[[NDArray[np.float64]], NDArray[np.float64]]


def sphere_distance(center: ArrayLike, radius: float) -> Distance:
    """Signed distance to a sphere (negative inside)."""
    c = np.asarray(center, dtype=np.float64)

    def dist(p: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.linalg.norm(np.atleast_2d(p) - c, axis=1) - radius

    return dist


def plane_distance(point: ArrayLike, normal: ArrayLike) -> Distance:
    """Signed distance to a plane (negative behind the unit ``normal``)."""
    q = np.asarray(point, dtype=np.float64)
    n = np.asarray(normal, dtype=np.float64)
    n = n / np.linalg.norm(n)

    def dist(p: NDArray[np.float64]) -> NDArray[np.float64]:
        return (np.atleast_2d(p) - q) @ n

    return dist


def mesh_distance(surface: TriangleSurface) -> Distance:
    """Signed distance to a closed triangle surface (negative inside), as contact measures it.

    The distance to the closest point of the facets, inside by the side of its
    pseudo-normal (:meth:`~contact.geometry.surfacequery.TriangleSurface.signed_distance`;
    exact on a closed surface that does not overlap itself). Between its nodes a coarse
    ball's facets lie inside its sphere by up to the chord's sagitta: a press measured
    against the sphere may not reach them.

    Raises
    ------
    SurfaceError
        If the surface is not closed and outward.
    """
    surface.check_closed()

    def dist(p: NDArray[np.float64]) -> NDArray[np.float64]:
        return surface.signed_distance(np.atleast_2d(p), sign="pseudonormal")

    return dist


def surface_distance(surface: pyvista.PolyData) -> Distance:
    """Signed distance to a closed, outward-oriented surface (negative inside)."""
    import vtk

    imp = vtk.vtkImplicitPolyDataDistance()
    imp.SetInput(surface)

    def dist(p: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.array([imp.EvaluateFunction(list(map(float, x))) for x in np.atleast_2d(p)])

    return dist


def _flesh_map(hand: Hand, nodes: NDArray[np.int64]) -> JLDMap:
    """The JLD map of flesh nodes, localised against the whole flesh."""
    return JLDMap(
        hand.skeleton,
        hand.flesh.points[nodes],
        hand.bone_id[nodes],
        reference=(hand.flesh.points, hand.bone_id),
    )


def _point_map(hand: Hand, node: int) -> JLDMap:
    """The JLD map of one flesh node, localised against the whole flesh (kept with the hand)."""
    cache = hand.derived
    if ("map", node) not in cache:
        cache["map", node] = _flesh_map(hand, np.array([node]))
    return cache["map", node]


def _moving_skin(hand: Hand, joint: str, base: Mapping[str, float]) -> tuple[NDArray, JLDMap]:
    """The skin nodes that ``joint`` moves, and their JLD map (kept with the hand).

    The nodes whose mapping changes between the joint's limits: the segments beyond the
    joint and the buffer areas around it. Found once per joint (the other angles as in the
    first call's ``base``: which nodes a joint moves does not depend on them).
    """
    cache = hand.derived
    if ("moving", joint) not in cache:
        if "skin map" not in cache:
            nodes = hand.skin_faces.nodes
            cache["skin map"] = (nodes, _flesh_map(hand, nodes))
        nodes, skin = cache["skin map"]
        lo, hi = hand.skeleton.limits[joint]
        a = skin.map({**base, joint: lo})
        b = skin.map({**base, joint: hi})
        moving = nodes[np.linalg.norm(a - b, axis=1) > 1e-9 * hand.skeleton.spec.min_flesh]
        cache["moving", joint] = (moving, _flesh_map(hand, moving))
    return cache["moving", joint]


def fingertip_node(hand: Hand, finger: str) -> int:
    """Flesh node at the tip of a named finger.

    The boundary node farthest along the finger's last bone, among those nearest its axis.

    Parameters
    ----------
    hand : Hand
    finger : {"thumb", "index", "middle", "ring", "little"}

    Returns
    -------
    int
        A boundary node of the flesh mesh.
    """
    if finger not in FINGERTIPS:
        raise RigError(f"unknown fingertip {finger!r}; expected one of {', '.join(FINGERTIPS)}")
    cache = hand.derived
    if ("tip", finger) not in cache:
        cache["tip", finger] = _fingertip_node(hand, finger)
    return cache["tip", finger]


def _fingertip_node(hand: Hand, finger: str) -> int:
    """:func:`fingertip_node` without the cache."""
    sk = hand.skeleton
    bone = sk.bones[FINGERTIPS[finger]]
    nodes = hand.flesh.boundary.nodes
    x = hand.flesh.points[nodes]
    a = np.stack([b.start for b in sk.bones.values()])
    ab = np.stack([b.end for b in sk.bones.values()]) - a
    own = sk.bone_names.index(bone.name)
    along = (x - bone.start) @ ((bone.end - bone.start) / bone.length)
    order = np.argsort(-along, kind="stable")  # the argmax's tie-break: the first node
    for chunk in np.array_split(order, max(1, len(order) // _CHUNK)):
        mine = _nearest_bone(x[chunk], a, ab) == own
        if mine.any():
            return int(nodes[chunk[np.argmax(mine)]])
    raise RigError(f"no boundary node of the flesh is nearest the bone {bone.name!r}")


def _nearest_bone(x: NDArray, a: NDArray, ab: NDArray) -> NDArray[np.int64]:
    """Index of the bone axis segment (start ``a``, vector ``ab``) nearest each point."""
    t = np.clip(np.einsum("nbk,bk->nb", x[:, None] - a, ab) / (ab * ab).sum(1), 0.0, 1.0)
    return np.argmin(np.linalg.norm(x[:, None] - (a + t[..., None] * ab), axis=2), axis=1)


def expected_halvings(lever: float, interval: float, epsilon: float) -> int:
    """Halvings a dichotomous search needs at most: ``ceil(log2(lever * interval / eps))``.

    ``interval`` is the bracket halved, in degrees (the scan's step in :func:`auto_flex`).

    The distance of a point at ``lever`` metres from the joint changes by at most
    ``lever`` per radian, so once the bracket is narrower than ``epsilon / lever`` radians
    the midpoint is within ``epsilon`` of the root.
    """
    return max(0, math.ceil(math.log2(lever * math.radians(interval) / epsilon)))


@dataclass(frozen=True)
class AutoFlexResult:
    """The outcome of :func:`auto_flex`.

    Attributes
    ----------
    joint : str
        The angle searched (a flexion ``"index_pip"`` or pivot ``"..._pivot"``).
    node : int
        The flesh node that reached the target: the point, or the first skin node the
        joint moves into the object before it (the pad of a finger before its tip).
    angle : float
        Degrees found (the best bracket end when not converged).
    distance : float
        Signed distance of the point to the object at ``angle`` (m).
    target : float
        The distance sought (0, or ``-press``).
    halvings : int
        Bisection steps taken (after the scan).
    converged : bool
        ``|distance - target| < epsilon``.
    reason : str
        Why it stopped.
    angles : dict of str to float
        The full pose with the found angle.
    history : list of (float, float)
        ``(angle, distance)`` of every evaluation.
    """

    joint: str
    node: int
    angle: float
    distance: float
    target: float
    halvings: int
    converged: bool
    reason: str
    angles: dict[str, float]
    history: list[tuple[float, float]] = field(default_factory=list)


def auto_flex(
    hand: Hand,
    point: int | str,
    distance: Distance,
    joint: str,
    angles: Mapping[str, float] | None = None,
    press: float = 0.0,
    epsilon: float = 1e-5,
    bracket: tuple[float, float] | None = None,
    scan: int = 16,
    max_halvings: int = 60,
    first_contact: bool = False,
) -> AutoFlexResult:
    """Find the flexion of ``joint`` at which a hand point reaches an object.

    Parameters
    ----------
    hand : Hand
    point : int or str
        A flesh node index, or a named fingertip (:data:`FINGERTIPS`).
    distance : callable
        Signed distance to the object's surface, ``(n, 3) -> (n,)``, negative inside.
    joint : str
        The angle to search (``"index_pip"``, ``"index_mcp"``, ``"wrist"``...).
    angles : mapping of str to float, optional
        The rest of the pose (a keyframe); the searched angle's value there is ignored.
    press : float
        Depth (m) to press past first contact: the target distance is ``-press``.
    epsilon : float
        Tolerance on the distance (m).
    bracket : (float, float), optional
        Angles (degrees) to search from and to; default from the angle in ``angles``
        (0 if absent) to the joint's upper limit. The search moves from the first end.
    scan : int
        The bracket is first walked in ``scan`` equal steps to the first one past the
        target (the first contact, not a later exit from the object); that step is then
        halved until the distance is within ``epsilon``.
    max_halvings : int
    first_contact : bool
        False (the paper's AUTO_F): the point alone reaches the target. True: the first
        skin node the joint moves to the target stops the search, the point or another
        (a finger's pad before its tip, on a small ball), so that the flexion never drives
        the finger through the object to bring the point there; nodes already past the
        target at the bracket's start are left out (contacts the solver resolves).

    Returns
    -------
    AutoFlexResult
        ``converged`` False (with the reason) when the point cannot reach the target
        within the bracket: the angle is then the bracket end nearest it.

    Raises
    ------
    RigError
        On an unknown joint angle or point name, or a bracket outside the limits.
    """
    sk = hand.skeleton
    limits = sk.limits
    if joint not in limits:
        raise RigError(f"auto_flex: unknown joint angle {joint!r}")
    node = fingertip_node(hand, point) if isinstance(point, str) else int(point)
    if not 0 <= node < hand.flesh.n_points:
        raise RigError(f"auto_flex: hand point {node} is not a flesh node")
    start = float((angles or {}).get(joint, 0.0))
    lo, hi = bracket if bracket is not None else (start, limits[joint][1])
    if not limits[joint][0] <= lo < hi <= limits[joint][1]:
        raise RigError(
            f"auto_flex: bracket [{lo:g}, {hi:g}] of {joint} must lie within its limits "
            f"[{limits[joint][0]:g}, {limits[joint][1]:g}] and increase"
        )
    base = {k: float(v) for k, v in (angles or {}).items()}
    jld = _point_map(hand, node)
    target = -float(press)
    history: list[tuple[float, float]] = []
    # with first_contact, the skin nodes the joint moves, less those already past the
    # target at the start (contacts the solver resolves): the first to reach it stops
    others, guard, keep = np.zeros(0, dtype=np.int64), None, np.zeros(0, dtype=bool)
    if first_contact:
        moving, guard = _moving_skin(hand, joint, base)
        keep = (distance(guard.map({**base, joint: lo})) > target) & (moving != node)
        others = moving[keep]
    who: dict[float, int] = {}

    def f(alpha: float) -> float:
        pose = {**base, joint: alpha}
        d = float(distance(jld.map(pose))[0])
        who[alpha] = node
        if others.size:
            dg = distance(guard.map(pose)[keep])  # type: ignore[union-attr]
            k = int(np.argmin(dg))
            if dg[k] < d:
                d, who[alpha] = float(dg[k]), int(others[k])
        history.append((alpha, d))
        return d - target

    def done(alpha: float, fa: float, n: int, ok: bool, why: str) -> AutoFlexResult:
        return AutoFlexResult(
            joint,
            who.get(alpha, node),
            alpha,
            fa + target,
            target,
            n,
            ok,
            why,
            {**base, joint: alpha},
            history,
        )

    # march from the bracket's start to the first sign change (first contact), then halve
    grid = np.linspace(lo, hi, scan + 1)
    f_lo = f(lo)
    if abs(f_lo) < epsilon:
        return done(lo, f_lo, 0, True, "within epsilon at the bracket's start")
    if f_lo < 0.0:
        return done(lo, f_lo, 0, False, "the point is already past the target at the start")
    for a in grid[1:]:
        fa = f(float(a))
        if abs(fa) < epsilon:
            return done(float(a), fa, 0, True, "within epsilon on the scan")
        if fa < 0.0:
            hi = float(a)
            break
        lo, f_lo = float(a), fa
    else:
        return done(lo, f_lo, 0, False, "the point does not reach the object within the bracket")
    n = 0
    while n < max_halvings:
        mid = 0.5 * (lo + hi)
        fm = f(mid)
        n += 1
        if abs(fm) < epsilon:
            return done(mid, fm, n, True, "within epsilon")
        if fm > 0:
            lo, f_lo = mid, fm
        else:
            hi = mid
    return done(mid, fm, n, False, f"no convergence in {max_halvings} halvings")
