"""Geometric checks of a hand: bones inside the skin, flesh thick enough, bones apart.

Distances are signed distances from bone nodes to the other surface's triangles
(``vtkImplicitPolyDataDistance`` through pyvista's ``compute_implicit_distance``): negative
inside an outward oriented closed surface.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from fem import MeshError

from .skeleton import Skeleton

if TYPE_CHECKING:
    import pyvista

__all__ = ["bone_gaps", "check_hand_geometry", "finger_widths", "flesh_thickness"]


def flesh_thickness(
    skin: pyvista.PolyData, bones: Mapping[str, pyvista.PolyData]
) -> dict[str, float]:
    """Smallest distance (m) from each bone's nodes to the skin; negative if one is outside.

    Parameters
    ----------
    skin : pyvista.PolyData
        Closed, outward skin.
    bones : mapping of str to pyvista.PolyData
        Bone surfaces by name.

    Returns
    -------
    dict of str to float
        By bone name: minus the largest signed distance of its nodes to the skin.
    """
    out = {}
    for name, poly in bones.items():
        d = poly.compute_implicit_distance(skin)["implicit_distance"]
        out[name] = float(-np.max(d))
    return out


def bone_gaps(
    bones: Mapping[str, pyvista.PolyData], within: float = 0.005
) -> dict[tuple[str, str], float]:
    """Smallest distance (m) between the nodes of one bone and the surface of another.

    Parameters
    ----------
    bones : mapping of str to pyvista.PolyData
    within : float
        Only pairs whose bounding boxes come closer than this are measured.

    Returns
    -------
    dict of (str, str) to float
        Distances of the measured pairs (both directions, the smaller kept); negative when
        a node of one bone lies inside another.
    """
    names = list(bones)
    box = np.array([bones[n].bounds for n in names]).reshape(-1, 3, 2)
    out = {}
    for i, a in enumerate(names):
        for j in range(i + 1, len(names)):
            b = names[j]
            apart = (box[i, :, 0] - within > box[j, :, 1]) | (box[j, :, 0] - within > box[i, :, 1])
            if apart.any():
                continue
            dab = bones[a].compute_implicit_distance(bones[b])["implicit_distance"].min()
            dba = bones[b].compute_implicit_distance(bones[a])["implicit_distance"].min()
            out[(a, b)] = float(min(dab, dba))
    return out


def check_hand_geometry(
    skin: pyvista.PolyData,
    bones: Mapping[str, pyvista.PolyData],
    min_flesh: float,
    min_gap: float,
) -> None:
    """Raise unless every bone is inside the skin under ``min_flesh`` and bones are apart.

    Raises
    ------
    fem.MeshError
        Naming the bone (or pair of bones) at fault and the distance found.
    """
    thick = flesh_thickness(skin, bones)
    name = min(thick, key=thick.get)
    if thick[name] < min_flesh:
        where = "outside the skin" if thick[name] < 0 else "too close under the skin"
        raise MeshError(
            f"bone {name} is {where}: flesh thickness {thick[name] * 1e3:.2f} mm, the rig "
            f"asks for at least {min_flesh * 1e3:.2f} mm"
        )
    gaps = bone_gaps(bones, within=2 * min_gap)
    if gaps:
        pair = min(gaps, key=gaps.get)
        if gaps[pair] < min_gap - 1e-9:
            raise MeshError(
                f"bones {pair[0]} and {pair[1]} are {gaps[pair] * 1e3:.2f} mm apart, the rig "
                f"asks for at least {min_gap * 1e3:.2f} mm"
            )


def finger_widths(skeleton: Skeleton, skin: pyvista.PolyData, at: float = 0.6) -> dict[str, float]:
    """Width (m) of each finger across its proximal phalanx, at rest.

    The skin is cut by the plane normal to the bone ``<part>_proximal`` at ``at`` of its
    length; the width is the extent, along the bone's x axis, of the piece of the cut
    around the axis, within 12 mm of it.

    Returns
    -------
    dict of str to float
        By the part name of the proximal phalanx (``"index"``, ...).
    """
    out = {}
    for part in skeleton.spec.groups:
        bone = skeleton.bones.get(f"{part}_proximal")
        if bone is None:
            continue
        c = bone.start + at * bone.length * bone.frame[:, 1]
        cut = skin.slice(normal=bone.frame[:, 1], origin=c).connectivity("closest", c)
        local = (np.asarray(cut.points) - c) @ bone.frame
        near = np.linalg.norm(local, axis=1) < 0.012
        if near.any():
            out[part] = float(np.ptp(local[near, 0]))
    return out
