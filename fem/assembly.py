"""Vectorised assembly of the linear elastic stiffness matrix.

One einsum per element type gives the elements' 3x3 node-pair blocks; a bincount scatter
sums them over the node-pair pattern. ``element_dofs`` and ``lame_fields`` are
re-exported here from :mod:`fem.dofs` and :mod:`fem.material`, where they live.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from .dofs import element_dofs
from .elements import ELEMENTS, ReferenceElement
from .mapping import gradients
from .material import LinearElastic, lame_fields
from .mesh import Mesh
from .nodalpressure import nodal_pressure_correction

__all__ = [
    "assemble_blocks",
    "assemble_stiffness",
    "element_blocks",
    "element_dofs",
    "element_stiffness",
    "lame_fields",
]

#: Elements processed at once; bounds the temporaries to a few hundred MB.
CHUNK = 100_000


def element_blocks(
    coords: NDArray[np.float64],
    element: ReferenceElement,
    lam: NDArray[np.float64],
    mu: NDArray[np.float64],
    bbar: bool = True,
) -> NDArray[np.float64]:
    """Element stiffness of isotropic linear elasticity as 3x3 node-pair blocks.

    ``K[a, b, i, k] = sum_q w_q det J_q (lam G_ai G_bk + mu G_ak G_bi + mu delta_ik G_al G_bl)``
    with ``G`` the physical shape-function gradients. An element with
    ``mean_dilatation`` (B-bar) takes its volumetric part from the element's mean
    dilatation instead: the sum above with ``-2 mu / 3`` for ``lam`` (the deviatoric
    part), plus ``kappa S_ai S_bk / V`` with ``S_a = sum_q w_q det J_q G_a``, ``V`` the
    element's volume and ``kappa = lam + 2 mu / 3`` the bulk modulus.

    Parameters
    ----------
    coords : ndarray, shape (M, n, 3)
        Element nodal coordinates.
    element : ReferenceElement
        Reference element of the block.
    lam, mu : ndarray, shape (M,)
        Lame parameters per element.
    bbar : bool
        Use the element's mean dilatation where it has one (False: every term at every
        Gauss point, "full integration").

    Returns
    -------
    ndarray, shape (M, n, n, 3, 3)
        Block ``[e, a, b]`` couples node ``a`` (rows, component ``i``) with node ``b``.
    """
    grad, detj = gradients(coords, element)
    wdet = detj * element.weights
    gs = grad * np.sqrt(wdet)[:, :, None, None]
    m = np.einsum("eqai,eqbk->eabik", gs, gs, optimize=True)
    if bbar and element.mean_dilatation:
        s = np.einsum("eq,eqai->eai", wdet, grad)
        kappa = (lam + 2.0 * mu / 3.0) / wdet.sum(axis=1)
        kb = kappa[:, None, None, None, None] * np.einsum("eai,ebk->eabik", s, s)
        kb -= (2.0 * mu / 3.0)[:, None, None, None, None] * m
    else:
        kb = lam[:, None, None, None, None] * m
    kb += mu[:, None, None, None, None] * m.swapaxes(-1, -2)
    trace = mu[:, None, None] * (m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2])
    for i in range(3):
        kb[..., i, i] += trace
    return kb


def element_stiffness(
    coords: NDArray[np.float64],
    element: ReferenceElement,
    lam: NDArray[np.float64],
    mu: NDArray[np.float64],
    bbar: bool = True,
) -> NDArray[np.float64]:
    """Element stiffness matrices ``(M, 3n, 3n)`` in the element's node-major DOF order.

    See :func:`element_blocks` for the formula and the parameters.
    """
    kb = element_blocks(coords, element, lam, mu, bbar)
    m, n = kb.shape[:2]
    return kb.transpose(0, 1, 3, 2, 4).reshape(m, 3 * n, 3 * n)


def assemble_stiffness(
    mesh: Mesh,
    materials: LinearElastic | Mapping[int, LinearElastic],
    *,
    bbar: bool = True,
    nodal_pressure: bool = False,
) -> sp.csr_matrix:
    """Assemble the global stiffness matrix.

    Parameters
    ----------
    mesh : Mesh
        The mesh (any mix of tetra, hexahedron and wedge cells).
    materials : LinearElastic or mapping of int to LinearElastic
        One material for all cells, or one per region id.
    bbar : bool
        Hexahedra and wedges take their volumetric strain as the element's mean (B-bar:
        no volumetric locking as Poisson's ratio nears 1/2); False integrates every term
        at every Gauss point. Tetrahedra are the same either way.
    nodal_pressure : bool
        Tetrahedra take their volumetric energy at the nodes (Bonet and Burton's average
        nodal pressure element, :mod:`fem.nodalpressure`: no volumetric locking, about
        four times the nonzeros); False: plain linear tetrahedra.

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
    pairs, inverse = _node_pairs(mesh, list(mesh.cells))
    blocks = np.zeros((len(pairs), 9))
    pos = 0
    for kind, conn in mesh.cells.items():
        elem = ELEMENTS[kind]
        lam, mu = fields[kind]
        for s in range(0, len(conn), CHUNK):
            c = conn[s : s + CHUNK]
            kb = element_blocks(mesh.points[c], elem, lam[s : s + CHUNK], mu[s : s + CHUNK], bbar)
            kb = kb.reshape(-1, 9)
            _scatter(blocks, inverse[pos : pos + len(kb)], kb)
            pos += len(kb)
    k = _to_csr(mesh, pairs, blocks)
    if nodal_pressure and "tetra" in mesh.cells:
        return (k + nodal_pressure_correction(mesh, materials)).tocsr()
    return k


def _node_pairs(mesh: Mesh, kinds: list[str]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """The node-pair pattern of the cells of ``kinds``: the pairs' keys and each block's pair.

    One 3x3 block per pair of nodes sharing a cell (9x fewer keys to sort than scalar COO
    entries), keyed ``row * N + column``, in the cells' order, node pairs within a cell
    row-major.
    """
    n = mesh.n_points
    keys = np.concatenate(
        [(mesh.cells[k][:, :, None] * n + mesh.cells[k][:, None, :]).ravel() for k in kinds]
    )
    pairs, inverse = np.unique(keys, return_inverse=True)
    return pairs, inverse.ravel()


def _scatter(blocks: NDArray, idx: NDArray[np.int64], values: NDArray) -> None:
    """Add ``values (k, 9)`` into ``blocks`` at the pairs ``idx``, in one bincount.

    The bincount spans only the pairs ``idx`` touches: its cost follows the chunk, not
    the whole pattern.
    """
    lo, hi = int(idx.min()), int(idx.max()) + 1
    flat = ((idx - lo)[:, None] * 9 + np.arange(9)).ravel()
    blocks[lo:hi] += np.bincount(flat, values.ravel(), minlength=(hi - lo) * 9).reshape(-1, 9)


def _to_csr(mesh: Mesh, pairs: NDArray[np.int64], blocks: NDArray) -> sp.csr_matrix:
    """The summed node-pair blocks ``(P, 9)`` as a CSR matrix over the mesh's DOFs."""
    n = mesh.n_points
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(pairs // n, minlength=n), out=indptr[1:])
    bsr = sp.bsr_matrix(
        (blocks.reshape(-1, 3, 3), pairs % n, indptr), shape=(mesh.n_dofs, mesh.n_dofs)
    )
    return bsr.tocsr()


def assemble_blocks(
    mesh: Mesh, blocks: dict[str, list[NDArray[np.float64]]]
) -> sp.csr_matrix:
    """Sum element node-pair blocks into one sparse matrix over the mesh's DOFs.

    ``blocks`` maps a cell kind to arrays ``(M, n, n, 3, 3)`` of its cells, in the
    mesh's order (several arrays of a kind add up). The node-pair pattern and the
    bincount scatter are :func:`assemble_stiffness`'s: no COO triple larger than the
    blocks themselves.
    """
    kinds = [k for k in mesh.cells if blocks.get(k)]
    if not kinds:
        return sp.csr_matrix((mesh.n_dofs, mesh.n_dofs))
    pairs, inverse = _node_pairs(mesh, kinds)
    total = np.zeros((len(pairs), 9))
    values = np.concatenate([sum(blocks[k]).reshape(-1, 9) for k in kinds])
    _scatter(total, inverse, values)
    return _to_csr(mesh, pairs, total)
