"""A faceted surface smoothed through its nodal normals (Phong tessellation).

A coarse mesh's facets lie inside the curved surface they stand for, by ``h^2 / 8R`` at a
facet's middle: as much as a small press. Weighted gaps measured on the flat facets see
that sagitta and close late. Phong tessellation (Boubekeur and Alexa 2008) moves each
point of a facet ``ALPHA`` of the way to the mean of its projections on the tangent
planes at the facet's corners (weighted by its shape functions); with ``ALPHA = 1/2`` it
is exact to second order on a sphere. Faces meeting at more than :data:`CREASE` keep
their own normals there: a block's edge stays sharp and its flat faces flat.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["ALPHA", "CREASE", "bulge", "corner_normals", "face_cross", "smoothed"]

#: Faces whose normals differ by more than this (degrees) meet at a crease: no smoothing.
CREASE = 40.0
#: Phong tessellation's blend: 1/2 is exact to second order on a sphere.
ALPHA = 0.5


def face_cross(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Normals of faces ``(F, k, 3)`` twice their areas long (quads by their diagonals)."""
    if x.shape[1] == 3:
        return np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    return np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 1])


def corner_normals(
    points: NDArray[np.float64], faces: dict[str, NDArray[np.int64]], crease: float = CREASE
) -> dict[str, NDArray[np.float64]]:
    """Each face corner's smoothed unit normal, ``(F, k, 3)`` per face kind.

    The mean of the normals of the faces around the corner's node that lie within
    ``crease`` degrees of the corner's own face, weighted by those faces' areas.
    """
    kinds = [k for k, f in faces.items() if len(f)]
    normals, areas, corner_face, corner_node = [], [], [], []
    base = 0
    for k in kinds:
        f = faces[k]
        c = face_cross(points[f])
        a = np.linalg.norm(c, axis=1)
        normals.append(c / np.maximum(a, 1e-300)[:, None])
        areas.append(a)
        corner_face.append(np.repeat(np.arange(len(f)) + base, f.shape[1]))
        corner_node.append(f.ravel())
        base += len(f)
    if not kinds:
        return {}
    nf, af = np.concatenate(normals), np.concatenate(areas)
    cf, cn = np.concatenate(corner_face), np.concatenate(corner_node)
    # the faces around each node, as CSR over the nodes
    order = np.argsort(cn, kind="stable")
    starts = np.searchsorted(cn[order], np.arange(len(points) + 1))
    count = np.diff(starts)[cn]  # faces around each corner's node
    corner = np.repeat(np.arange(cn.size), count)
    offset = np.arange(corner.size) - np.repeat(np.cumsum(count) - count, count)
    other = cf[order[starts[cn[corner]] + offset]]
    near = np.einsum("ij,ij->i", nf[cf[corner]], nf[other]) >= np.cos(np.radians(crease))
    acc = np.zeros((cn.size, 3))
    np.add.at(acc, corner[near], af[other[near], None] * nf[other[near]])
    acc /= np.maximum(np.linalg.norm(acc, axis=1), 1e-300)[:, None]
    out, start = {}, 0
    for k in kinds:
        f = faces[k]
        out[k] = acc[start : start + f.size].reshape(*f.shape, 3)
        start += f.size
    return out


def smoothed(x: NDArray, corner_n: NDArray, n: NDArray) -> NDArray[np.float64]:
    """Phong-smoothed points at shape-function values ``n`` (q, k) on faces ``x`` (F, k, 3).

    The same points on every face: ``(F, q, 3)``, each face's flat point and its
    :func:`bulge`.
    """
    f, q = len(x), len(n)
    flat = np.einsum("qk,fkd->fqd", n, x)
    rep = np.repeat(np.arange(f), q)
    lift = bulge(x[rep], corner_n[rep], np.tile(n, (f, 1)))
    return flat + lift.reshape(f, q, 3)


def bulge(x: NDArray, corner: NDArray, n: NDArray) -> NDArray[np.float64]:
    """The smoothed surface's offset from the flat facet, one point per facet.

    ``x`` (P, k, 3) the facets' vertices, ``corner`` (P, k, 3) their corner normals,
    ``n`` (P, k) each point's shape-function values on its facet; returns (P, 3).
    """
    flat = np.einsum("pk,pkd->pd", n, x)
    lift = np.einsum("pkd,pkd->pk", flat[:, None, :] - x, corner)
    return -ALPHA * np.einsum("pk,pk,pkd->pd", n, lift, corner)
