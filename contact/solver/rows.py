"""Contact rows (step 4, dispatch): each contact's linearised gap row ``E_b``.

One row per contact: its part in each body is a sparse row ``E_b`` (the slave's ``+n``,
the master facet's ``-w_k n``), so that the gap change is ``sum_b E_b u_b`` and a contact
force ``lambda`` (positive pushes the bodies apart) acts on body ``b`` as
``E_b^T lambda``: each reaction, reversed, is dispatched onto the master facet's nodes
with the barycentric weights, and action equals reaction by construction. Node-to-surface
rows come from measured gaps (:mod:`contact.solver.pairs`); mortar rows
(:mod:`contact.solver.mortar`) from the reference geometry, once per frame.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from ..geometry.plane import Plane
from .body import ElasticBody
from .kept import Kept, digest
from .mortar import mortar_coupling
from .pairs import ContactPair, Penetrations
from .planemortar import plane_rows

__all__ = ["ContactRows", "MortarCandidates", "mortar_candidates", "pad_columns"]


def pad_columns(a: NDArray, width: int, fill: float) -> NDArray:
    """``a`` (m, k) padded on the right to ``width`` columns with ``fill``."""
    if a.shape[1] == width:
        return a
    out = np.full((a.shape[0], width), fill, dtype=a.dtype)
    out[:, : a.shape[1]] = a
    return out


def _stack(a: NDArray, b: NDArray, fill: float) -> NDArray:
    """Rows of ``a`` then ``b``, padded to the wider of the two."""
    w = max(a.shape[1], b.shape[1])
    return np.concatenate([pad_columns(a, w, fill), pad_columns(b, w, fill)])


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

    def slave_points(
        self, pairs: Sequence[ContactPair], u: Mapping[str, NDArray] | None = None
    ) -> NDArray[np.float64]:
        """Each row's slave point ``sum_j a_j x_j``, ``(m, 3)``.

        A node row's node, a weighted row's weighted mean of its nodes; at rest, or
        displaced by ``u`` (each body's ``(N, 3)``).
        """
        return self._points(pairs, u, slave=True)

    def master_points(
        self, pairs: Sequence[ContactPair], u: Mapping[str, NDArray] | None = None
    ) -> NDArray[np.float64]:
        """Each row's master point ``sum_k b_k x_k``, ``(m, 3)``, its pair's master a body.

        A node row's closest point, a weighted row's weighted mean of the master's nodes
        under it; at rest, or displaced by ``u``.
        """
        return self._points(pairs, u, slave=False)

    def _points(
        self, pairs: Sequence[ContactPair], u: Mapping[str, NDArray] | None, slave: bool
    ) -> NDArray[np.float64]:
        out = np.zeros((len(self), 3))
        nodes_all, coef_all = (self.s_nodes, self.s_coef) if slave else (self.m_nodes, self.m_coef)
        for i in np.unique(self.pair):
            sel = self.pair == i
            body = pairs[int(i)].slave if slave else pairs[int(i)].master
            x = body.mesh.points  # type: ignore[union-attr]
            if u is not None:
                x = x + np.asarray(u[body.name]).reshape(-1, 3)
            nodes, used = nodes_all[sel], nodes_all[sel] >= 0
            coef = np.where(used, coef_all[sel], 0.0)
            out[sel] = np.einsum("rk,rkd->rd", coef, x[np.where(used, nodes, 0)])
        return out

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


#: The last couplings between bodies: a run's frames whose planes move and whose bodies
#: stay (a ball on a block under a plate) integrate them once.
KEEP = 8
_KEPT: Kept[MortarCandidates] = Kept(KEEP)


def mortar_candidates(pair: ContactPair, index: int, search: float) -> MortarCandidates:
    """The mortar rows of a pair, one per covered slave node.

    Against a body :mod:`contact.solver.mortar`'s, integrated once for the same two
    surfaces (the last :data:`KEEP` are kept, read-only); against a plane
    :mod:`contact.solver.planemortar`'s, on the slave's smoothed surface, the plane where
    the frame places it.
    """
    slave, master = pair.slave, pair.master
    if isinstance(master, Plane):
        return _plane_candidates(slave, master, index)
    key = digest(slave.mesh.points, slave.contact_faces.faces, master.mesh.points,
                 master.contact_faces.faces, np.float64(search))  # fmt: skip
    kept = _KEPT.get(key, lambda: _body_candidates(slave, master, search))
    rows = replace(kept.rows, pair=np.full(len(kept.rows), index, np.int64))
    return replace(kept, rows=rows)


def _body_candidates(slave: ElasticBody, master: ElasticBody, search: float) -> MortarCandidates:
    """The mortar rows of ``slave``'s contact faces against ``master``'s (pair index 0)."""
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
        np.zeros(k, np.int64),
        c.slave_nodes.copy(),
        c.normals.copy(),
        c.mean_gap0.copy(),
        s_nodes,
        s_coef,
        m_nodes,
        m_coef,
    )
    area = c.area.copy()
    for a in (rows.node, rows.normal, rows.g0, s_nodes, s_coef, m_nodes, m_coef, area):
        a.setflags(write=False)  # kept for later frames: shared, never changed
    e_s, e_m = c.rows(slave.mesh.n_points, master.mesh.n_points)
    return MortarCandidates(rows, e_s.tocsr(), e_m.tocsr(), area)


def _plane_candidates(slave: ElasticBody, plane: Plane, index: int) -> MortarCandidates:
    """The weighted rows of ``slave``'s contact faces against ``plane``."""
    c = plane_rows(slave.mesh.points, slave.contact_faces.faces, plane)
    k = len(c)
    s_nodes, s_coef = _padded(c.d, 1.0 / c.area)
    rows = ContactRows(
        np.full(k, index, np.int64),
        c.nodes.copy(),
        np.broadcast_to(plane.normal, (k, 3)).copy(),
        c.gap0.copy(),
        s_nodes,
        s_coef,
        np.full((k, 0), -1, np.int64),
        np.zeros((k, 0)),
    )
    scaled = sp.diags(1.0 / c.area) @ c.d if k else c.d
    e_s = sp.kron(scaled, plane.normal[None, :], format="csr")
    return MortarCandidates(rows, e_s, sp.csr_matrix((k, 0)), c.area.copy())
