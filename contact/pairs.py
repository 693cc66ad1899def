"""Contact pairs and their linearised constraint rows.

A contact is a *slave node* of one body against a *master*: a rigid plane, or the
contact surface of another body (a facet, and the barycentric weights of the slave node's
closest point on it). Frictionless and small-strain, the gap of a contact along the
master's normal ``n`` is linear in the displacements::

    g = g0 + n . (u_slave - sum_k w_k u_master_k)      (body master)
    g = g0 + n . u_slave                               (plane master; its motion is in g0)

with ``g0`` the gap of the reference (posed, undeformed) positions measured along that
same normal and weights. One such row per contact: its part in each body is a sparse row
``E_b`` (the slave's ``+n``, the master facet's ``-w_k n``), so that the gap change is
``sum_b E_b u_b`` and a contact force ``lambda`` (positive pushes the bodies apart) acts
on body ``b`` as ``E_b^T lambda``: action equals reaction by construction.

Finding contacts (step 2 of seed 000, "repel") uses the deformed positions: a slave node
behind a plane or inside the master's closed surface is penetrating; its row is taken
from its closest point on the deformed master. Rows are kept while the node stays in
contact (contact memory), so the compliance of a row is computed once.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

import fem

from .body import ElasticBody
from .geometry import Plane

__all__ = ["ContactPair", "ContactRows", "Penetrations", "measure"]


@dataclass(frozen=True)
class ContactPair:
    """The slave nodes of one body against a master (a plane or another body's surface).

    Parameters
    ----------
    slave : ElasticBody
        The body whose surface nodes must stay outside the master.
    master : ElasticBody or Plane
        The obstacle.
    """

    slave: ElasticBody
    master: ElasticBody | Plane

    @property
    def name(self) -> str:
        """``"slave/master"``, for messages."""
        return f"{self.slave.name}/{self.master.name}"

    @property
    def rigid(self) -> bool:
        """True when the master is a plane."""
        return isinstance(self.master, Plane)

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


def measure(pair: ContactPair, u: dict[str, NDArray[np.float64]], margin: float) -> Penetrations:
    """Gaps of a pair's candidates at the displaced positions ``x + u``.

    Only slave nodes within ``margin`` of the master's bounding box are examined.
    """
    slave = pair.slave
    nodes = pair.candidates
    xs = slave.mesh.points[nodes] + u[slave.name][nodes]
    if pair.rigid:
        plane: Plane = pair.master  # type: ignore[assignment]
        gap = plane.signed_distance(xs)
        near = gap < margin
        k = int(near.sum())
        return Penetrations(
            nodes[near],
            gap[near],
            np.full((k, 3), -1, np.int64),
            np.zeros((k, 3)),
            np.broadcast_to(plane.normal, (k, 3)).copy(),
        )
    from .surfacequery import DEGENERATE_TOL, WINDING_THRESHOLD, TriangleSurface

    master: ElasticBody = pair.master  # type: ignore[assignment]
    tri = master.contact_triangles
    xm = master.mesh.points + u[master.name]
    used = master.contact_nodes
    lo, hi = xm[used].min(axis=0) - margin, xm[used].max(axis=0) + margin
    box = np.all((xs >= lo) & (xs <= hi), axis=1)
    if not box.any():
        return Penetrations.empty()
    nodes, xs = nodes[box], xs[box]
    # an iterate may crush a few facets far from this contact to zero area (a ball pinned
    # on planes before it has moved): they hold no area and no solid angle, so the
    # queries go on without them
    x = xm[tri]
    dbl = np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), axis=1)
    edge2 = np.max([((x[:, i] - x[:, (i + 1) % 3]) ** 2).sum(axis=1) for i in range(3)], axis=0)
    keep = dbl > 10 * DEGENERATE_TOL * edge2
    tri = tri if keep.all() else tri[keep]
    surface = TriangleSurface(xm, tri, name=f"{master.name} contact surface")
    c = surface.closest(xs)
    # a closed contact surface (a ball, a skin: checked at rest) tells inside by its
    # winding number, robust in concave places; an open one (a pad's top) by the side of
    # the pseudo-normal
    if master.contact_closed:
        inside = surface.winding_number(xs) > WINDING_THRESHOLD
    else:
        inside = c.side(xs) < 0
    gap = np.where(inside, -c.distance, c.distance)
    near = gap < margin
    return Penetrations(
        nodes[near],
        gap[near],
        tri[c.face[near]],
        c.bary[near],
        c.normal[near],
    )


@dataclass
class ContactRows:
    """The active contacts: one linearised gap row each, kept while the contact holds.

    Attributes
    ----------
    pair : ndarray of int, shape (m,)
        Index of each row's pair.
    node : ndarray of int, shape (m,)
        Its slave node.
    facet, weights, normal : ndarray, shape (m, 3)
        Its master facet nodes (-1 for a plane), weights and normal.
    g0 : ndarray, shape (m,)
        Gap of the reference positions along the row (m); the plane's motion included.
    """

    pair: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))
    node: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))
    facet: NDArray[np.int64] = field(default_factory=lambda: np.zeros((0, 3), np.int64))
    weights: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))
    normal: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))
    g0: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))

    def __len__(self) -> int:
        return int(self.pair.size)

    @property
    def keys(self) -> NDArray[np.int64]:
        """``(m, 2)`` pair and slave node of every row: a contact's identity."""
        return np.column_stack([self.pair, self.node])

    def select(self, mask: NDArray[np.bool_]) -> ContactRows:
        """The rows where ``mask`` holds."""
        return ContactRows(
            self.pair[mask],
            self.node[mask],
            self.facet[mask],
            self.weights[mask],
            self.normal[mask],
            self.g0[mask],
        )

    def extended(self, pairs: Sequence[ContactPair], index: int, p: Penetrations) -> ContactRows:
        """These rows and new ones for pair ``index`` from measured penetrations."""
        pair = pairs[index]
        x = pair.slave.mesh.points[p.nodes]
        if pair.rigid:
            plane: Plane = pair.master  # type: ignore[assignment]
            g0 = plane.signed_distance(x)
        else:
            xm = pair.master.mesh.points  # type: ignore[union-attr]
            target = np.einsum("mk,mkj->mj", p.weights, xm[p.facet])
            g0 = np.einsum("mj,mj->m", x - target, p.normal)
        return ContactRows(
            np.concatenate([self.pair, np.full(p.nodes.size, index, np.int64)]),
            np.concatenate([self.node, p.nodes]),
            np.concatenate([self.facet, p.facet]),
            np.concatenate([self.weights, p.weights]),
            np.concatenate([self.normal, p.normal]),
            np.concatenate([self.g0, g0]),
        )

    def matrices(
        self, pairs: Sequence[ContactPair], bodies: Sequence[ElasticBody]
    ) -> dict[str, sp.csr_matrix]:
        """Each body's part ``E_b`` (m x n_dofs_b) of the rows; bodies in no row omitted."""
        m = len(self)
        slave_of = np.array([bodies.index(p.slave) for p in pairs], dtype=np.int64)
        master_of = np.array(
            [-1 if p.rigid else bodies.index(p.master) for p in pairs],  # type: ignore[arg-type]
            dtype=np.int64,
        )
        s_body = slave_of[self.pair] if m else np.zeros(0, np.int64)
        m_body = master_of[self.pair] if m else np.zeros(0, np.int64)
        out: dict[str, sp.csr_matrix] = {}
        rows3 = np.repeat(np.arange(m), 3)
        for b, body in enumerate(bodies):
            n = body.mesh.n_dofs
            r, c, v = [], [], []
            sel = np.flatnonzero(s_body == b)
            if sel.size:
                r.append(rows3.reshape(m, 3)[sel].ravel())
                c.append(fem.node_dofs(self.node[sel]))
                v.append(self.normal[sel].ravel())
            sel = np.flatnonzero(m_body == b)
            if sel.size:
                for k in range(3):
                    r.append(rows3.reshape(m, 3)[sel].ravel())
                    c.append(fem.node_dofs(self.facet[sel, k]))
                    v.append((-self.weights[sel, k][:, None] * self.normal[sel]).ravel())
            if r:
                e = sp.csr_matrix(
                    (np.concatenate(v), (np.concatenate(r), np.concatenate(c))), shape=(m, n)
                )
                e.sum_duplicates()
                out[body.name] = e
        return out
