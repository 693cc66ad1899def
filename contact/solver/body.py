"""An elastic body: mesh, materials, supports and loads, with its stiffness factored once."""

from __future__ import annotations

from collections.abc import Mapping
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

import fem

if TYPE_CHECKING:
    from ..geometry.surfacequery import TriangleSurface

__all__ = ["ElasticBody"]


class ElasticBody:
    """A linear elastic body whose stiffness is assembled once and factored once.

    ``turns_freely`` (False): the body is a finite-strain body's linearisation
    (:mod:`contact.solver.finite`), whose turn Newton's method carries past the
    small-rotation bound of a linear body. ``finite`` (False): the body is the reference
    of a neo-Hookean body (:meth:`contact.solver.finite.FiniteBody.of`): its stiffness is
    not the linear one, its results are read at finite strain.

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
    contact_faces : fem.BoundaryFaces, optional
        The faces that can touch (a hollow ball's outer sphere, a hand's skin); default:
        the whole boundary less the faces whose nodes are all prescribed (bone holes).
    hold_rotation : bool, optional
        A free body is placed by the contacts through its translations only, its
        rotation held (see :class:`fem.StaticSolver`); default True for a free body:
        frictionless contact cannot turn a ball.
    supports : mapping of str to array_like of int, optional
        Named groups of prescribed nodes (a hand's bones) whose reaction forces are
        reported; every node of a group must be prescribed in all three directions.
    lazy : bool, optional
        Factor the stiffness on first use (default), so that the contact iteration can
        mark the contact zone first (:meth:`fem.StaticSolver.mark`: partial solves
        there); False factors it now.
    bbar : bool, optional
        Bricks and wedges with their element's mean dilatation (default; see
        :func:`fem.assemble_stiffness`), or fully integrated.
    nodal_pressure : bool, optional
        Tetrahedra with averaged nodal pressures (no volumetric locking, about four times
        the stiffness's nonzeros; :mod:`fem.nodalpressure`), or plain (default).
    stiffness : scipy.sparse matrix, optional
        A stiffness to use instead of assembling the linear one (a finite-strain body's
        tangent at its current placement, :mod:`contact.solver.finite`).
    """

    turns_freely: bool = False
    finite: bool = False

    def __init__(
        self,
        name: str,
        mesh: fem.Mesh,
        materials: fem.LinearElastic | Mapping[int, fem.LinearElastic],
        *,
        prescribed: ArrayLike | None = None,
        loads: ArrayLike | None = None,
        backend: str = "auto",
        contact_faces: fem.BoundaryFaces | None = None,
        supports: Mapping[str, ArrayLike] | None = None,
        hold_rotation: bool = True,
        lazy: bool = True,
        bbar: bool = True,
        nodal_pressure: bool = False,
        stiffness: sp.spmatrix | None = None,
    ) -> None:
        self.name = name
        self.mesh = mesh
        self.materials = materials
        self.bbar = bbar
        self.nodal_pressure = nodal_pressure
        if stiffness is None:
            stiffness = fem.assemble_stiffness(
                mesh, materials, bbar=bbar, nodal_pressure=nodal_pressure
            )
        elif stiffness.shape != (mesh.n_dofs, mesh.n_dofs):
            raise ValueError(
                f"{name}: stiffness must have shape ({mesh.n_dofs}, {mesh.n_dofs}), "
                f"got {stiffness.shape}"
            )
        self.stiffness = sp.csr_matrix(stiffness)
        self.stiffness_diagonal = self.stiffness.diagonal()  # kept: each frame's round-off scale
        pres = None if prescribed is None else np.asarray(prescribed, dtype=np.int64)
        self.solver = fem.StaticSolver(
            self.stiffness,
            pres,
            points=mesh.points,
            backend=backend,
            hold_rotation=hold_rotation,
            lazy=lazy,
        )
        n = mesh.n_dofs
        self.loads = np.zeros(n) if loads is None else np.asarray(loads, dtype=np.float64)
        if self.loads.shape != (n,):
            raise ValueError(f"{name}: loads must have shape ({n},), got {self.loads.shape}")
        self._contact_faces = contact_faces
        fixed = np.zeros(n, dtype=bool)
        if pres is not None:
            fixed[pres] = True
        self.fixed_dofs = fixed
        groups: dict[str, NDArray[np.int64]] = {}
        for key, nodes in (supports or {}).items():
            idx = np.asarray(nodes, dtype=np.int64).ravel()
            if idx.size and (idx.min() < 0 or idx.max() >= mesh.n_points):
                raise ValueError(
                    f"{name}: support {key!r} has nodes outside 0..{mesh.n_points - 1}"
                )
            if not fixed[fem.node_dofs(idx)].all():
                raise ValueError(f"{name}: support {key!r} has nodes that are not prescribed")
            groups[str(key)] = idx
        self.supports = groups

    def translated(self, points: ArrayLike) -> ElasticBody:
        """The same body moved rigidly by a translation to ``points``.

        Stiffness and factorisation do not change under a translation: they are shared,
        nothing is refactored.
        """
        x = np.asarray(points, dtype=np.float64)
        d = x - self.mesh.points
        if x.shape != self.mesh.points.shape or np.ptp(d, axis=0).max() > 1e-9 * self.size:
            raise ValueError(f"{self.name}: translated() takes the points moved by one vector")
        moved = object.__new__(ElasticBody)
        moved.__dict__.update(self.__dict__)
        moved.mesh = fem.Mesh(x, self.mesh.cells, self.mesh.regions)
        return moved

    def with_loads(self, loads: ArrayLike) -> ElasticBody:
        """The same body under other known nodal loads ``(3N,)``, nothing refactored.

        Stiffness, solver and factorisation are shared. The solver answers a load by its
        value (:meth:`fem.StaticSolver.apply_inverse` reuses an anticipated answer only for
        the very vector it anticipated), so the shared factorisation solves the new loads
        afresh.
        """
        f = np.asarray(loads, dtype=np.float64)
        if f.shape != self.loads.shape:
            raise ValueError(
                f"{self.name}: loads must have shape {self.loads.shape}, got {f.shape}"
            )
        out = object.__new__(ElasticBody)
        out.__dict__.update(self.__dict__)
        out.loads = f.copy()
        return out

    @property
    def free(self) -> bool:
        """True when nothing but contacts holds the body."""
        return self.solver.free_body

    @cached_property
    def turning(self) -> fem.TurningInverse | None:
        """A free body's exact inverse where it ``turns_freely`` (None otherwise).

        A finite-strain tangent does not vanish on the body's turns: the contact solves
        that place it by all six modes border its compliance with the modes' ``Psi`` and
        stiffness ``H`` (:class:`fem.TurningInverse`) instead of taking its rigid modes
        as free.
        """
        if not (self.turns_freely and self.free):
            return None
        return fem.TurningInverse(self.solver.factorize())

    @cached_property
    def surface_nodes(self) -> NDArray[np.int64]:
        """Nodes on the body's boundary: the ones that can touch."""
        return self.mesh.boundary.nodes

    @cached_property
    def prescribed_nodes(self) -> NDArray[np.int64]:
        """Nodes with all three DOFs prescribed."""
        return np.flatnonzero(self.fixed_dofs.reshape(-1, 3).all(axis=1))

    @cached_property
    def contact_faces(self) -> fem.BoundaryFaces:
        """Boundary faces that can touch (see the class parameters)."""
        if self._contact_faces is not None:
            return self._contact_faces
        bnd = self.mesh.boundary
        held = self.fixed_dofs.reshape(-1, 3).all(axis=1)
        return bnd.subset({k: ~held[f].all(axis=1) for k, f in bnd.faces.items()})

    @cached_property
    def contact_triangles(self) -> NDArray[np.int64]:
        """The contact faces as outward triangles (quads split), in mesh node numbers."""
        from ..geometry.surfacequery import surface_of_mesh

        return surface_of_mesh(self.mesh, self.contact_faces)[1]

    @cached_property
    def contact_surface(self) -> TriangleSurface:
        """The contact faces as a triangle surface at rest (edge neighbours computed once).

        Deformed positions: :meth:`~contact.geometry.surfacequery.TriangleSurface.moved`.
        """
        from ..geometry.surfacequery import TriangleSurface

        surf = TriangleSurface(
            self.mesh.points, self.contact_triangles, name=f"{self.name} contact surface"
        )
        _ = surf._twins, surf._corners  # kept by every moved copy
        return surf

    @cached_property
    def contact_closed(self) -> bool:
        """Whether the contact faces close on themselves (then a node far outside is skipped)."""
        return self.contact_surface.is_closed

    @cached_property
    def contact_nodes(self) -> NDArray[np.int64]:
        """Sorted nodes of the contact faces."""
        return self.contact_faces.nodes

    def mark_zone(
        self, nodes: ArrayLike, nearness: ArrayLike, touched: ArrayLike | None = None
    ) -> int:
        """Mark a contact zone for partial solves, if the body is not factored yet.

        Parameters
        ----------
        nodes : array_like of int
            Nodes of the zone (repeats allowed).
        nearness : array_like of float
            How near each is to contact (smaller first: a gap, m); where the zone would
            pass the solver's capacity (:meth:`fem.StaticSolver.mark_capacity`), the
            nearest nodes are marked.
        touched : array_like of bool, shape (k, 3), optional
            The components of each node that contact rows can touch (default: all);
            a node listed twice gets the union. Marked DOFs make the factorisation
            dearer (they are ordered last, a dense trailing block): only these are.

        Returns
        -------
        int
            Nodes marked (0 when already factored, or the backend has no partial solves).
        """
        nodes = np.asarray(nodes, dtype=np.int64).ravel()
        if self.solver.factored or not nodes.size:
            return 0
        comp = np.ones((nodes.size, 3), dtype=bool)
        if touched is not None:
            comp = np.broadcast_to(np.asarray(touched, dtype=bool), (nodes.size, 3))
        order = np.argsort(np.asarray(nearness, dtype=np.float64).ravel(), kind="stable")
        nodes, comp = nodes[order], comp[order]
        uniq, first, inv = np.unique(nodes, return_index=True, return_inverse=True)
        mask = np.zeros((uniq.size, 3), dtype=bool)
        np.logical_or.at(mask, inv, comp)
        near = np.argsort(first)  # nearest first
        uniq, mask = uniq[near], mask[near]
        keep = np.cumsum(mask.sum(axis=1)) <= self.solver.mark_capacity()
        uniq, mask = uniq[keep], mask[keep]
        dofs = (3 * uniq[:, None] + np.arange(3))[mask]
        return int(uniq.size) if self.solver.mark(dofs) else 0

    def support_forces(self, reactions: NDArray[np.float64]) -> dict[str, NDArray[np.float64]]:
        """Total reaction force ``(3,)`` on each support group (N), from nodal reactions."""
        r = np.asarray(reactions, dtype=np.float64).reshape(-1, 3)
        return {k: r[nodes].sum(axis=0) for k, nodes in self.supports.items()}

    @cached_property
    def size(self) -> float:
        """The body's extent (largest side of its bounding box)."""
        lo, hi = fem.bounding_box(self.mesh.points)
        return float((hi - lo).max())

    @cached_property
    def node_areas(self) -> NDArray[np.float64]:
        """Tributary boundary area of every node (zero inside)."""
        from ..geometry.plane import tributary_areas

        return tributary_areas(self.mesh.points, self.mesh.boundary.faces)
