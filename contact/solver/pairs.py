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
from its closest point on the deformed master. :func:`measure` searches only the nodes
that can be near (a :class:`Survey` of the last measurement bounds how far the others
still are) and only the master's triangles near them: the iteration measures every pair
at every update, and a deformed surface's search tree is built anew each time. Rows are
kept while the node stays in contact (contact memory), so the compliance of a row is
computed once.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import scipy.sparse as sp
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

__all__ = [
    "ContactPair",
    "ContactRows",
    "MortarCandidates",
    "Penetrations",
    "Survey",
    "measure",
    "mortar_candidates",
]


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
    mortar: bool = False

    def __post_init__(self) -> None:
        if self.mortar and isinstance(self.master, Plane):
            raise ValueError(f"{self.name}: mortar rows need a deformable master, not a plane")

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
    u: dict[str, NDArray[np.float64]],
    margin: float,
    survey: Survey | None = None,
) -> tuple[Penetrations, Survey | None]:
    """Gaps of a pair's candidates at the displaced positions ``x + u``.

    Only slave nodes within ``margin`` of the master's bounding box are examined. Against
    a closed master surface, the nodes a ``survey`` of an earlier measurement shows to be
    further than ``margin`` are skipped: the result is that of a search of every node.
    The others are searched on the master's whole surface (its bounding-volume
    hierarchy, refitted at the new coordinates: :mod:`contact.geometry.closestkernels`).

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
    tri = master.contact_triangles
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
    # an iterate may crush a few facets far from this contact to zero area (a ball pinned
    # on planes before it has moved): they hold no area and no solid angle, so the
    # queries go on without them
    try:
        surface = master.contact_surface.moved(xm)  # connectivity checked once
        keep = ~surface.degenerate(10 * DEGENERATE_TOL)
    except SurfaceError:  # a facet crushed below the surface's own tolerance
        keep = ~degenerate_triangles(xm, tri, 10 * DEGENERATE_TOL)[2]
    if not keep.all():
        tri = tri[keep]
        surface = TriangleSurface(xm, tri, name=f"{master.name} contact surface")
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


def _survey(
    u: dict[str, NDArray[np.float64]],
    nodes: NDArray[np.int64],
    used: NDArray[np.int64],
    pair: ContactPair,
    clear: NDArray[np.float64],
) -> Survey:
    return Survey(np.array(u[pair.slave.name][nodes]), np.array(u[pair.master.name][used]), clear)


def _pad(a: NDArray, width: int, fill: float) -> NDArray:
    """``a`` (m, k) padded on the right to ``width`` columns with ``fill``."""
    if a.shape[1] == width:
        return a
    out = np.full((a.shape[0], width), fill, dtype=a.dtype)
    out[:, : a.shape[1]] = a
    return out


def _stack(a: NDArray, b: NDArray, fill: float) -> NDArray:
    """Rows of ``a`` then ``b``, padded to the wider of the two."""
    w = max(a.shape[1], b.shape[1])
    return np.concatenate([_pad(a, w, fill), _pad(b, w, fill)])


@dataclass
class ContactRows:
    """The active contacts: one linearised gap row each, kept while the contact holds.

    A row reads ``g = g0 + n . (sum_j a_j u_slave[j] - sum_k b_k u_master[k])``: for a
    node against a facet, ``a = (1)`` on the node and ``b`` the facet's barycentric
    weights; against a plane, no ``b``; for a mortar row, ``a`` and ``b`` are the row's
    mortar integrals over its area. Coefficients are stored padded (node -1, weight 0).

    Attributes
    ----------
    pair : ndarray of int, shape (m,)
        Index of each row's pair.
    node : ndarray of int, shape (m,)
        Its slave node (the row's identity with the pair).
    normal : ndarray, shape (m, 3)
        The master's normal, pointing into the slave side.
    g0 : ndarray, shape (m,)
        Gap of the reference positions along the row (m); a plane's motion included.
    s_nodes, s_coef : ndarray, shape (m, ks)
        Slave nodes and coefficients ``a``.
    m_nodes, m_coef : ndarray, shape (m, km)
        Master nodes and coefficients ``b``.
    """

    pair: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))
    node: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))
    normal: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))
    g0: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    s_nodes: NDArray[np.int64] = field(default_factory=lambda: np.zeros((0, 1), np.int64))
    s_coef: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 1)))
    m_nodes: NDArray[np.int64] = field(default_factory=lambda: np.zeros((0, 3), np.int64))
    m_coef: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))

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
            self.normal[mask],
            self.g0[mask],
            self.s_nodes[mask],
            self.s_coef[mask],
            self.m_nodes[mask],
            self.m_coef[mask],
        )

    def joined(self, other: ContactRows) -> ContactRows:
        """These rows, then ``other``'s."""
        return ContactRows(
            np.concatenate([self.pair, other.pair]),
            np.concatenate([self.node, other.node]),
            np.concatenate([self.normal, other.normal]),
            np.concatenate([self.g0, other.g0]),
            _stack(self.s_nodes, other.s_nodes, -1),
            _stack(self.s_coef, other.s_coef, 0.0),
            _stack(self.m_nodes, other.m_nodes, -1),
            _stack(self.m_coef, other.m_coef, 0.0),
        )

    def extended(self, pairs: Sequence[ContactPair], index: int, p: Penetrations) -> ContactRows:
        """These rows and node-to-surface rows for pair ``index`` from measured gaps."""
        pair = pairs[index]
        x = pair.slave.mesh.points[p.nodes]
        k = p.nodes.size
        if pair.rigid:
            plane: Plane = pair.master  # type: ignore[assignment]
            g0 = plane.signed_distance(x)
            m_nodes, m_coef = np.full((k, 0), -1, np.int64), np.zeros((k, 0))
        else:
            xm = pair.master.mesh.points  # type: ignore[union-attr]
            target = np.einsum("mk,mkj->mj", p.weights, xm[p.facet])
            g0 = np.einsum("mj,mj->m", x - target, p.normal)
            m_nodes, m_coef = p.facet, p.weights
        new = ContactRows(
            np.full(k, index, np.int64),
            p.nodes.copy(),
            p.normal.copy(),
            g0,
            p.nodes[:, None].copy(),
            np.ones((k, 1)),
            m_nodes,
            m_coef,
        )
        return self.joined(new)

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
        for b, body in enumerate(bodies):
            n = body.mesh.n_dofs
            r, c, v = [], [], []
            for sel_body, nodes, coef, sign in (
                (s_body, self.s_nodes, self.s_coef, 1.0),
                (m_body, self.m_nodes, self.m_coef, -1.0),
            ):
                rows = np.flatnonzero(sel_body == b)
                if not rows.size or not nodes.shape[1]:
                    continue
                nd, cf = nodes[rows], coef[rows]
                used = nd >= 0
                ri = np.broadcast_to(rows[:, None], nd.shape)[used]
                ni, ci = nd[used], cf[used]
                nrm = self.normal[ri]  # (q, 3)
                r.append(np.repeat(ri, 3))
                c.append((3 * ni[:, None] + np.arange(3)).ravel())
                v.append((sign * ci[:, None] * nrm).ravel())
            if r:
                e = sp.csr_matrix(
                    (np.concatenate(v), (np.concatenate(r), np.concatenate(c))), shape=(m, n)
                )
                e.sum_duplicates()
                e.eliminate_zeros()
                out[body.name] = e
        return out


@dataclass(frozen=True)
class MortarCandidates:
    """Every mortar row a pair can have, from the reference geometry.

    Attributes
    ----------
    rows : ContactRows
        One row per slave node with an overlap (``g0`` the weighted mean gap, m).
    e_slave, e_master : scipy.sparse.csr_matrix
        The rows' parts in the slave's and the master's DOFs: the linearised gaps are
        ``rows.g0 + e_slave u_s + e_master u_m``.
    area : ndarray
        Each row's area (m^2): the nodal pressure is ``lambda / area``.
    """

    rows: ContactRows
    e_slave: sp.csr_matrix
    e_master: sp.csr_matrix
    area: NDArray[np.float64]

    def gaps(self, u_slave: NDArray[np.float64], u_master: NDArray[np.float64]) -> NDArray:
        """Linearised weighted gaps of every candidate row at the displacements (m)."""
        return self.rows.g0 + self.e_slave @ u_slave.ravel() + self.e_master @ u_master.ravel()


def _padded(a: sp.csr_matrix, scale: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    """Rows of a CSR matrix as padded (nodes, coefficients) arrays, scaled per row."""
    counts = np.diff(a.indptr)
    width = int(counts.max(initial=0))
    nodes = np.full((a.shape[0], width), -1, dtype=np.int64)
    coef = np.zeros((a.shape[0], width))
    row = np.repeat(np.arange(a.shape[0]), counts)
    col = np.arange(a.indices.size) - np.repeat(a.indptr[:-1], counts)
    nodes[row, col] = a.indices
    coef[row, col] = a.data * scale[row]
    return nodes, coef


def mortar_candidates(pair: ContactPair, index: int, search: float) -> MortarCandidates:
    """The mortar rows of a body pair (:mod:`contact.solver.mortar`), one per covered slave node."""
    from .mortar import mortar_coupling

    slave, master = pair.slave, pair.master
    assert isinstance(master, ElasticBody)
    c = mortar_coupling(
        slave.mesh.points,
        slave.contact_faces.faces,
        master.mesh.points,
        master.contact_faces.faces,
        search=search,
    )
    k = len(c)
    scale = 1.0 / c.area
    s_nodes, s_coef = _padded(c.d, scale)
    m_nodes, m_coef = _padded(c.m, scale)
    rows = ContactRows(
        np.full(k, index, np.int64),
        c.slave_nodes.copy(),
        c.normals.copy(),
        c.mean_gap0.copy(),
        s_nodes,
        s_coef,
        m_nodes,
        m_coef,
    )
    e_s, e_m = c.rows(slave.mesh.n_points, master.mesh.n_points)
    return MortarCandidates(rows, e_s.tocsr(), e_m.tocsr(), c.area.copy())
