"""Scenes shared by the benchmarks: the hand at rest pressing a ball held in a cup.

:func:`hand_cup` is the scene of ``tests/test_contact_hand.py`` made reusable and
refinable: the shipped hand at rest (its bones prescribed, flesh ``E = 100 kPa``,
``nu = 0.4``) and a free ball of radius 20 mm under the palm, its top touching the lowest
skin node above its centre's footprint (that node lies off the ball's pole: the skin's
nearest node is about 2.5 mm from the ball, :func:`clearance`, so the ball touches the
palm once the cup has risen that far); the ball sits in a cup of four rigid planes tilted
35 degrees from the vertical (they hold it sideways, as fingers would), which rises by
``press`` into the palm. Contacts: the ball's nodes against the four planes, and node to
surface between ball and hand in both directions.

The mesh is refined through the hand's resolution (``"coarse"`` or ``"fine"``, the two
shipped meshes) and the ball's cells (``divisions`` along each edge of its core cube,
``layers`` from the core to the sphere); :data:`REFINEMENTS` names three levels.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

import fem
from contact.geometry.plane import Plane
from contact.hand.shipped import Hand, load_hand
from contact.solver.body import ElasticBody
from contact.solver.pairs import ContactPair

__all__ = [
    "BALL_RADIUS",
    "E_FLESH",
    "NU",
    "REFINEMENTS",
    "CupLevel",
    "ball_centre",
    "clearance",
    "hand_body",
    "hand_cup",
    "shipped_hand",
]

#: Ball radius (m).
BALL_RADIUS = 0.02
#: Young's modulus of the flesh (Pa); the ball's is ``ratio`` times it.
E_FLESH = 1.0e5
#: Poisson's ratio of flesh and ball.
NU = 0.4
#: Tilt of the cup's planes from the vertical (degrees).
CUP_TILT = 35.0
#: Where the ball's centre lies under the palm, in the hand's x-y plane (m).
FOOTPRINT = (0.01, 0.06)


@dataclass(frozen=True)
class CupLevel:
    """One refinement level of :func:`hand_cup`.

    Attributes
    ----------
    name : str
        For tables and plots.
    resolution : {"coarse", "fine"}
        The shipped hand mesh.
    divisions, layers : int
        The ball's cells (see :func:`fem.ball_mesh`).
    """

    name: str
    resolution: str
    divisions: int
    layers: int


#: Three refinement levels of the hand cup: the coarse hand with the ball of the tests
#: (hand skin cells about 4.9 mm, ball surface cells about 3.9 mm), then the fine hand
#: (skin cells about 2.8 mm) with a ball of about 2.6 mm and of about 2.0 mm surface cells.
REFINEMENTS = (
    CupLevel("coarse hand, ball 8/4", "coarse", 8, 4),
    CupLevel("fine hand, ball 12/6", "fine", 12, 6),
    CupLevel("fine hand, ball 16/8", "fine", 16, 8),
)


@functools.cache
def shipped_hand(resolution: str = "coarse") -> Hand:
    """The shipped hand of one resolution, read once per process."""
    return load_hand(resolution)


def hand_body(resolution: str = "coarse", modulus: float = E_FLESH) -> ElasticBody:
    """A new elastic body of the hand at rest: bones prescribed, skin the contact surface.

    Each call assembles and factors a new body, so that its solver's statistics (back-
    solves, compliance rows kept from earlier frames) start from zero.

    Parameters
    ----------
    resolution : {"coarse", "fine"}
    modulus : float
        Young's modulus of the flesh (Pa).

    Returns
    -------
    ElasticBody
        Named ``"hand"``, with one support group per bone.
    """
    h = shipped_hand(resolution)
    bones = {n: h.bone_nodes(n) for n in h.skeleton.bone_names if h.bone_nodes(n).size}
    return ElasticBody(
        "hand",
        h.flesh,
        fem.LinearElastic(modulus, NU),
        prescribed=fem.node_dofs(h.prescribed_nodes),
        supports=bones,
        contact_faces=h.skin_faces,
    )


def ball_centre(hand: ElasticBody, radius: float = BALL_RADIUS) -> NDArray[np.float64]:
    """Centre of the ball whose top touches the lowest skin node above its footprint (m)."""
    x, skin = hand.mesh.points, hand.contact_nodes
    centre = np.array(FOOTPRINT)
    under = skin[np.linalg.norm(x[skin, :2] - centre, axis=1) < radius]
    return np.array([*centre, x[under, 2].min() - radius])


def clearance(hand: ElasticBody, radius: float = BALL_RADIUS) -> float:
    """Distance from the ball of :func:`ball_centre` to the nearest skin node (m)."""
    x = hand.mesh.points[hand.contact_nodes]
    return float(np.min(np.linalg.norm(x - ball_centre(hand, radius), axis=1)) - radius)


def hand_cup(
    ratio: float,
    press: float,
    resolution: str = "coarse",
    *,
    divisions: int = 8,
    layers: int | None = None,
    radius: float = BALL_RADIUS,
    hand: ElasticBody | None = None,
) -> tuple[list[ElasticBody], list[ContactPair], list[Plane]]:
    """The hand at rest pressed by a ball that a rising cup of four planes holds.

    Parameters
    ----------
    ratio : float
        The ball's Young's modulus over the flesh's.
    press : float
        How far the cup rises into the palm (m).
    resolution : {"coarse", "fine"}
        The hand mesh (ignored when ``hand`` is given).
    divisions : int
        Cells along each edge of the ball's core cube.
    layers : int, optional
        Cells from the core to the sphere; ``divisions // 2`` by default.
    radius : float
        Ball radius (m).
    hand : ElasticBody, optional
        A hand body to reuse (from :func:`hand_body`); a new one by default.

    Returns
    -------
    bodies : list of ElasticBody
        The ball (first: the seed loop's Dirichlet body) and the hand.
    pairs : list of ContactPair
        The ball against each plane, then ball/hand and hand/ball.
    planes : list of Plane
        The four cup planes, moved by ``press`` along +z.
    """
    if not ratio > 0:
        raise ValueError(f"the modulus ratio must be positive, got {ratio!r}")
    hand = hand_body(resolution) if hand is None else hand
    flesh = hand.materials
    modulus = flesh.E if isinstance(flesh, fem.LinearElastic) else E_FLESH
    c = ball_centre(hand, radius)
    ball = ElasticBody(
        "ball",
        fem.ball_mesh(
            radius, divisions=divisions, layers=layers or max(divisions // 2, 1), center=c
        ),
        fem.LinearElastic(ratio * modulus, NU),
    )
    planes = []
    tilt = np.radians(CUP_TILT)
    for k, phi in enumerate(np.radians([0.0, 90.0, 180.0, 270.0])):
        d = np.array([np.sin(tilt) * np.cos(phi), np.sin(tilt) * np.sin(phi), -np.cos(tilt)])
        planes.append(Plane(c + radius * d, -d, motion=[0, 0, press], name=f"cup{k}"))
    pairs = [ContactPair(ball, p) for p in planes]
    pairs += [ContactPair(ball, hand), ContactPair(hand, ball)]
    return [ball, hand], pairs, planes
