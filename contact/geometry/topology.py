"""What a triangle surface's connectivity alone determines, kept per connectivity.

A posed hand's skin is a new :class:`~contact.geometry.surfacequery.TriangleSurface` every
frame on the same triangles: whether it is closed, the closest-point hierarchy's shape, the
triangles across each edge and the corners around each node are worked out once, in a
record shared by every surface of that connectivity (:func:`topology_record`).
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .triangles import unit

__all__ = ["edge_twins", "node_corners", "pseudo_normals", "topology_record"]

#: Topology of recent surfaces by their connectivity: closed or not, edge neighbours, the
#: corners around each node. A posed hand's skin is a new surface every frame, on the same
#: triangles; what depends on the triangles alone is worked out once. The posing makes a
#: surface of every bone each frame too: the record keeps up to ``_TOPOLOGY_KEPT`` surfaces
#: and ``_TOPOLOGY_TRIANGLES`` triangles in all (about 100 bytes each), the least recently
#: used dropped first (so that the many small bones do not push out the skin and the ball).
_TOPOLOGY: OrderedDict[tuple[int, bytes], dict[str, Any]] = OrderedDict()
_TOPOLOGY_KEPT = 256
_TOPOLOGY_TRIANGLES = 500_000


def topology_record(n_points: int, triangles: NDArray[np.int64]) -> dict[str, Any]:
    """The shared topology record of a connectivity (made empty if new)."""
    key = (n_points, triangles.tobytes())
    entry = _TOPOLOGY.pop(key, None)
    if entry is None:
        entry = {}
    _TOPOLOGY[key] = entry
    held = sum(len(k[1]) for k in _TOPOLOGY) // 24  # triangles (3 int64 each)
    while len(_TOPOLOGY) > 1 and (len(_TOPOLOGY) > _TOPOLOGY_KEPT or held > _TOPOLOGY_TRIANGLES):
        old, _ = _TOPOLOGY.popitem(last=False)
        held -= len(old[1]) // 24
    return entry


def edge_twins(triangles: NDArray[np.int64], n_points: int) -> NDArray[np.int64]:
    """``twins[f, i]``: the triangle across the edge of ``f`` opposite its node ``i``.

    A triangle is its own twin across an open edge. Read-only.
    """
    tri = triangles
    n = np.int64(n_points)
    a = tri[:, [1, 2, 0]].ravel()  # edge opposite node i runs from i+1 to i+2
    b = tri[:, [2, 0, 1]].ravel()
    key = a * n + b
    order = np.argsort(key, kind="stable")
    srt = key[order]
    rev = b * n + a
    pos = np.clip(np.searchsorted(srt, rev), 0, len(srt) - 1)
    found = srt[pos] == rev
    twin = np.where(found, order[pos] // 3, np.repeat(np.arange(len(tri)), 3))
    twin = twin.reshape(-1, 3)
    twin.setflags(write=False)
    return twin


def node_corners(
    triangles: NDArray[np.int64], n_points: int
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Corners ``3 f + i`` sorted by node, and where each node's run starts (read-only)."""
    flat = triangles.ravel()
    order = np.argsort(flat, kind="stable")
    start = np.searchsorted(flat[order], np.arange(n_points + 1))
    order.setflags(write=False)
    start.setflags(write=False)
    return order, start


def pseudo_normals(
    points: NDArray[np.float64],
    triangles: NDArray[np.int64],
    face_normals: NDArray[np.float64],
    corners: tuple[NDArray[np.int64], NDArray[np.int64]],
    nodes: NDArray[np.int64],
) -> NDArray[np.float64]:
    """Angle-weighted pseudo-normals ``(k, 3)`` of ``nodes`` (Baerentzen and Aanaes 2005).

    Summed over the corners around each node (``corners`` from :func:`node_corners`), not
    the whole surface; zero for a node no triangle uses.
    """
    order, start = corners
    counts = start[nodes + 1] - start[nodes]
    owner = np.repeat(np.arange(nodes.size), counts)
    first = np.repeat(start[nodes] - np.cumsum(counts) + counts, counts)
    corner = order[first + np.arange(counts.sum())]
    f, i = corner // 3, corner % 3
    x = points[triangles[f]]
    k = np.arange(f.size)
    u = unit(x[k, (i + 1) % 3] - x[k, i])
    v = unit(x[k, (i + 2) % 3] - x[k, i])
    angle = np.arctan2(np.linalg.norm(np.cross(u, v), axis=1), np.einsum("ij,ij->i", u, v))
    out = np.zeros((nodes.size, 3))
    np.add.at(out, owner, angle[:, None] * face_normals[f])
    return unit(out)
