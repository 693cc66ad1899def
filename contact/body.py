"""An elastic body: mesh, materials, supports and loads, with its stiffness factored once."""

from __future__ import annotations

from collections.abc import Mapping
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray

import fem

__all__ = ["ElasticBody"]


class ElasticBody:
    """A linear elastic body whose stiffness is assembled and factored once.

    Parameters
    ----------
    name : str
        For messages and results (``"ball"``, ``"hand"``).
    mesh : fem.Mesh
        Its volume mesh.
    materials : fem.LinearElastic or mapping of int to fem.LinearElastic
        One material, or one per region.
    prescribed : array_like of int, optional
        DOFs held by the body's own supports (a hand's bone nodes). None: a free body,
        whose rigid-body modes the contacts must hold.
    loads : array_like, shape (3N,), optional
        Known nodal loads (pressure, gravity); zero by default.
    backend : str
        Linear solver (see :func:`fem.factorize`).
    """

    def __init__(
        self,
        name: str,
        mesh: fem.Mesh,
        materials: fem.LinearElastic | Mapping[int, fem.LinearElastic],
        *,
        prescribed: ArrayLike | None = None,
        loads: ArrayLike | None = None,
        backend: str = "auto",
    ) -> None:
        self.name = name
        self.mesh = mesh
        self.materials = materials
        self.stiffness = fem.assemble_stiffness(mesh, materials)
        pres = None if prescribed is None else np.asarray(prescribed, dtype=np.int64)
        self.solver = fem.StaticSolver(self.stiffness, pres, points=mesh.points, backend=backend)
        n = mesh.n_dofs
        self.loads = np.zeros(n) if loads is None else np.asarray(loads, dtype=np.float64)
        if self.loads.shape != (n,):
            raise ValueError(f"{name}: loads must have shape ({n},), got {self.loads.shape}")

    @property
    def free(self) -> bool:
        """True when nothing but contacts holds the body."""
        return self.solver.free_body

    @cached_property
    def surface_nodes(self) -> NDArray[np.int64]:
        """Nodes on the body's boundary: the ones that can touch."""
        return self.mesh.boundary.nodes

    @cached_property
    def size(self) -> float:
        """The body's extent (largest side of its bounding box)."""
        return float(np.ptp(self.mesh.points, axis=0).max())

    @cached_property
    def node_areas(self) -> NDArray[np.float64]:
        """Tributary boundary area of every node (zero inside)."""
        from .geometry import tributary_areas

        return tributary_areas(self.mesh.points, self.mesh.boundary.faces)
