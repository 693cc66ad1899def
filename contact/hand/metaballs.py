"""The skin as the iso-surface of ellipsoidal metaballs.

The body model of Thalmann, Shen and Chauvineau (1996), sections 1 to 3.

Each primitive is an ellipsoid attached to its proximal joint, in that joint's frame, with
radii ``(a, b, c)`` and a weight ``w``. Its field is a soft-object kernel of the ellipsoidal
distance ``r`` (``r = 1`` on the ellipsoid)::

    f(r) = w * (1 - r**2 / R**2) ** 3   for r < R,   0 beyond,

where ``R > 1`` is the rig's ``skin.reach``. The surface is the level ``T = (1 - 1/R**2)**3``,
so an isolated primitive of weight 1 is exactly its ellipsoid; neighbours within reach blend.

Blend groups keep fingers apart (Thalmann, Shen and Chauvineau 1996, 3.1): fields are summed
per group, and every group blends with the base group (the palm) but not with the others::

    F = S_base + max over other groups g of S_g.

The field is sampled on a regular grid, contoured with VTK's flying edges at ``T``, cleaned,
smoothed with a Taubin filter (which keeps the volume) and checked: closed, manifold,
consistently and outward oriented, one piece, free of self-intersections.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ..geometry.surfaces import (
    check_closed_surface,
    enclosed_volume,
    poly_from_arrays,
    surface_arrays,
)
from .skeleton import Skeleton

if TYPE_CHECKING:
    import pyvista

__all__ = ["field_on_grid", "field_threshold", "posed_primitives", "skin_surface"]

log = logging.getLogger(__name__)


def field_threshold(reach: float) -> float:
    """The iso-level ``(1 - 1/reach**2)**3`` at which a lone unit primitive is its ellipsoid."""
    return float((1.0 - 1.0 / reach**2) ** 3)


def posed_primitives(
    skeleton: Skeleton, angles: Mapping[str, float] | None = None
) -> dict[str, NDArray]:
    """World centres, axes, radii, weights and group indices of the posed primitives.

    Parameters
    ----------
    skeleton : Skeleton
    angles : mapping of str to float, optional
        Joint angles in degrees (rest pose when omitted).

    Returns
    -------
    dict
        ``center (n, 3)``, ``axes (n, 3, 3)`` (columns: the ellipsoid's axes in the world),
        ``radii (n, 3)``, ``weight (n,)``, ``group (n,)`` (index into ``skeleton.spec.groups``).
    """
    frames = skeleton.joint_frames(angles)
    prims = skeleton.primitives
    f = np.stack([frames[p.joint] for p in prims])
    center = np.einsum("nij,nj->ni", f[:, :3, :3], np.stack([p.center for p in prims]))
    groups = skeleton.spec.groups
    return {
        "center": center + f[:, :3, 3],
        "axes": f[:, :3, :3] @ np.stack([p.rotation for p in prims]),
        "radii": np.stack([p.radii for p in prims]),
        "weight": np.array([p.weight for p in prims]),
        "group": np.array([groups.index(p.group) for p in prims]),
    }


def _group_sum(
    prims: dict[str, NDArray], which: NDArray, origin: NDArray, h: float, shape: tuple, reach: float
) -> NDArray[np.float32]:
    """Sum of the fields of primitives ``which`` on the grid, each over its own sub-box."""
    out = np.zeros(shape, dtype=np.float32)
    for i in which:
        c, ax, rad, w = prims["center"][i], prims["axes"][i], prims["radii"][i], prims["weight"][i]
        half = reach * np.sqrt(((ax * rad) ** 2).sum(axis=1))
        lo = np.maximum(np.floor((c - half - origin) / h).astype(int), 0)
        hi = np.minimum(np.ceil((c + half - origin) / h).astype(int) + 1, shape)
        if (hi <= lo).any():
            continue
        xs = [origin[k] + h * np.arange(lo[k], hi[k]) - c[k] for k in range(3)]
        # local coordinates u_k = sum_j ax[j, k] x_j / rad_k, by broadcasting per axis
        q = np.zeros((hi - lo).tolist())
        for k in range(3):
            u = (
                xs[0][:, None, None] * ax[0, k]
                + xs[1][None, :, None] * ax[1, k]
                + xs[2][None, None, :] * ax[2, k]
            ) / rad[k]
            q += u * u
        g = np.clip(1.0 - q / reach**2, 0.0, None) ** 3
        out[lo[0] : hi[0], lo[1] : hi[1], lo[2] : hi[2]] += (w * g).astype(np.float32)
    return out


def field_on_grid(
    skeleton: Skeleton,
    angles: Mapping[str, float] | None = None,
    spacing: float = 0.001,
    padding: int = 3,
) -> pyvista.ImageData:
    """Sample the blended skin field on a regular grid around the posed primitives.

    Parameters
    ----------
    skeleton : Skeleton
    angles : mapping of str to float, optional
        Joint angles in degrees.
    spacing : float
        Grid step (m).
    padding : int
        Empty grid layers around the primitives' reach, so the iso-surface closes.

    Returns
    -------
    pyvista.ImageData
        With point array ``"field"``; contour it at :func:`field_threshold`.
    """
    import pyvista as pv

    if not spacing > 0:
        raise ValueError(f"grid spacing must be positive, got {spacing!r}")
    reach = skeleton.spec.reach
    prims = posed_primitives(skeleton, angles)
    half = reach * np.sqrt(((prims["axes"] * prims["radii"][:, None, :]) ** 2).sum(axis=2))
    lo = (prims["center"] - half).min(axis=0) - padding * spacing
    hi = (prims["center"] + half).max(axis=0) + padding * spacing
    shape = tuple((np.ceil((hi - lo) / spacing).astype(int) + 1).tolist())
    base = skeleton.spec.groups.index(skeleton.spec.base_group)
    total = _group_sum(prims, np.flatnonzero(prims["group"] == base), lo, spacing, shape, reach)
    others = np.zeros(shape, dtype=np.float32)
    for g in sorted(set(prims["group"].tolist()) - {base}):
        s = _group_sum(prims, np.flatnonzero(prims["group"] == g), lo, spacing, shape, reach)
        np.maximum(others, s, out=others)
    total += others
    grid = pv.ImageData(dimensions=shape, spacing=(spacing,) * 3, origin=lo.tolist())
    grid.point_data["field"] = total.ravel(order="F")
    return grid


def skin_surface(
    skeleton: Skeleton,
    angles: Mapping[str, float] | None = None,
    resolution: float = 0.001,
    smooth_iterations: int = 30,
    check_self_intersections: bool = True,
) -> pyvista.PolyData:
    """The skin: the checked, smoothed iso-surface of the rig's metaballs.

    Parameters
    ----------
    skeleton : Skeleton
    angles : mapping of str to float, optional
        Joint angles in degrees; the rest pose by default. (Posing the primitives is
        Thalmann, Shen and Chauvineau's way; the FE skin is posed by the JLD mapping instead.)
    resolution : float
        Grid spacing of the field (m); triangle edges come out about this long.
    smooth_iterations : int
        Taubin smoothing iterations (0 for none).
    check_self_intersections : bool
        Also run the triangle-triangle self-intersection test (a few seconds at 1 mm).

    Returns
    -------
    pyvista.PolyData
        Triangles, outward oriented.

    Raises
    ------
    fem.MeshError
        If the surface is open, non-manifold, in several pieces or self-intersecting (then
        the rig's primitives or the resolution need changing).
    """
    grid = field_on_grid(skeleton, angles, resolution)
    level = field_threshold(skeleton.spec.reach)
    poly = grid.contour([level], scalars="field", method="flying_edges")
    poly = poly.triangulate().clean(tolerance=1e-3 * resolution, absolute=False)
    if smooth_iterations:
        poly = poly.smooth_taubin(
            n_iter=smooth_iterations, pass_band=0.05, normalize_coordinates=True
        )
    pts, tri = surface_arrays(poly)
    keep = np.unique(tri)
    remap = np.full(len(pts), -1)
    remap[keep] = np.arange(len(keep))
    pts, tri = pts[keep], remap[tri]
    if enclosed_volume(pts, tri) < 0:  # contour winding follows the field gradient
        tri = tri[:, ::-1]
    poly = poly_from_arrays(pts, tri)
    check_closed_surface(
        poly, f"skin of {skeleton.spec.source}", check_intersections=check_self_intersections
    )
    log.info("skin surface: %d points, %d triangles", poly.n_points, poly.n_cells)
    return poly
