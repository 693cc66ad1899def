"""A body other than the hand as a run places it, frame by frame: the ball or an ``[[object]]``.

A :class:`SceneObject` holds what lasts across frames (its mesh at the scene placement,
its material, the faces that can touch, its own loads) and what each frame adds: the
joint it follows, its weight and external load (the run adds the turn it has rolled,
:mod:`contact.run.rolling`). :meth:`SceneObject.body` gives the placed
:class:`~contact.solver.body.ElasticBody`, factored once and again only when the
placement turns it (a translation shares the factorisation). A ``fixed`` object is
rigid and held by the world: every node prescribed, its reactions the contact forces.
A ``finite`` (neo-Hookean) object's body is its reference for the finite-strain solve
(:mod:`contact.solver.finite`), which never factors its linear stiffness: it is not
assembled. It turns as far as its contacts take it and is never placed anew.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

import fem

from ..geometry.plane import Plane
from ..geometry.surfacequery import TriangleSurface, surface_of_mesh
from ..hand.objects import ObjectAssociation
from ..scene.model import Follow
from ..scene.objects import ObjectScene
from ..solver.body import ElasticBody
from ..solver.pairs import ContactPair
from .ball import Ball, nodal_pressure

__all__ = [
    "SceneObject", "body_pairs", "from_ball", "from_scene", "object_pairs", "plane_pairs",
]

log = logging.getLogger(__name__)

#: The external force and moment on an object at a time (N, N m), or None.
LoadAt = Callable[[float], "tuple[NDArray[np.float64], NDArray[np.float64]]"]


@dataclass
class SceneObject:
    """A ball or an object, placed for each frame.

    Parameters
    ----------
    name : str
        Its body name in results (``"ball"``, an ``[[object]]``'s name).
    mesh : fem.Mesh
        At its scene placement (hand frame).
    material : fem.LinearElastic
    faces : fem.BoundaryFaces
        The faces that can touch (a hollow ball's outer sphere; an object's boundary).
    loads : ndarray, shape (3N,)
        Its own loads at the scene placement (a hollow ball's pressure), turned with it.
    nodal_pressure : bool
        Tetrahedra with averaged nodal pressures.
    follow : Follow or None
        The joint it follows.
    fixed : bool
        Rigid, held by the world.
    centre : ndarray, shape (3,)
        The point about which an external load's moment is given, at the scene placement.
    finite : bool
        Neo-Hookean, solved at finite strain.
    follower : tuple of (fem.BoundaryFaces, float) or None
        A finite hollow ball's internal pressure, on its inner faces, following their
        deformation (then not in ``loads``).
    """

    name: str
    mesh: fem.Mesh
    material: fem.LinearElastic
    faces: fem.BoundaryFaces
    loads: NDArray[np.float64]
    nodal_pressure: bool = False
    follow: Follow | None = None
    fixed: bool = False
    centre: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    finite: bool = False
    follower: tuple[fem.BoundaryFaces, float] | None = None
    _body: ElasticBody | None = field(default=None, init=False, repr=False)
    _key: bytes = field(default=b"", init=False, repr=False)

    @property
    def rolls(self) -> bool:
        """A free linear object, placed by its contacts alone: it may roll and be placed anew.

        Neither follows a joint nor fixed; a finite one turns as far as it goes instead.
        """
        return not self.fixed and self.follow is None and not self.finite

    def transform(self, skeleton: object, pose: Callable | None, t: float) -> NDArray[np.float64]:
        """Its rigid placement at ``t`` from the scene's (4x4): its joint's, if it follows one."""
        if self.follow is None or skeleton is None or pose is None:
            return np.eye(4)
        f = self.follow
        assoc = ObjectAssociation(self.name, f.joint, f.start, f.stop)
        return assoc.transform(skeleton, pose, t)

    def points(self, tf: NDArray[np.float64]) -> NDArray[np.float64]:
        """Its nodes placed by ``tf``."""
        return self.mesh.points @ tf[:3, :3].T + tf[:3, 3]

    def surface(self, tf: NDArray[np.float64]) -> TriangleSurface:
        """Its contact surface placed by ``tf``: the facets the contact search meets."""
        tri = surface_of_mesh(self.mesh, self.faces)[1]
        return TriangleSurface(self.points(tf), tri, name=self.name)

    def body(
        self,
        tf: NDArray[np.float64],
        t: float,
        gravity: tuple[float, float, float] | None,
        backend: str,
        load: LoadAt | None = None,
    ) -> ElasticBody:
        """The body placed by ``tf`` at ``t``: own loads, gravity and the external ``load``.

        Factored again only when ``tf`` turns it; a translation shares the factorisation.
        ``load`` (``t -> (force, moment)``, the moment about :attr:`centre` placed by
        ``tf``) is spread by nodal volume (:func:`fem.loads.resultant_load`).
        """
        key = np.round(tf[:3, :3], 12).tobytes()
        x = self.points(tf)
        if self._body is None or key != self._key:
            mesh = fem.Mesh(x, self.mesh.cells, self.mesh.regions)
            loads = self.loads.reshape(-1, 3) @ tf[:3, :3].T
            if gravity is not None and not self.fixed:
                loads = loads + fem.gravity_load(mesh, self.material, gravity).reshape(-1, 3)
            prescribed = np.arange(3 * len(x)) if self.fixed else None
            n = 3 * len(x)
            finite = self.finite and not self.fixed
            self._body = ElasticBody(
                self.name,
                mesh,
                self.material,
                prescribed=prescribed,
                loads=loads.ravel(),
                contact_faces=self.faces,
                backend=backend,
                nodal_pressure=self.nodal_pressure,
                stiffness=sp.csr_matrix((n, n)) if finite else None,
            )
            self._body.finite = finite
            self._key = key
            return self._loaded(self._body, tf, t, load)
        return self._loaded(self._body.translated(x), tf, t, load)

    def _loaded(
        self, body: ElasticBody, tf: NDArray[np.float64], t: float, load: LoadAt | None
    ) -> ElasticBody:
        """``body`` with the external load at ``t`` added, nothing refactored."""
        if load is None:
            return body
        force, moment = load(t)
        centre = tf[:3, :3] @ self.centre + tf[:3, 3]
        weights = fem.loads.nodal_volumes(body.mesh)
        f = fem.loads.resultant_load(body.mesh.points, weights, force, moment, centre)
        return body.with_loads(body.loads + f.ravel())


def from_ball(ball: Ball, follow: Follow | None) -> SceneObject:
    """The scene's ball as an object named ``"ball"``.

    A neo-Hookean hollow ball's pressure follows its cavity: a follower load.
    """
    finite = ball.spec.model == "neo-hookean"
    follows = finite and ball.spec.pressure != 0.0
    return SceneObject(
        "ball",
        ball.mesh,
        ball.material,
        ball.outer,
        np.zeros_like(ball.loads) if follows else ball.loads,
        ball.nodal_pressure,
        follow=follow,
        centre=np.asarray(ball.spec.center, dtype=np.float64),
        finite=finite,
        follower=(ball.inner, ball.spec.pressure) if follows else None,
    )


def from_scene(spec: ObjectScene, mesh: fem.Mesh, where: str) -> SceneObject:
    """An ``[[object]]`` from its table and its mesh in its own coordinates.

    The mesh is placed by the table's ``rotation`` and ``center``; every boundary face can
    touch.
    """
    tf = spec.placement
    placed = fem.Mesh(mesh.points @ tf[:3, :3].T + tf[:3, 3], mesh.cells, mesh.regions)
    material = spec.elastic
    nodal = nodal_pressure(
        "tetra" in placed.cells, material.nu, spec.nodal_pressure, f"{where}.material"
    )
    return SceneObject(
        spec.name,
        placed,
        material,
        placed.boundary,
        np.zeros(3 * len(placed.points)),
        nodal,
        follow=spec.follow,
        fixed=spec.fixed,
        centre=placed.points.mean(axis=0),
        finite=spec.material.finite,
    )


def object_pairs(
    a: ElasticBody, b: ElasticBody, mu: float, gaps: str = "nodal"
) -> list[ContactPair]:
    """The pairs of two bodies: one weighted (mortar) pair, or node rows both ways.

    Mortar rows pass the contact patch test (a uniform pressure across two blocks stays
    uniform), which node-to-surface rows both ways do not. They are taken where the pair
    is frictionless, and with friction too where ``gaps`` is ``"weighted"``
    (:class:`~contact.solver.settings.ContactSettings`). The slave is the finer surface
    (the smaller median tributary area of a contact node).
    """
    if mu > 0 and gaps != "weighted":
        return [ContactPair(a, b, friction=mu), ContactPair(b, a, friction=mu)]

    def fineness(body: ElasticBody) -> float:
        return float(np.median(body.node_areas[body.contact_nodes]))

    slave, master = (a, b) if fineness(a) <= fineness(b) else (b, a)
    return [ContactPair(slave, master, mortar=True, friction=mu)]


def body_pairs(
    objects: Sequence[ElasticBody],
    hand: ElasticBody | None,
    friction: Callable[[str, str], float],
    gaps: str = "nodal",
) -> list[ContactPair]:
    """Each object against the later ones, then the hand against each object.

    ``friction(a, b)`` is a pair's coefficient (``"hand"`` for the hand). Objects, and the
    hand against each object, meet as :func:`object_pairs` says.
    """
    out = []
    for i, a in enumerate(objects):
        for b in objects[i + 1 :]:
            out += object_pairs(a, b, friction(b.name, a.name), gaps)
    for o in objects if hand is not None else ():
        mu = friction("hand", o.name)
        if gaps == "weighted":
            out += object_pairs(o, hand, mu, gaps)
        else:
            out += [ContactPair(o, hand, friction=mu), ContactPair(hand, o, friction=mu)]
    return out


def plane_pairs(
    bodies: Sequence[ElasticBody],
    planes: Sequence[Plane],
    friction: Callable[[str, str], float],
    gaps: str = "nodal",
) -> list[ContactPair]:
    """Each body against each plane: weighted rows where ``gaps`` asks.

    ``friction(plane, body)`` is the pair's coefficient; ``gaps`` as
    :class:`~contact.solver.settings.ContactSettings` has it.
    """
    out = []
    for b in bodies:
        for p in planes:
            mu = friction(p.name, b.name)
            out.append(ContactPair(b, p, mortar=gaps == "weighted", friction=mu))
    return out
