"""Isoparametric mapping: Jacobians and physical shape-function gradients.

Everything is vectorised over elements: arrays are shaped ``(n_elements, n_quad, ...)``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .elements import ReferenceElement

__all__ = ["det3", "gradients", "inv3", "jacobians"]


def det3(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """Determinants of a stack of 3x3 matrices, shape ``(..., 3, 3) -> (...)``."""
    return (
        a[..., 0, 0] * (a[..., 1, 1] * a[..., 2, 2] - a[..., 1, 2] * a[..., 2, 1])
        - a[..., 0, 1] * (a[..., 1, 0] * a[..., 2, 2] - a[..., 1, 2] * a[..., 2, 0])
        + a[..., 0, 2] * (a[..., 1, 0] * a[..., 2, 1] - a[..., 1, 1] * a[..., 2, 0])
    )


def inv3(a: NDArray[np.float64], det: NDArray[np.float64]) -> NDArray[np.float64]:
    """Inverses of a stack of 3x3 matrices given their determinants."""
    inv = np.empty_like(a)
    inv[..., 0, 0] = a[..., 1, 1] * a[..., 2, 2] - a[..., 1, 2] * a[..., 2, 1]
    inv[..., 0, 1] = a[..., 0, 2] * a[..., 2, 1] - a[..., 0, 1] * a[..., 2, 2]
    inv[..., 0, 2] = a[..., 0, 1] * a[..., 1, 2] - a[..., 0, 2] * a[..., 1, 1]
    inv[..., 1, 0] = a[..., 1, 2] * a[..., 2, 0] - a[..., 1, 0] * a[..., 2, 2]
    inv[..., 1, 1] = a[..., 0, 0] * a[..., 2, 2] - a[..., 0, 2] * a[..., 2, 0]
    inv[..., 1, 2] = a[..., 0, 2] * a[..., 1, 0] - a[..., 0, 0] * a[..., 1, 2]
    inv[..., 2, 0] = a[..., 1, 0] * a[..., 2, 1] - a[..., 1, 1] * a[..., 2, 0]
    inv[..., 2, 1] = a[..., 0, 1] * a[..., 2, 0] - a[..., 0, 0] * a[..., 2, 1]
    inv[..., 2, 2] = a[..., 0, 0] * a[..., 1, 1] - a[..., 0, 1] * a[..., 1, 0]
    return inv / det[..., None, None]


def jacobians(
    coords: NDArray[np.float64], element: ReferenceElement, xi: NDArray[np.float64] | None = None
) -> NDArray[np.float64]:
    """Jacobian matrices ``J[e, q, i, j] = d x_i / d xi_j``.

    Parameters
    ----------
    coords : ndarray, shape (n_elements, n_nodes, 3)
        Nodal coordinates of each element.
    element : ReferenceElement
        The reference element.
    xi : ndarray, shape (q, 3), optional
        Reference points; the element's quadrature points by default.

    Returns
    -------
    ndarray, shape (n_elements, q, 3, 3)
    """
    dn = element.grad(element.points if xi is None else xi)
    return np.matmul(coords.transpose(0, 2, 1)[:, None], dn[None])


def gradients(
    coords: NDArray[np.float64], element: ReferenceElement
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Physical shape-function gradients and Jacobian determinants at quadrature points.

    Parameters
    ----------
    coords : ndarray, shape (n_elements, n_nodes, 3)
        Nodal coordinates of each element.
    element : ReferenceElement
        The reference element.

    Returns
    -------
    grad : ndarray, shape (n_elements, n_quad, n_nodes, 3)
        ``grad[e, q, a, i] = d N_a / d x_i``.
    detj : ndarray, shape (n_elements, n_quad)
        Jacobian determinants (signed: never made absolute here).
    """
    dn = element.grad(element.points)
    jac = np.matmul(coords.transpose(0, 2, 1)[:, None], dn[None])  # (E, q, 3, 3)
    detj = det3(jac)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = inv3(jac, detj)
    grad = np.matmul(dn[None], inv)  # (E, q, n, 3)
    return grad, detj
