"""Vectorised assembly of the linear elastic stiffness matrix."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from .elements import ELEMENTS, ReferenceElement
from .mapping import gradients
from .material import LinearElastic, materials_by_region
from .mesh import Mesh

__all__ = ["assemble_stiffness", "element_dofs", "element_stiffness", "lame_fields"]

#: Elements processed at once; bounds the temporaries to a few hundred MB.
CHUNK = 100_000


def element_dofs(conn: NDArray[np.int64]) -> NDArray[np.int64]:
    """Global DOFs of each element, node-major: ``(M, k) -> (M, 3k)``."""
    return (3 * conn[:, :, None] + np.arange(3)).reshape(len(conn), -1)


def element_stiffness(
    coords: NDArray[np.float64],
    element: ReferenceElement,
    lam: NDArray[np.float64],
    mu: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Element stiffness matrices of isotropic linear elasticity.

    ``K[a i, b k] = sum_q w_q det J_q (lam G_ai G_bk + mu G_ak G_bi + mu delta_ik G_al G_bl)``.

    Parameters
    ----------
    coords : ndarray, shape (M, n, 3)
        Element nodal coordinates.
    element : ReferenceElement
        Reference element of the block.
    lam, mu : ndarray, shape (M,)
        Lame parameters per element.

    Returns
    -------
    ndarray, shape (M, 3n, 3n)
        Rows and columns in the element's node-major DOF order.
    """
    grad, detj = gradients(coords, element)
    m, q, n, _ = grad.shape
    gs = grad * np.sqrt(detj * element.weights)[:, :, None, None]
    a = gs.reshape(m, q, 3 * n)
    mm = np.matmul(a.transpose(0, 2, 1), a).reshape(m, n, 3, n, 3)
    trace = np.einsum("malbl->mab", mm)
    ke = lam[:, None, None, None, None] * mm
    ke += mu[:, None, None, None, None] * mm.transpose(0, 1, 4, 3, 2)
    diag = np.arange(3)
    ke[:, :, diag, :, diag] += (mu[:, None, None] * trace)[None]
    return ke.reshape(m, 3 * n, 3 * n)


def lame_fields(
    mesh: Mesh, materials: LinearElastic | Mapping[int, LinearElastic]
) -> dict[str, tuple[NDArray[np.float64], NDArray[np.float64]]]:
    """Per-cell Lame parameters ``(lam, mu)`` for every cell block."""
    mats = materials_by_region(materials, mesh.region_ids)
    ids = np.array(sorted(mats))
    lam_t = np.array([mats[int(r)].lame[0] for r in ids])
    mu_t = np.array([mats[int(r)].lame[1] for r in ids])
    out = {}
    for kind, reg in mesh.regions.items():
        pos = np.searchsorted(ids, reg)
        out[kind] = (lam_t[pos], mu_t[pos])
    return out


def assemble_stiffness(
    mesh: Mesh, materials: LinearElastic | Mapping[int, LinearElastic]
) -> sp.csr_matrix:
    """Assemble the global stiffness matrix.

    Parameters
    ----------
    mesh : Mesh
        The mesh (any mix of tetra, hexahedron and wedge cells).
    materials : LinearElastic or mapping of int to LinearElastic
        One material for all cells, or one per region id.

    Returns
    -------
    scipy.sparse.csr_matrix, shape (3N, 3N)
        Symmetric to round-off; DOF ``3 * node + component``.

    Raises
    ------
    MaterialError
        If a region of the mesh has no material.
    """
    fields = lame_fields(mesh, materials)
    n = mesh.n_dofs
    total = sum(len(c) * (3 * c.shape[1]) ** 2 for c in mesh.cells.values())
    idx_t = np.int32 if n < 2**31 - 1 else np.int64
    rows = np.empty(total, dtype=idx_t)
    cols = np.empty(total, dtype=idx_t)
    data = np.empty(total)
    pos = 0
    for kind, conn in mesh.cells.items():
        elem = ELEMENTS[kind]
        lam, mu = fields[kind]
        nd = 3 * conn.shape[1]
        for s in range(0, len(conn), CHUNK):
            c = conn[s : s + CHUNK]
            ke = element_stiffness(mesh.points[c], elem, lam[s : s + CHUNK], mu[s : s + CHUNK])
            dofs = element_dofs(c).astype(idx_t)
            size = len(c) * nd * nd
            data[pos : pos + size] = ke.ravel()
            rows[pos : pos + size] = np.repeat(dofs, nd, axis=1).ravel()
            cols[pos : pos + size] = np.tile(dofs, (1, nd)).ravel()
            pos += size
    k = sp.csr_matrix((data, (rows, cols)), shape=(n, n))
    k.sum_duplicates()
    return k
