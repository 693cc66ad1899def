"""Contact pairs and their penetrations (step 2, repel).

A contact is a *slave node* of one body against a *master*: a rigid plane, or the
contact surface of another body (a facet, and the barycentric weights of the slave node's
closest point on it). Frictionless and small-strain, the gap of a contact along the
master's normal ``n`` is linear in the displacements::

    g = g0 + n . (u_slave - sum_k w_k u_master_k)      (body master)
    g = g0 + n . u_slave                               (plane master; its motion is in g0)

with ``g0`` the gap of the reference (posed, undeformed) positions measured along that
same normal and weights; each contact's row is :class:`contact.solver.rows.ContactRows`.

Finding contacts (step 2 of Gourret, Magnenat-Thalmann and Thalmann 1989, "repel") uses
the deformed positions: a slave node behind a plane or inside the master's closed surface
is penetrating; its row is taken from its closest point on the deformed master.
:func:`measure` searches only the nodes that can be near (a :class:`Survey` of the last
measurement bounds how far the others still are) and only the master's triangles near
them: the iteration measures every pair at every update, and a deformed surface's search
tree is built anew each time. Rows are kept while the node stays in contact (contact
memory), so the compliance of a row is computed once.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

import fem

from ..geometry.plane import Plane
from ..geometry.surfacequery import (
    DEGENERATE_TOL,
    SurfaceError,
    TriangleSurface,
    degenerate_triangles,
)
from .body import ElasticBody

__all__ = ["ContactPair", "Penetrations", "Survey", "displaced_surface", "measure"]


@dataclass(frozen=True)
class ContactPair:
    """The slave nodes of one body against a master (a plane or another body's surface).

    Parameters
    ----------
    slave : ElasticBody
        The body whose surface nodes must stay outside the master.
    master : ElasticBody or Plane
        The obstacle.
    mortar : bool
        Weighted (mortar) rows instead of node-to-surface rows: against a body
        (:mod:`contact.solver.mortar`) or a plane (:mod:`contact.solver.planemortar`).
        Friction acts on their weighted slip: the row's weighted slave point against the
        master's point under it.
    friction : float
        Coulomb's coefficient ``mu >= 0`` of the pair (0: frictionless).
    """

    slave: ElasticBody
    master: ElasticBody | Plane
    mortar: bool = False
    friction: float = 0.0

    def __post_init__(self) -> None:
        mu = self.friction
        if isinstance(mu, bool) or not isinstance(mu, (int, float)) or not 0.0 <= mu < np.inf:
            raise ValueError(f"{self.name}: friction = {mu!r} must be a finite number >= 0")

    @property
    def name(self) -> str:
        """``"slave/master"``, for messages."""
        return f"{self.slave.name}/{self.master.name}"

    @property
    def rigid(self) -> bool:
        """True when the master is a plane."""
        return isinstance(self.master, Plane)

    @property
    def loose(self) -> bool:
        """True when a side is placed by the contacts: a free body or a force-driven plane.

        Such a side can slide through what it nearly touches in the frame's first solve.
        """
        m = self.master
        return self.slave.free or (m.force is not None if isinstance(m, Plane) else m.free)

    @property
    def wide_start(self) -> bool:
        """True when the frame's first contact set takes every node inside or near.

        Where a side is :attr:`loose`, or where the pair has friction (each contact-set
        update is a frictional solve, dearer than the rows it saves). Otherwise the first
        set is the nodes deeper than half the deepest overlap: about Hertz's patch.
        """
        return self.loose or self.friction > 0

    @property
    def touched(self) -> NDArray[np.bool_]:
        """Which displacement components ``(3,)`` of a slave node its rows can touch.

        A frictionless pair against a plane has one row per node along the plane's
        normal: the normal's nonzero components (one, for a plane across an axis). Any
        other pair: all three (tangential rows, or a master's normals that vary).
        """
        if self.rigid and not self.friction:
            return self.master.normal != 0.0  # type: ignore[union-attr]
        return np.ones(3, dtype=bool)

    @cached_property
    def candidates(self) -> NDArray[np.int64]:
        """Slave nodes that can touch.

        Its contact surface, less the nodes held fixed when the master is rigid (a row
        with no compliance on either side).
        """
        nodes = self.slave.contact_nodes
        if self.rigid and self.slave.prescribed_nodes.size:
            nodes = np.setdiff1d(nodes, self.slave.prescribed_nodes)
        return nodes


@dataclass
class Penetrations:
    """Gaps of a pair's candidate nodes at the current positions.

    Attributes
    ----------
    nodes : ndarray of int, shape (k,)
        Slave nodes examined (near the master).
    gap : ndarray, shape (k,)
        Signed distance to the master (m), negative inside.
    facet : ndarray of int, shape (k, 3)
        Master nodes of the closest facet (-1 for a plane).
    weights : ndarray, shape (k, 3)
        Barycentric weights of the closest point (0 for a plane).
    normal : ndarray, shape (k, 3)
        Master's outward normal there.
    """

    nodes: NDArray[np.int64]
    gap: NDArray[np.float64]
    facet: NDArray[np.int64]
    weights: NDArray[np.float64]
    normal: NDArray[np.float64]

    @classmethod
    def empty(cls) -> Penetrations:
        """No node near the master."""
        return cls(
            np.zeros(0, np.int64),
            np.zeros(0),
            np.zeros((0, 3), np.int64),
            np.zeros((0, 3)),
            np.zeros((0, 3)),
        )

    def select(self, mask: NDArray[np.bool_]) -> Penetrations:
        """The entries where ``mask`` holds."""
        return Penetrations(
            self.nodes[mask],
            self.gap[mask],
            self.facet[mask],
            self.weights[mask],
            self.normal[mask],
        )

    def joined(self, other: Penetrations) -> Penetrations:
        """These entries, then ``other``'s."""
        return Penetrations(
            np.concatenate([self.nodes, other.nodes]),
            np.concatenate([self.gap, other.gap]),
            np.concatenate([self.facet, other.facet]),
            np.concatenate([self.weights, other.weights]),
            np.concatenate([self.normal, other.normal]),
        )


@dataclass(frozen=True)
class Survey:
    """What one measurement of a pair tells of the next: who cannot be near yet.

    The distance from a point to a surface moves by at most the point's own
    displacement plus the largest displacement of the surface's nodes (barycentric
    interpolation moves no surface point further than its nodes), and a point that stays
    off the surface all the way cannot change sides. So a candidate that was outside at
    distance ``d`` is still outside, further than ``d`` less those two displacements:
    where that bound exceeds the margin, it is not queried again.

    Attributes
    ----------
    u_slave : ndarray, shape (c, 3)
        The candidates' displacements at the measurement.
    u_master : ndarray, shape (s, 3)
        The master's contact nodes' displacements then.
    clear : ndarray, shape (c,)
        A lower bound of each candidate's distance to the master then, each known
        outside where it is positive (0: inside, or not known).
    """

    u_slave: NDArray[np.float64]
    u_master: NDArray[np.float64]
    clear: NDArray[np.float64]


def measure(
    pair: ContactPair,
    u: Mapping[str, NDArray[np.float64]],
    margin: float,
    survey: Survey | None = None,
) -> tuple[Penetrations, Survey | None]:
    """Gaps of a pair's candidates at the displaced positions ``x + u``.

    Only slave nodes within ``margin`` of the master's bounding box are examined. Against
    a closed master surface, the nodes a ``survey`` of an earlier measurement shows to be
    further than ``margin`` are skipped: the result is that of a search of every node.
    The others are searched on the master's whole surface (its bounding-volume
    hierarchy, refitted at the new coordinates: :mod:`contact.geometry.closestkernels`).
    ``u`` holds each body's displacements by name and, under its own name, a force-driven
    plane's translation ``(1, 3)`` from its ``motion``.

    Returns
    -------
    Penetrations
        The nodes within ``margin`` (or inside).
    Survey or None
        For the next measurement of the pair (None for a plane or an open master).
    """
    slave = pair.slave
    nodes = pair.candidates
    xs = slave.mesh.points[nodes] + u[slave.name][nodes]
    if pair.rigid:
        plane: Plane = pair.master  # type: ignore[assignment]
        gap = plane.signed_distance(xs)
        if plane.name in u:  # a force-driven plane moved by the solve, from its motion
            gap -= float(np.ravel(u[plane.name])[:3] @ plane.normal)
        near = gap < margin
        k = int(near.sum())
        return Penetrations(
            nodes[near],
            gap[near],
            np.full((k, 3), -1, np.int64),
            np.zeros((k, 3)),
            np.broadcast_to(plane.normal, (k, 3)).copy(),
        ), None
    master: ElasticBody = pair.master  # type: ignore[assignment]
    xm = master.mesh.points + u[master.name]
    used = master.contact_nodes
    lo, hi = fem.bounding_box(xm[used])
    closed = master.contact_closed
    # distance to the master's bounding box: a lower bound of that to the surface, and
    # a node off the box is outside a closed surface
    clear = np.linalg.norm(np.maximum(np.maximum(lo - xs, xs - hi), 0.0), axis=1)
    if survey is not None and closed:
        drift = float(np.linalg.norm(u[master.name][used] - survey.u_master, axis=1).max())
        moved = np.linalg.norm(u[slave.name][nodes] - survey.u_slave, axis=1) + drift
        clear = np.maximum(clear, survey.clear - moved)
    ask = clear <= margin
    if not ask.any():
        return Penetrations.empty(), _survey(u, nodes, used, pair, clear) if closed else None
    q_nodes, q = nodes[ask], xs[ask]
    surface, tri = displaced_surface(master, xm)
    c = surface.closest(q)
    # inside: the side of the closest point's pseudo-normal (Baerentzen and Aanaes: exact
    # on a closed surface that does not overlap itself; on an open one, a pad's top, the
    # side it faces)
    inside = c.side(q) < 0
    gap = np.where(inside, -c.distance, c.distance)
    near = gap < margin
    p = Penetrations(q_nodes[near], gap[near], tri[c.face[near]], c.bary[near], c.normal[near])
    if not closed:
        return p, None
    clear[ask] = np.where(inside, 0.0, c.distance)
    return p, _survey(u, nodes, used, pair, clear)


def displaced_surface(
    body: ElasticBody, x: NDArray[np.float64]
) -> tuple[TriangleSurface, NDArray[np.int64]]:
    """A body's contact surface at points ``x`` ``(N, 3)``, and its triangles.

    An iterate may crush a few facets far from the contact to zero area (a ball pinned on
    planes before it has moved, a soft block pressed flat): they hold no area and no
    solid angle, so the queries go on without them.
    """
    tri = body.contact_triangles
    try:
        surface = body.contact_surface.moved(x)  # connectivity checked once
        keep = ~surface.degenerate(10 * DEGENERATE_TOL)
    except SurfaceError:  # a facet crushed below the surface's own tolerance
        keep = ~degenerate_triangles(x, tri, 10 * DEGENERATE_TOL)[2]
    if not keep.all():
        tri = tri[keep]
        surface = TriangleSurface(x, tri, name=f"{body.name} contact surface")
    return surface, tri


def _survey(
    u: Mapping[str, NDArray[np.float64]],
    nodes: NDArray[np.int64],
    used: NDArray[np.int64],
    pair: ContactPair,
    clear: NDArray[np.float64],
) -> Survey:
    return Survey(np.array(u[pair.slave.name][nodes]), np.array(u[pair.master.name][used]), clear)
