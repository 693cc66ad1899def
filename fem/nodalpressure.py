"""Linear tetrahedra without volumetric locking: the average nodal pressure element.

A linear tetrahedron's strain is constant, so its volumetric strain cannot be relaxed
inside the element as a brick's mean dilatation relaxes it (B-bar): as Poisson's ratio
nears 1/2 a tetrahedral mesh locks (on Lame's thick sphere with three tetrahedra through
the wall, half as stiff again as it should be at nu 0.499). Bonet and Burton's element (1998,
"A simple average nodal pressure tetrahedral element for incompressible and nearly
incompressible dynamic explicit applications") keeps each tetrahedron's deviatoric energy
and takes the volumetric energy at the nodes instead, from the volume-weighted average of
the dilatations of the tetrahedra around each node::

    theta_n = sum_e (V_e / 4) theta_e / V_n,      V_n = sum_e V_e / 4
    U_vol = sum_n kappa_n V_n theta_n^2 / 2

with ``kappa_n`` the same average of the bulk moduli. A node has a quarter of each of its
tetrahedra's volume to spend on incompressibility instead of a tetrahedron its whole
volume: the ratio of constraints to unknowns of a tetrahedral mesh (about 1 per node
against 3) no longer locks it. Its stiffness couples nodes two edges apart: about four
times the nonzeros of the plain tetrahedra, three times the factor's.

Here the stiffness is the plain one plus :func:`nodal_pressure_correction` (the nodal
volumetric term less the elements' own), and the strain of a tetrahedron takes the mean
of its four nodes' dilatations (:func:`nodal_dilatation`) for its own, as its stress does.
An affine displacement has the same dilatation everywhere: the patch test holds.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from .dofs import element_dofs
from .elements import ELEMENTS
from .mapping import gradients
from .material import LinearElastic, lame_fields
from .mesh import Mesh

__all__ = ["nodal_dilatation", "nodal_pressure_correction"]


def _divergence(mesh: Mesh) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """Each tetrahedron's DOFs ``(M, 12)``, divergence row ``(M, 12)`` and volume ``(M,)``."""
    conn = mesh.cells["tetra"]
    elem = ELEMENTS["tetra"]
    grad, detj = gradients(mesh.points[conn], elem)
    vol = (detj * elem.weights).sum(axis=1)
    # a linear tetrahedron's gradients are constant: those of its one Gauss point
    return element_dofs(conn), grad[:, 0].reshape(len(conn), 12), vol


def _operator(mesh: Mesh) -> tuple[sp.csr_matrix, NDArray[np.float64]]:
    """``G`` (N x 3N, ``theta_n = G u``) and the nodes' volumes ``V_n`` (0 off the tets)."""
    conn = mesh.cells["tetra"]
    dofs, div, vol = _divergence(mesh)
    n = mesh.n_points
    vn = np.bincount(conn.ravel(), np.repeat(vol / 4.0, 4), minlength=n)
    rows = np.repeat(conn, 12, axis=1).ravel()  # node a of each (element, a, dof)
    cols = np.tile(dofs, 4).ravel()
    vals = np.repeat(np.repeat((vol / 4.0)[:, None], 4, axis=1), 12, axis=1).ravel()
    vals = vals * np.tile(div, 4).ravel()
    g = sp.csr_matrix((vals, (rows, cols)), shape=(n, mesh.n_dofs))
    inv = np.divide(1.0, vn, out=np.zeros(n), where=vn > 0)
    return sp.diags(inv) @ g, vn


def nodal_dilatation(mesh: Mesh, u: ArrayLike) -> NDArray[np.float64]:
    """Each node's dilatation, the volume-weighted mean of its tetrahedra's ``(N,)``.

    Nodes of no tetrahedron get 0.
    """
    if "tetra" not in mesh.cells:
        return np.zeros(mesh.n_points)
    g, _ = _operator(mesh)
    return g @ np.asarray(u, dtype=np.float64).ravel()


def nodal_pressure_correction(
    mesh: Mesh, materials: LinearElastic | Mapping[int, LinearElastic]
) -> sp.csr_matrix:
    """What turns the plain tetrahedra's stiffness into the average nodal pressure one.

    ``sum_n kappa_n V_n g_n g_n^T - sum_e kappa_e V_e b_e b_e^T`` over the tetrahedra,
    ``g_n`` the rows of the nodal dilatation, ``b_e`` the tetrahedra's divergence rows and
    ``kappa = lam + 2 mu / 3`` the bulk modulus. Symmetric, ``(3N, 3N)``; empty without
    tetrahedra.

    Parameters
    ----------
    mesh : Mesh
    materials : LinearElastic or mapping of int to LinearElastic
        As for :func:`fem.assemble_stiffness`.

    Returns
    -------
    scipy.sparse.csr_matrix
    """
    n = mesh.n_dofs
    if "tetra" not in mesh.cells:
        return sp.csr_matrix((n, n))
    lam, mu = lame_fields(mesh, materials)["tetra"]
    kappa = lam + 2.0 * mu / 3.0
    conn = mesh.cells["tetra"]
    dofs, div, vol = _divergence(mesh)
    elem_vol = (kappa * vol)[:, None, None] * div[:, :, None] * div[:, None, :]
    rows = np.repeat(dofs, 12, axis=1).ravel()
    cols = np.tile(dofs, 12).ravel()
    own = sp.csr_matrix((elem_vol.ravel(), (rows, cols)), shape=(n, n))
    g, _ = _operator(mesh)
    kn = np.bincount(conn.ravel(), np.repeat(kappa * vol / 4.0, 4), minlength=mesh.n_points)
    nodal = (g.T @ sp.diags(kn) @ g).tocsr()  # kappa_n V_n = sum_e kappa_e V_e / 4
    out = (nodal - own).tocsr()
    out.sum_duplicates()
    return out
