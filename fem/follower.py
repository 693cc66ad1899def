"""A pressure that follows the surface it acts on: its nodal forces and their stiffness.

At finite strain a gas or fluid pressure acts on the deformed surface, along its deformed
normal and over its deformed area (a follower load)::

    f_a = -p int N_a (x_xi x x_eta) dxi deta

with ``x = X + u`` on each face (nodes counter-clockwise seen from the side the pressure
acts from, as in :func:`fem.pressure_load`). The forces depend on ``u``; their derivative
``K_p = -d f / d u`` joins the tangent stiffness::

    K_p[a, b] = p int N_a (N_b,xi [-x_eta]x + N_b,eta [x_xi]x) dxi deta

(``[c]x v = c x v``). Face by face it is not symmetric; over a closed surface under one
pressure it is (the load is then conservative: ``p`` times the enclosed volume's change)
and it is returned symmetrised only where the caller says the surface is closed.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from .dofs import element_dofs
from .elements import face_quadrature
from .errors import LoadError
from .loads import faces_of
from .mesh import BoundaryFaces, Mesh

__all__ = ["follower_pressure"]


def _cross_matrix(c: NDArray[np.float64]) -> NDArray[np.float64]:
    """``[c]x`` with ``[c]x v = c x v``, shape ``(..., 3, 3)``."""
    out = np.zeros((*c.shape[:-1], 3, 3))
    out[..., 0, 1], out[..., 0, 2] = -c[..., 2], c[..., 1]
    out[..., 1, 0], out[..., 1, 2] = c[..., 2], -c[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -c[..., 1], c[..., 0]
    return out


def follower_pressure(
    mesh: Mesh,
    faces: BoundaryFaces | Mapping[str, ArrayLike],
    pressure: float,
    u: ArrayLike,
    *,
    closed: bool = False,
) -> tuple[NDArray[np.float64], sp.csr_matrix]:
    """Nodal forces of a pressure on the deformed faces, and their stiffness ``-df/du``.

    Parameters
    ----------
    mesh : Mesh
    faces : BoundaryFaces or mapping
        ``"triangle"`` ``(F, 3)`` and/or ``"quad"`` ``(F, 4)`` node indices.
    pressure : float
        Pascals, pushing against each face's right-hand normal.
    u : array_like, shape (3N,) or (N, 3)
        Displacements (m).
    closed : bool
        The faces close a volume: the stiffness is symmetrised (exact there).

    Returns
    -------
    force : ndarray, shape (3N,)
    stiffness : scipy.sparse.csr_matrix, shape (3N, 3N)
    """
    fcs = faces_of(faces)
    p = float(pressure)
    if not np.isfinite(p):
        raise LoadError(f"pressure must be finite, got {pressure!r}")
    x_all = mesh.points + np.asarray(u, dtype=np.float64).reshape(-1, 3)
    n = mesh.n_points
    force = np.zeros((n, 3))
    rows, cols, vals = [], [], []
    for kind, conn in fcs.items():
        if not conn.size:
            continue
        if conn.min() < 0 or conn.max() >= n:
            raise LoadError(f"{kind} faces refer to nodes outside 0..{n - 1}")
        nq, dn, w = face_quadrature(conn.shape[1])
        x = x_all[conn]  # (F, k, 3)
        t1 = np.einsum("fki,qk->fqi", x, dn[:, :, 0])
        t2 = np.einsum("fki,qk->fqi", x, dn[:, :, 1])
        fa = -p * np.einsum("fqi,q,qa->fai", np.cross(t1, t2), w, nq)
        np.add.at(force, conn, fa)
        k = conn.shape[1]
        blk = np.einsum("q,qa,qb,fqij->fabij", w, nq, dn[:, :, 0], _cross_matrix(-t2))
        blk += np.einsum("q,qa,qb,fqij->fabij", w, nq, dn[:, :, 1], _cross_matrix(t1))
        ke = (p * blk).transpose(0, 1, 3, 2, 4).reshape(len(conn), 3 * k, 3 * k)
        dofs = element_dofs(conn)
        rows.append(np.repeat(dofs, 3 * k, axis=1).ravel())
        cols.append(np.tile(dofs, 3 * k).ravel())
        vals.append(ke.ravel())
    size = mesh.n_dofs
    if not rows:
        return force.ravel(), sp.csr_matrix((size, size))
    stiff = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(size, size)
    )
    if closed:
        stiff = ((stiff + stiff.T) / 2).tocsr()
    stiff.sum_duplicates()
    return force.ravel(), stiff
