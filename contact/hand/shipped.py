"""The hand as shipped: skeleton, skin, bones and the flesh tetrahedra, at three resolutions.

The files live in ``meshes/hand/`` (rebuilt by ``python -m meshes.build``)::

    rig.toml                 skeleton, bone shapes, skin primitives (the source of it all)
    skin_<res>.vtp           the skin surface the flesh was meshed from
    bones_<res>.vtp          every bone surface, cell data "bone_id" (index in the rig)
    flesh_<res>.vtu          tetrahedra; point data "bone_id" (-1: free flesh), cell data
                             "region" (hand part) and "bone" (nearest bone)

with ``<res>`` ``coarse`` or ``fine``. fTetWild is not deterministic, so everything that
needs a hand reads these files through :func:`load_hand`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

import fem
from fem import MeshError

from ..geometry.surfaces import poly_from_arrays, surface_arrays
from .flesh import open_joints
from .skeleton import Skeleton, load_skeleton

if TYPE_CHECKING:
    import pyvista

__all__ = ["HAND_DIR", "RESOLUTIONS", "Hand", "hand_files", "load_hand"]

#: Where the shipped hand lives.
HAND_DIR = Path(__file__).resolve().parents[2] / "meshes" / "hand"
#: The shipped resolutions.
RESOLUTIONS = ("coarse", "fine", "fingertips")


def hand_files(resolution: str, directory: str | os.PathLike | None = None) -> dict[str, Path]:
    """Paths of the rig and of the skin, bones and flesh files of one resolution."""
    if resolution not in RESOLUTIONS:
        raise ValueError(
            f"unknown hand resolution {resolution!r}; expected one of {', '.join(RESOLUTIONS)}"
        )
    d = Path(directory) if directory is not None else HAND_DIR
    return {
        "rig": d / "rig.toml",
        "skin": d / f"skin_{resolution}.vtp",
        "bones": d / f"bones_{resolution}.vtp",
        "flesh": d / f"flesh_{resolution}.vtu",
    }


@dataclass(frozen=True)
class Hand:
    """A meshed hand at rest.

    Attributes
    ----------
    skeleton : Skeleton
        Joints, limits, forward kinematics; ``skeleton.bone_names[i]`` is bone id ``i``.
    flesh : fem.Mesh
        Tetrahedra between skin and bones; regions are hand parts
        (``skeleton.spec.groups``: palm 0, thumb 1, index 2, middle 3, ring 4, little 5).
    bone_id : ndarray of int64, shape (n_points,)
        The bone each flesh node is fixed to, -1 for free nodes.
    cell_bone : ndarray of int64, shape (n_cells,)
        The bone nearest each cell (for the skin mapping).
    skin : pyvista.PolyData
        The skin surface the flesh was meshed from.
    bones : dict of str to pyvista.PolyData
        Bone surfaces by name, in bone-id order.
    resolution : str
    """

    skeleton: Skeleton
    flesh: fem.Mesh
    bone_id: NDArray[np.int64]
    cell_bone: NDArray[np.int64]
    skin: pyvista.PolyData
    bones: dict[str, pyvista.PolyData]
    resolution: str

    @cached_property
    def derived(self) -> dict:
        """Work derived from the hand and kept as long as it lives (its poser, fingertip nodes).

        Filled by :func:`contact.pose_hand` and :mod:`contact.hand.autoflex`: a grasp run poses
        and searches the same hand frame after frame.
        """
        return {}

    @cached_property
    def prescribed_nodes(self) -> NDArray[np.int64]:
        """Indices of the flesh nodes fixed to a bone (they move rigidly with it)."""
        return np.flatnonzero(self.bone_id >= 0)

    def bone_nodes(self, bone: str) -> NDArray[np.int64]:
        """Indices of the flesh nodes fixed to one bone."""
        names = self.skeleton.bone_names
        if bone not in names:
            raise KeyError(f"unknown bone {bone!r}; bones: {', '.join(names)}")
        return np.flatnonzero(self.bone_id == names.index(bone))

    @cached_property
    def skin_faces(self) -> fem.BoundaryFaces:
        """The flesh's boundary faces on the skin: the only ones that can touch a ball.

        The flesh's boundary also holds the bone holes and the joint cavities. A face is on
        the skin when its centre and its three nodes lie within half the rig's smallest
        flesh thickness of the skin surface the flesh was meshed from (bone holes lie a
        whole thickness away at least; a joint cavity's face near the skin has a node
        deeper in); the faces found must close on themselves.

        Raises
        ------
        fem.MeshError
            If they do not (flesh and skin files that do not belong together).
        """
        from ..geometry.surfacequery import TriangleSurface
        from ..geometry.surfaces import surface_arrays

        bnd = self.flesh.boundary
        tri = bnd.faces.get("triangle", np.zeros((0, 3), np.int64))
        skin = TriangleSurface(*surface_arrays(self.skin), name="skin")
        near = 0.5 * self.skeleton.spec.min_flesh
        d = skin.closest(self.flesh.points[tri].mean(axis=1)).distance
        nodes = np.unique(tri)
        dn = np.full(self.flesh.n_points, np.inf)
        dn[nodes] = skin.closest(self.flesh.points[nodes]).distance
        on = (d < near) & (dn[tri].max(axis=1) < near)
        found = TriangleSurface(self.flesh.points, tri[on], name="skin faces of the flesh")
        if not found.is_closed:
            raise MeshError(
                f"hand {self.resolution}: the flesh's faces on the skin do not close "
                f"({int(on.sum())} of {len(tri)} boundary faces): flesh and skin files differ"
            )
        return bnd.subset(
            {k: (on if k == "triangle" else np.zeros(len(f), bool)) for k, f in bnd.faces.items()}
        )

    @property
    def part_names(self) -> tuple[str, ...]:
        """Region names: region ``i`` of the flesh is part ``part_names[i]``."""
        return self.skeleton.spec.groups


def _read_poly(path: Path) -> pyvista.PolyData:
    import pyvista as pv

    if not path.is_file():
        raise MeshError(f"hand file {path} does not exist (rebuild: python -m meshes.build)")
    try:
        return pv.read(path)
    except Exception as exc:
        raise MeshError(f"cannot read {path}: {type(exc).__name__}: {exc}") from None


def load_hand(resolution: str = "coarse", directory: str | os.PathLike | None = None) -> Hand:
    """Read the shipped hand of one resolution.

    Parameters
    ----------
    resolution : {"coarse", "fine", "fingertips"}
    directory : path-like, optional
        Folder holding the files (default ``meshes/hand`` of this repository).

    Returns
    -------
    Hand

    Raises
    ------
    fem.MeshError
        Naming the file: missing, unreadable, malformed, or bone ids that do not match the
        rig (out of range, or a bone without a node).
    contact.RigError
        On a bad rig file.
    """
    files = hand_files(resolution, directory)
    skeleton = load_skeleton(files["rig"])
    names = skeleton.bone_names
    mesh, point_data, cell_data = fem.read_mesh_data(files["flesh"])
    where = files["flesh"]
    if "bone_id" not in point_data or "bone" not in cell_data:
        raise MeshError(f"{where}: point data 'bone_id' and cell data 'bone' are required")
    bone_id = np.asarray(point_data["bone_id"]).astype(np.int64).ravel()
    cell_bone = np.asarray(cell_data["bone"]["tetra"]).astype(np.int64).ravel()
    if bone_id.min() < -1 or bone_id.max() >= len(names):
        raise MeshError(f"{where}: bone_id must lie in -1..{len(names) - 1}")
    missing = sorted(set(range(len(names))) - set(bone_id.tolist()))
    if missing:
        raise MeshError(f"{where}: bone {names[missing[0]]} has no prescribed node")
    if mesh.region_ids.max() >= len(skeleton.spec.groups):
        raise MeshError(f"{where}: a region id is not a hand part of the rig")
    mesh, bone_id, cell_bone = open_joints(mesh, bone_id, cell_bone)  # older files
    skin = _read_poly(files["skin"])
    all_bones = _read_poly(files["bones"])
    if "bone_id" not in all_bones.cell_data:
        raise MeshError(f"{files['bones']}: cell data 'bone_id' is required")
    ids = np.asarray(all_bones.cell_data["bone_id"])
    pts, tri = surface_arrays(all_bones)
    bones = {}
    for i, name in enumerate(names):
        t = tri[ids == i]
        if len(t) == 0:
            raise MeshError(f"{files['bones']}: no surface for bone {name}")
        used, t = np.unique(t, return_inverse=True)
        bones[name] = poly_from_arrays(pts[used], t.reshape(-1, 3))
    return Hand(skeleton, mesh, bone_id, cell_bone, skin, bones, resolution)
