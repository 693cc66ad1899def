"""What a frame reports of its contacts: nodal contact fields, friction's state, held or not."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from .body import ElasticBody
from .pairs import ContactPair
from .results import FrictionReport
from .rows import ContactRows

__all__ = ["FrictionState", "contact_fields", "held_verdict"]


@dataclass(frozen=True)
class FrictionState:
    """The closed contacts' friction at the end of a frame.

    Attributes
    ----------
    rows : ContactRows
        The closed contacts' normal rows, then their tangential rows.
    lam : ndarray
        The forces of ``rows`` (N).
    tangential : ndarray, shape (k, 3)
        Each closed contact's tangential force on its slave node (N).
    status : ndarray of int, shape (k,)
        1 stick, 2 slip.
    cone_use : ndarray, shape (k,)
        ``|t| / (mu n)`` (0 where frictionless).
    slip : ndarray, shape (k,)
        Slip increment since the anchor (m).
    report : FrictionReport
    pair_mu : ndarray
        Each pair's coefficient as solved: 0 on the side of an interface met both ways
        that takes no tangential rows (:meth:`contact.solver.tangential.Friction.one_way`).
    """

    rows: ContactRows
    lam: NDArray[np.float64]
    tangential: NDArray[np.float64]
    status: NDArray[np.int64]
    cone_use: NDArray[np.float64]
    slip: NDArray[np.float64]
    report: FrictionReport
    pair_mu: NDArray[np.float64]

    def per_contact(self) -> dict[str, NDArray]:
        """The per-contact arrays of :attr:`FrameResult.contacts`."""
        return {
            "tangential": self.tangential,
            "status": self.status,
            "cone_use": self.cone_use,
            "slip": self.slip,
        }


def contact_fields(
    bodies: Sequence[ElasticBody],
    pairs: Sequence[ContactPair],
    rows: ContactRows,
    lam: NDArray[np.float64],
    e: Mapping[str, sp.csr_matrix],
    contact_force: Mapping[str, NDArray[np.float64]],
    friction: FrictionState | None,
) -> dict[str, dict[str, NDArray]]:
    """Every body's nodal contact fields (see :attr:`FrameResult.contact_fields`).

    The normal force of a node is the size of what the normal rows put on it, its
    tangential force the rest of its contact force; status and cone use are the largest
    over the contacts of a node: a slave node's own, and a master facet's nodes' where
    the friction of an interface met both ways is solved on the other side (a
    frictionless closed contact slips).
    """
    status = np.full(len(rows), 2, np.int64)
    cone = np.zeros(len(rows))
    solved = np.array([p.friction for p in pairs], dtype=float)
    if friction is not None:
        status, cone, solved = friction.status, friction.cone_use, friction.pair_mu
    # pairs whose friction the opposite pair solves: their nodes take its status instead
    handed = np.array([p.friction > 0 and m == 0 for p, m in zip(pairs, solved)], dtype=bool)
    out = {}
    for b in bodies:
        n = b.mesh.n_points
        eb = e.get(b.name)
        fn = (eb.T @ lam).reshape(-1, 3) if eb is not None else np.zeros((n, 3))
        st = np.zeros(n, np.int64)
        cu = np.zeros(n)
        mine = np.array([p.slave is b for p in pairs], dtype=bool)
        sel = (mine & ~handed)[rows.pair] if len(rows) else np.zeros(0, bool)
        np.maximum.at(st, rows.node[sel], status[sel])
        np.maximum.at(cu, rows.node[sel], cone[sel])
        facing = np.array(
            [not p.rigid and p.master is b and m > 0 for p, m in zip(pairs, solved)], dtype=bool
        )
        rel = facing[rows.pair] if len(rows) else np.zeros(0, bool)
        if rel.any() and rows.m_nodes.shape[1]:
            nodes, w = rows.m_nodes[rel], rows.m_coef[rel]
            used = (nodes >= 0) & (w > 0)
            k = np.broadcast_to(np.arange(rel.sum())[:, None], nodes.shape)[used]
            np.maximum.at(st, nodes[used], status[rel][k])
            np.maximum.at(cu, nodes[used], cone[rel][k])
        out[b.name] = {
            "normal_force": np.linalg.norm(fn, axis=1),
            "tangential_force": np.asarray(contact_force[b.name]) - fn,
            "contact_status": st,
            "cone_use": cu,
        }
    return out


def held_verdict(bodies: Sequence[ElasticBody], converged: bool, stop: str) -> bool | None:
    """Whether every free body is held: None with no free body or where the frame says nothing.

    False where the frame stopped as not held; True where it converged (a bone over its
    limit does not stop a frame).
    """
    if not any(b.solver.free_body for b in bodies):
        return None
    if stop.startswith("not held"):
        return False
    return True if converged else None
