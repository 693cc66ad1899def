"""Strain and stress from displacements: Gauss points, element averages, nodal averages."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .elements import ELEMENTS
from .mapping import gradients
from .material import LinearElastic, lame_fields
from .mesh import Mesh
from .nodalpressure import nodal_dilatation

__all__ = ["cell_stress", "gauss_strain", "nodal_average", "stress_from_strain", "von_mises"]


def _strain_and_weights(
    mesh: Mesh, u: ArrayLike, bbar: bool = True, nodal_pressure: bool = False
) -> dict[str, tuple[NDArray[np.float64], NDArray[np.float64]]]:
    """Per type: strain at the Gauss points ``(M, q, 3, 3)`` and their weights ``(M, q)``.

    An element with ``mean_dilatation`` (B-bar) has its Gauss points' volumetric strain
    replaced by the element's mean, as its stiffness does; with ``nodal_pressure`` a
    tetrahedron's by the mean of its nodes' (:mod:`fem.nodalpressure`).
    """
    uv = np.asarray(u, dtype=np.float64).reshape(-1, 3)
    theta = nodal_dilatation(mesh, uv) if nodal_pressure and "tetra" in mesh.cells else None
    out = {}
    for kind, conn in mesh.cells.items():
        elem = ELEMENTS[kind]
        grad, detj = gradients(mesh.points[conn], elem)
        w = detj * elem.weights
        du = np.einsum("eqaj,eai->eqij", grad, uv[conn])  # du_i/dx_j
        eps = 0.5 * (du + du.swapaxes(-1, -2))
        if bbar and elem.mean_dilatation:
            tr = np.trace(eps, axis1=-2, axis2=-1)
            mean = (w * tr).sum(axis=1) / w.sum(axis=1)
            eps = eps + ((mean[:, None] - tr) / 3.0)[..., None, None] * np.eye(3)
        if theta is not None and kind == "tetra":
            tr = np.trace(eps, axis1=-2, axis2=-1)
            mean = theta[conn].mean(axis=1)
            eps = eps + ((mean[:, None] - tr) / 3.0)[..., None, None] * np.eye(3)
        out[kind] = (eps, w)
    return out


def gauss_strain(
    mesh: Mesh, u: ArrayLike, *, bbar: bool = True, nodal_pressure: bool = False
) -> dict[str, NDArray[np.float64]]:
    """Small strain tensor at every Gauss point: per type ``(M, q, 3, 3)``.

    ``bbar`` and ``nodal_pressure`` as in :func:`fem.assemble_stiffness`.
    """
    strains = _strain_and_weights(mesh, u, bbar, nodal_pressure)
    return {kind: eps for kind, (eps, _) in strains.items()}


def stress_from_strain(
    eps: NDArray[np.float64], lam: NDArray[np.float64], mu: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Isotropic Hooke's law ``sigma = lam tr(eps) I + 2 mu eps`` (``lam, mu`` broadcast)."""
    tr = np.trace(eps, axis1=-2, axis2=-1)
    return lam[..., None, None] * tr[..., None, None] * np.eye(3) + 2.0 * mu[..., None, None] * eps


def von_mises(sigma: NDArray[np.float64]) -> NDArray[np.float64]:
    """Von Mises equivalent stress of ``(..., 3, 3)`` tensors."""
    dev = sigma - np.trace(sigma, axis1=-2, axis2=-1)[..., None, None] * np.eye(3) / 3.0
    return np.sqrt(1.5 * np.einsum("...ij,...ij->...", dev, dev))


def cell_stress(
    mesh: Mesh,
    materials: LinearElastic | Mapping[int, LinearElastic],
    u: ArrayLike,
    initial: Mapping[str, ArrayLike] | None = None,
    *,
    at: str = "mean",
    bbar: bool = True,
    nodal_pressure: bool = False,
) -> dict[str, NDArray[np.float64]]:
    """Cauchy stress per cell.

    Parameters
    ----------
    mesh, materials, u
        The mesh, its materials and a displacement vector ``(3N,)``.
    initial : mapping, optional
        Initial stress per cell type ``(M, 3, 3)`` added to the elastic stress.
    at : {"mean", "gauss"}
        ``"mean"``: the volume average over each cell ``(M, 3, 3)``; ``"gauss"``: every
        Gauss point ``(M, q, 3, 3)``.
    bbar, nodal_pressure : bool
        As the stiffness was assembled (:func:`fem.assemble_stiffness`).
    """
    if at not in ("mean", "gauss"):
        raise ValueError(f"at must be 'mean' or 'gauss', got {at!r}")
    strains = _strain_and_weights(mesh, u, bbar, nodal_pressure)
    fields = lame_fields(mesh, materials)
    out = {}
    for kind, (e, w) in strains.items():
        lam, mu = fields[kind]
        s = stress_from_strain(e, lam[:, None], mu[:, None])
        if initial is not None and kind in initial:
            s = s + np.asarray(initial[kind], dtype=np.float64)[:, None]
        if at == "mean":
            s = np.einsum("eq,eqij->eij", w, s) / w.sum(axis=1)[:, None, None]
        out[kind] = s
    return out


def nodal_average(mesh: Mesh, cell_values: Mapping[str, ArrayLike]) -> NDArray[np.float64]:
    """Volume-weighted average of per-cell values at the nodes (for smooth plots).

    ``cell_values`` maps each cell type to ``(M, ...)``; returns ``(N, ...)``.
    """
    first = np.asarray(next(iter(cell_values.values())))
    shape = first.shape[1:]
    acc = np.zeros((mesh.n_points, int(np.prod(shape, dtype=int))))
    weight = np.zeros(mesh.n_points)
    for kind, conn in mesh.cells.items():
        if kind not in cell_values:
            raise ValueError(f"cell values missing for the {kind} cells")
        v = np.asarray(cell_values[kind], dtype=np.float64)
        if v.shape != (len(conn), *shape):
            raise ValueError(
                f"cell values for {kind} must have shape {(len(conn), *shape)}, got {v.shape}"
            )
        vol = mesh.volumes[kind]
        k = conn.shape[1]
        flat = v.reshape(len(conn), -1) * (vol / k)[:, None]
        for j in range(flat.shape[1]):
            acc[:, j] += np.bincount(
                conn.ravel(), np.repeat(flat[:, j], k), minlength=mesh.n_points
            )
        weight += np.bincount(conn.ravel(), np.repeat(vol / k, k), minlength=mesh.n_points)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = acc / weight[:, None]
    out[weight == 0] = 0.0
    return out.reshape((mesh.n_points, *shape))
