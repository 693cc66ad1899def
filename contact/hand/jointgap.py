"""Two layers of free flesh in every gap between bones: no node is tied to two bones.

A flexion turns one bone past the other. A free node of the flesh whose tetrahedra reach the
nodes of both bones (a *bridging* node, typically one node across the 1 mm gap of a joint)
must stay on the positive side of every face its tetrahedra share with either bone: at a
deep flexion those half-spaces no longer meet, and no mapping or relaxation of the free
nodes can keep all its tetrahedra positive. :func:`split_joint_gaps` bisects the edges from
every bridging node to the nodes of all its bones but one (the bone with most of its edges):
the new middle nodes are tied to that bone only, the bridging node to its kept bone only, so
the gap holds two layers of free nodes and each layer follows one bone. The bisection is
conforming (every tetrahedron on a split edge splits in two, of half its volume, same
orientation) and keeps the skin surface unchanged.

A bridging node left afterwards sits in a tetrahedron with nodes of two bones that are not
the two bones of a joint (such tetrahedra across a joint are dropped by
:func:`contact.hand.flesh.open_joints`); :func:`bridging_nodes` lists them.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

import fem

__all__ = ["bridging_nodes", "gap_edges", "split_joint_gaps"]

#: The six edges of a tetrahedron (local node pairs).
_EDGES = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])


def _free_fixed_edges(tets: NDArray[np.int64], bone_id: NDArray[np.int64]) -> NDArray[np.int64]:
    """Unique (free node, fixed node) edges of the tetrahedra, shape (E, 2)."""
    e = tets[:, _EDGES].reshape(-1, 2)
    e = np.concatenate([e, e[:, ::-1]])
    e = e[(bone_id[e[:, 0]] < 0) & (bone_id[e[:, 1]] >= 0)]
    return np.unique(e, axis=0)


def bridging_nodes(tets: NDArray[np.int64], bone_id: NDArray[np.int64]) -> NDArray[np.int64]:
    """Free nodes joined by an edge to the nodes of two bones or more.

    Parameters
    ----------
    tets : ndarray of int, shape (M, 4)
    bone_id : ndarray of int, shape (N,)
        Bone of every node, -1 for free ones.

    Returns
    -------
    ndarray of int64
        The nodes, sorted.
    """
    e = _free_fixed_edges(np.asarray(tets), np.asarray(bone_id))
    pairs = np.unique(np.stack([e[:, 0], bone_id[e[:, 1]]], axis=1), axis=0)
    nodes, count = np.unique(pairs[:, 0], return_counts=True)
    return nodes[count > 1]


def gap_edges(tets: NDArray[np.int64], bone_id: NDArray[np.int64]) -> NDArray[np.int64]:
    """The edges :func:`split_joint_gaps` bisects, shape (E, 2): (bridging node, fixed node).

    For each bridging node, its edges to the nodes of every bone but the one it has most
    edges to (ties: the lower bone id), but for the edges of a tetrahedron that itself
    holds nodes of two bones.
    """
    tets, bone_id = np.asarray(tets), np.asarray(bone_id)
    e = _free_fixed_edges(tets, bone_id)
    nb = int(bone_id.max()) + 1
    key = e[:, 0] * nb + bone_id[e[:, 1]]
    ukey, count = np.unique(key, return_counts=True)
    node, bone = ukey // nb, ukey % nb
    # per node, the bone with the most edges (np.unique sorts by node, then bone)
    order = np.lexsort((bone, -count, node))
    first = np.ones(len(order), dtype=bool)
    first[1:] = node[order][1:] != node[order][:-1]
    kept = np.full(int(e[:, 0].max(initial=-1)) + 1, -1, dtype=np.int64)
    kept[node[order][first]] = bone[order][first]
    several = np.bincount(node, minlength=len(kept)) > 1
    split = several[e[:, 0]] & (bone_id[e[:, 1]] != kept[e[:, 0]])
    # an edge of a tetrahedron with the nodes of two bones stays: its middle node would
    # bridge them again (so a second split changes nothing)
    return e[split & ~_in_spanning(tets, bone_id, e)]


def _in_spanning(
    tets: NDArray[np.int64], bone_id: NDArray[np.int64], edges: NDArray[np.int64]
) -> NDArray[np.bool_]:
    """Which ``edges`` belong to a tetrahedron with fixed nodes of two bones or more."""
    b = np.where(bone_id[tets] >= 0, bone_id[tets], -1)
    lo = np.where(b >= 0, b, np.iinfo(np.int64).max).min(axis=1)
    spanning = tets[b.max(axis=1) > lo]
    if len(spanning) == 0:
        return np.zeros(len(edges), dtype=bool)
    se = spanning[:, _EDGES].reshape(-1, 2)
    n = int(max(tets.max(), edges.max(initial=0))) + 1
    key = np.unique(np.concatenate([se[:, 0] * n + se[:, 1], se[:, 1] * n + se[:, 0]]))
    return np.isin(edges[:, 0] * n + edges[:, 1], key)


def _bisect(
    points: NDArray[np.float64], tets: NDArray[np.int64], edges: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.int64]]:
    """Bisect ``edges`` one after the other (conforming): points, tets, parent of each tet.

    Every tetrahedron holding an edge ``(p, a)`` becomes two: one with ``a`` replaced by
    the edge's middle node, one with ``p`` replaced by it.
    """
    n, m = len(points), len(tets)
    cap = m + 8 * len(edges) + 16
    t = np.empty((cap, 4), dtype=np.int64)
    t[:m] = tets
    parent = np.empty(cap, dtype=np.int64)
    parent[:m] = np.arange(m)
    new_pts = np.empty((len(edges), 3))
    star: dict[int, set[int]] = {}
    touched = np.flatnonzero(np.isin(tets, edges).any(axis=1))
    for c in touched.tolist():
        for v in t[c].tolist():
            star.setdefault(v, set()).add(c)
    for k, (p, a) in enumerate(edges.tolist()):
        mid = n + k
        new_pts[k] = 0.5 * (points[p] + points[a])
        cells = star.get(p, set()) & star.get(a, set())
        star[mid] = set()
        for c in sorted(cells):
            if m == len(t):
                t = np.concatenate([t, np.empty_like(t)])
                parent = np.concatenate([parent, np.empty_like(parent)])
            old = t[c].copy()
            t[m] = np.where(old == p, mid, old)
            parent[m] = parent[c]
            t[c] = np.where(old == a, mid, old)
            star[a].discard(c)
            star[mid].update((c, m))
            for v in t[m].tolist():
                if v != mid:
                    star.setdefault(v, set()).add(m)
            star[p].discard(m)
            m += 1
    return np.vstack([points, new_pts]), t[:m], parent[:m]


def split_joint_gaps(
    mesh: fem.Mesh, bone_id: NDArray[np.int64], cell_bone: NDArray[np.int64]
) -> tuple[fem.Mesh, NDArray[np.int64], NDArray[np.int64]]:
    """Bisect the edges :func:`gap_edges` names, so no free node is tied to two bones.

    Parameters
    ----------
    mesh : fem.Mesh
        The flesh (tetrahedra; regions kept by the halves of a split tetrahedron).
    bone_id : ndarray of int, shape (N,)
        Bone of every node, -1 for free ones.
    cell_bone : ndarray of int, shape (M,)
        Nearest bone of every cell (kept by the halves).

    Returns
    -------
    mesh, bone_id, cell_bone
        The refined flesh (the new nodes appended, free), or the inputs unchanged when no
        node bridges two bones.
    """
    tets = mesh.cells["tetra"]
    bone_id = np.asarray(bone_id, dtype=np.int64)
    edges = gap_edges(tets, bone_id)
    if len(edges) == 0:
        return mesh, bone_id, cell_bone
    points, cells, parent = _bisect(mesh.points, tets, edges)
    out = fem.Mesh(points, {"tetra": cells}, {"tetra": mesh.regions["tetra"][parent]})
    bone_id = np.concatenate([bone_id, np.full(len(edges), -1, dtype=np.int64)])
    return out, bone_id, np.asarray(cell_bone)[parent]
