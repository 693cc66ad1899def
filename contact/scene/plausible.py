"""A scene that reads but asks for what no grasp has, or what its meshes cannot resolve.

A friction coefficient above measure:
Coulomb coefficients measured for skin run from about 0.2 (dry skin on smooth plastic or
glass) to about 2 (moist skin on rubber). A coefficient above :data:`MAX_FRICTION` is
allowed, since the solver handles it, but warned of in one log line naming the key: a
grip that needs it is not one a hand can make, and a search for a finger's force is then
likely to end short of its target.

Weighted gaps on the coarse hand: its fingertip's skin nodes (about 5 mm apart) are
wider than a press's contact patch, and a weighted gap, the mean of the overlap over a
node's faces, closes only well past first touch (the finger-press fingertip about 1 mm
into the ball by its nodes, where the fine hand's close at first touch:
``benchmarks/results/flexion.md``). Warned of, naming the keys.
"""

from __future__ import annotations

import logging

from .spec import Scene

__all__ = ["MAX_FRICTION", "friction_keys", "warn_coarse_gaps", "warn_friction"]

log = logging.getLogger(__name__)

#: The largest Coulomb coefficient measured for skin on common materials.
MAX_FRICTION = 2.0


def friction_keys(scene: Scene) -> list[tuple[str, float]]:
    """Every friction coefficient the scene gives, with its key path, in file order."""
    out = [] if scene.ball_friction is None else [("ball.friction", scene.ball_friction)]
    out += [(f"plane[{i}].friction", p.friction) for i, p in enumerate(scene.planes)]
    if scene.hand is not None:
        out.append(("hand.friction", scene.hand.friction))
    out += [(f"object[{i}].friction", o.friction) for i, o in enumerate(scene.objects)]
    return [(key, float(mu)) for key, mu in out if mu is not None]


def warn_friction(scene: Scene, source: str) -> None:
    """One warning for each coefficient above :data:`MAX_FRICTION`, naming its key.

    Parameters
    ----------
    scene : Scene
        The scene as read.
    source : str
        The scene file, named first in each line.
    """
    for key, mu in friction_keys(scene):
        if mu > MAX_FRICTION:
            log.warning(
                "%s: %s = %g: above %g, past the coefficients measured for skin on common "
                "materials (0.2 to 2)",
                source, key, mu, MAX_FRICTION,
            )  # fmt: skip


def warn_coarse_gaps(scene: Scene, source: str) -> None:
    """One warning where the coarse hand meets objects by weighted gaps."""
    hand, gaps = scene.hand, scene.solver.contact.gaps
    if hand is None or gaps != "weighted" or hand.resolution != "coarse":
        return
    if scene.ball is None and not scene.objects:
        return
    log.warning(
        '%s: solver.gaps = "weighted" with hand.resolution = "coarse": the coarse '
        "fingertip's nodes are wider than a press's patch, and its weighted gaps close "
        'only about 1 mm past first touch; use hand.resolution = "fingertips" or "fine"',
        source,
    )
