"""The flesh of the hand as tetrahedra between the skin and the bones.

The skin (outward) and every bone surface flipped inward are merged into one surface and
filled with pytetwild: fTetWild keeps what the winding number marks inside, so the bones
become holes (see :mod:`fem.meshing`). The holes' nodes are the prescribed nodes: each is
labelled with its bone (``bone_id``, the bone's index in the rig, -1 for free flesh), found
by the connected pieces of the mesh boundary, each piece matched to the nearest bone. Every
cell gets a region, the hand part of its nearest bone axis (the rig's skin groups, in order:
palm 0, thumb 1, index 2, ...), and its nearest bone.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

import fem
from fem import MeshError

from ..geometry.surfaces import surface_arrays
from .skeleton import Skeleton

if TYPE_CHECKING:
    import pyvista

__all__ = [
    "cell_bones",
    "joint_pairs",
    "label_bone_nodes",
    "merged_surface",
    "open_joints",
    "tetrahedralize_flesh",
]

log = logging.getLogger(__name__)


def merged_surface(
    skin: pyvista.PolyData, bones: Mapping[str, pyvista.PolyData]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The skin as it is and every bone flipped inward, as one triangle surface."""
    pts, tri = surface_arrays(skin)
    points, triangles, offset = [pts], [tri], len(pts)
    for poly in bones.values():
        p, t = surface_arrays(poly)
        points.append(p)
        triangles.append(t[:, ::-1] + offset)
        offset += len(p)
    return np.vstack(points), np.vstack(triangles)


def tetrahedralize_flesh(
    skin: pyvista.PolyData,
    bones: Mapping[str, pyvista.PolyData],
    edge_length: float,
    sizing_field: tuple | None = None,
    **tetwild_options: Any,
) -> fem.Mesh:
    """Tetrahedra filling the skin with the bones left out as holes.

    Parameters
    ----------
    skin : pyvista.PolyData
        Closed, outward skin surface.
    bones : mapping of str to pyvista.PolyData
        Closed, outward bone surfaces, inside the skin and apart from each other.
    edge_length : float
        Target tetrahedron edge length (m).
    sizing_field : tuple, optional
        Edge lengths over a background mesh (``(points, tets, values)``, see
        :func:`fem.tetrahedralize`): finer where it asks.
    **tetwild_options
        Passed through :func:`fem.tetrahedralize` to ``pytetwild.tetrahedralize`` (e.g.
        ``epsilon``, ``stop_energy``, ``num_opt_iter``, ``coarsen``).

    Returns
    -------
    fem.Mesh
        Positively oriented tetrahedra, region 0. Not deterministic (fTetWild).
    """
    points, triangles = merged_surface(skin, bones)
    return fem.tetrahedralize(
        (points, triangles), edge_length, sizing_field=sizing_field, **tetwild_options
    ).remove_unused_points()


def _pieces(n_points: int, faces: NDArray[np.int64]) -> NDArray[np.int64]:
    """Piece label of every boundary face (faces joined through shared nodes)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    e = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    g = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n_points, n_points))
    _, labels = connected_components(g, directed=False)
    return labels[faces[:, 0]]


def label_bone_nodes(
    mesh: fem.Mesh, bones: Mapping[str, pyvista.PolyData], tolerance: float
) -> NDArray[np.int64]:
    """The bone of every node on a bone hole, -1 elsewhere.

    Parameters
    ----------
    mesh : fem.Mesh
        The flesh, with one hole per bone.
    bones : mapping of str to pyvista.PolyData
        The bone surfaces, in bone-id order.
    tolerance : float
        Largest distance (m) a hole's node may lie from its bone surface.

    Returns
    -------
    ndarray of int64, shape (n_points,)

    Raises
    ------
    fem.MeshError
        If the boundary does not consist of the skin and one hole per bone, naming the bone.
    """
    import pyvista as pv

    faces = mesh.boundary.faces["triangle"]
    labels = _pieces(mesh.n_points, faces)
    names = list(bones)
    pieces = np.unique(labels)
    if len(pieces) != len(names) + 1:
        raise MeshError(
            f"the flesh boundary has {len(pieces)} pieces, expected the skin and "
            f"{len(names)} bone holes (bones merged or lost by the mesher)"
        )
    nodes = [np.unique(faces[labels == k]) for k in pieces]
    skin_piece = int(np.argmax([len(n) for n in nodes]))
    dist = np.full((len(pieces), len(names)), np.inf)
    for i, n in enumerate(nodes):
        if i == skin_piece:
            continue
        cloud = pv.PolyData(mesh.points[n])
        for j, name in enumerate(names):
            d = cloud.compute_implicit_distance(bones[name])["implicit_distance"]
            dist[i, j] = np.abs(d).max()
    bone_id = np.full(mesh.n_points, -1, dtype=np.int64)
    taken: dict[int, str] = {}
    for i, n in enumerate(nodes):
        if i == skin_piece:
            continue
        j = int(np.argmin(dist[i]))
        if dist[i, j] > tolerance:
            raise MeshError(
                f"a hole of the flesh lies {dist[i, j] * 1e3:.2f} mm from the nearest bone "
                f"({names[j]}), more than the tolerance {tolerance * 1e3:.2f} mm"
            )
        if j in taken:
            raise MeshError(f"bone {names[j]} matches two holes of the flesh")
        taken[j] = names[j]
        bone_id[n] = j
    return bone_id


def cell_bones(mesh: fem.Mesh, skeleton: Skeleton) -> NDArray[np.int64]:
    """Index of the bone whose axis segment is nearest each cell centroid (rest pose)."""
    c = mesh.points[mesh.cells["tetra"]].mean(axis=1)
    a = np.stack([b.start for b in skeleton.bones.values()])
    ab = np.stack([b.end for b in skeleton.bones.values()]) - a
    t = np.clip(np.einsum("cbk,bk->cb", c[:, None] - a, ab) / (ab * ab).sum(1), 0.0, 1.0)
    d = np.linalg.norm(c[:, None] - (a + t[..., None] * ab), axis=2)
    return np.argmin(d, axis=1)


def joint_pairs(skeleton: Skeleton) -> list[tuple[int, int]]:
    """The (parent bone, child bone) ids of every joint of a skeleton (bone-id order)."""
    carried = {b.joint: i for i, b in enumerate(skeleton.bones.values())}
    pairs = []
    for i, b in enumerate(skeleton.bones.values()):
        parent = skeleton.joints[b.joint].parent if b.joint in skeleton.joints else None
        if parent is not None and parent in carried:
            pairs.append((carried[parent], i))
    return pairs


def open_joints(
    mesh: fem.Mesh,
    bone_id: NDArray[np.int64],
    cell_bone: NDArray[np.int64],
    joints: Sequence[tuple[int, int]] | None = None,
) -> tuple[fem.Mesh, NDArray[np.int64], NDArray[np.int64]]:
    """Open the joints: drop the tetrahedra that tie two bones across a joint.

    Always dropped: the tetrahedra whose four nodes are all fixed to bones, two bones or
    more. They fill the gap between two bone ends across a joint: their nodes are all
    prescribed, so they carry no unknown, only a spurious force from one bone to the next,
    and any flexion shears them inside out (the bones turn rigidly about the joint).

    With ``joints`` (see :func:`joint_pairs`): also every tetrahedron with nodes fixed to
    both bones of a joint. Such a tetrahedron spans the 1 mm gap between the two bone ends
    with one or two free nodes; the bones turn past each other and its fixed nodes turn
    its face over (the plane through two nodes of one bone and one of the other flips
    with the flexion), which no position of the free node can undo, and the free nodes
    squeezed between the two bone ends have nowhere to go. Without them the joint is a
    cavity inside the flesh around it (the skin is untouched), as in a real joint, where
    the bone ends slide on cartilage. Nodes left in no cell are removed.
    """
    tets = mesh.cells["tetra"]
    b = bone_id[tets]
    across = (b >= 0).all(axis=1) & (b.min(axis=1) != b.max(axis=1))
    for parent, child in joints or ():
        across |= (b == parent).any(axis=1) & (b == child).any(axis=1)
    if not across.any():
        return mesh, bone_id, cell_bone
    keep = ~across
    used = np.zeros(mesh.n_points, dtype=bool)
    used[tets[keep].ravel()] = True
    new = np.full(mesh.n_points, -1, dtype=np.int64)
    new[used] = np.arange(int(used.sum()))
    cut = fem.Mesh(
        mesh.points[used], {"tetra": new[tets[keep]]}, {"tetra": mesh.regions["tetra"][keep]}
    )
    return cut, bone_id[used], cell_bone[keep]
