"""Degree-of-freedom numbering: three DOFs a node, node-major (``3 * node + component``)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["element_dofs", "node_dofs"]


def node_dofs(nodes: ArrayLike, components: ArrayLike = (0, 1, 2)) -> NDArray[np.int64]:
    """DOFs of nodes, node-major: ``3 * node + component`` for each node and component."""
    n = np.asarray(nodes, dtype=np.int64).ravel()
    c = np.asarray(components, dtype=np.int64).ravel()
    return (3 * n[:, None] + c[None, :]).ravel()


def element_dofs(conn: NDArray[np.int64]) -> NDArray[np.int64]:
    """Global DOFs of each element, node-major: ``(M, k) -> (M, 3k)``."""
    return (3 * conn[:, :, None] + np.arange(3)).reshape(len(conn), -1)
