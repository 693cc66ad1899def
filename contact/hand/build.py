"""Building the hand meshes from the rig: skin, bones, flesh, checks, files.

:func:`build_hand` runs the whole chain for one :class:`Resolution`; :func:`write_hand`
writes the files :func:`contact.hand.shipped.load_hand` reads.
``python -m meshes.build`` calls both.
"""

from __future__ import annotations

import logging
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

import fem

from ..geometry.surfaces import check_closed_surface, enclosed_volume, surface_arrays
from .bones import bone_surfaces
from .checks import bone_gaps, check_hand_geometry, flesh_thickness
from .flesh import (
    cell_bones,
    joint_pairs,
    label_bone_nodes,
    open_joints,
    tetrahedralize_flesh,
)
from .jointgap import split_joint_gaps
from .metaballs import skin_surface
from .quality import quality_summary
from .shipped import Hand, hand_files
from .skeleton import Skeleton

__all__ = [
    "COARSE", "FINE", "FINGERTIPS", "TIP_GROWTH", "TIP_REACH", "Resolution", "build_hand",
    "fingertip_sizing", "hand_report", "write_hand",
]  # fmt: skip

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Resolution:
    """How finely to mesh the hand.

    Attributes
    ----------
    name : str
        ``"coarse"`` or ``"fine"`` (the file suffix).
    skin_grid : float
        Spacing of the metaball grid (m).
    skin_reduction : float
        Fraction of the skin's triangles removed by quadric decimation (volume kept), 0 for
        none.
    bone_edge : float
        Edge length of the swept bone surfaces (m).
    tet_edge : float
        Target tetrahedron edge length (m).
    tetwild : dict
        Extra ``pytetwild.tetrahedralize`` options (``epsilon`` relative to the bounding box
        diagonal, ``num_opt_iter``, ``stop_energy``, ``coarsen``); empty:
        :func:`fem.tetrahedralize`.
    tip_edge : float
        Target edge length (m) at the fingertips, growing to ``tet_edge`` away from them
        (:func:`fingertip_sizing`); 0: ``tet_edge`` everywhere.
    """

    name: str
    skin_grid: float
    skin_reduction: float
    bone_edge: float
    tet_edge: float
    tetwild: dict[str, Any] = field(default_factory=dict)
    tip_edge: float = 0.0

    @property
    def epsilon(self) -> float:
        """FTetWild's envelope, relative to the bounding box diagonal."""
        return float(self.tetwild.get("epsilon", 1e-3))


#: A few thousand nodes, for tests and the quick example (under a minute of fTetWild).
COARSE = Resolution(
    "coarse", 0.0015, 0.95, 0.004, 0.007, {"epsilon": 2e-3, "num_opt_iter": 10, "stop_energy": 20.0}
)
#: The finer hand: fTetWild's envelope (1e-3 of the diagonal), fewer optimisation passes.
FINE = Resolution(
    "fine", 0.001, 0.85, 0.002, 0.0035, {"epsilon": 1e-3, "num_opt_iter": 20, "stop_energy": 15.0}
)
#: The coarse hand's flesh with fingertips of 2 mm edges, where a press's patch is a few
#: millimetres across (weighted gaps resolve it: ``benchmarks/results/flexion.md``): the fine
#: skin, meshed under :func:`fingertip_sizing` and coarsened to it.
FINGERTIPS = Resolution(
    "fingertips", 0.001, 0.85, 0.004, 0.007,
    {"epsilon": 1e-3, "num_opt_iter": 10, "stop_energy": 20.0, "coarsen": True}, tip_edge=0.002,
)  # fmt: skip
#: Where the fingertips' edge holds: within this distance (m) of a distal bone; beyond it
#: the edge grows by :data:`TIP_GROWTH` per unit of distance, up to the hand's.
TIP_REACH = 0.010
TIP_GROWTH = 0.5


def build_hand(skeleton: Skeleton, res: Resolution) -> tuple[Hand, dict[str, float]]:
    """Skin, bones and flesh of the rig at rest, checked.

    Parameters
    ----------
    skeleton : Skeleton
    res : Resolution

    Returns
    -------
    hand : Hand
    timings : dict of str to float
        Seconds spent on ``skin``, ``bones``, ``tetrahedralize``, ``labels``.

    Raises
    ------
    fem.MeshError
        On a bad skin (open, several pieces, self-intersecting), a bone outside the skin or
        under too thin a flesh, bones too close, or holes the mesher lost.
    """
    spec = skeleton.spec
    timings = {}
    t0 = time.perf_counter()
    skin = skin_surface(skeleton, resolution=res.skin_grid)
    if res.skin_reduction > 0:
        skin = skin.decimate(res.skin_reduction, volume_preservation=True)
        pts, tri = surface_arrays(skin)
        if enclosed_volume(pts, tri) < 0:
            skin.flip_faces(inplace=True)
        check_closed_surface(skin, f"decimated skin ({res.name})")
    timings["skin"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    bones = bone_surfaces(skeleton, edge=res.bone_edge)
    for name, poly in bones.items():
        check_closed_surface(poly, f"bone {name}")
    check_hand_geometry(skin, bones, spec.min_flesh, spec.gap)
    timings["bones"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    sizing = fingertip_sizing(skin, bones, res.tip_edge, res.tet_edge) if res.tip_edge else None
    mesh = tetrahedralize_flesh(skin, bones, res.tet_edge, sizing_field=sizing, **res.tetwild)
    timings["tetrahedralize"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    diag = float(np.linalg.norm(np.ptp(mesh.points, axis=0)))
    bone_id = label_bone_nodes(mesh, bones, tolerance=2.0 * res.epsilon * diag)
    cell_bone = cell_bones(mesh, skeleton)
    parts = np.array([spec.groups.index(b.part) for b in skeleton.bones.values()])
    flesh = fem.Mesh(mesh.points, mesh.cells, {"tetra": parts[cell_bone]})
    flesh, bone_id, cell_bone = open_joints(flesh, bone_id, cell_bone, joint_pairs(skeleton))
    flesh, bone_id, cell_bone = split_joint_gaps(flesh, bone_id, cell_bone)
    timings["labels"] = time.perf_counter() - t0
    log.info("hand %s: %s in %s", res.name, flesh, {k: round(v, 1) for k, v in timings.items()})
    return Hand(skeleton, flesh, bone_id, cell_bone, skin, bones, res.name), timings


def fingertip_sizing(
    skin: Any, bones: dict[str, Any], tip: float, far: float, spacing: float = 0.004
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The sizing field of fTetWild: finest at the fingertips.

    ``tip`` within :data:`TIP_REACH` of a distal bone, growing by :data:`TIP_GROWTH` per
    metre beyond, up to ``far``. On a background grid of tetrahedra of ``spacing`` over
    the skin's bounds; the ``sizing_field`` of :func:`fem.tetrahedralize` (points,
    tetrahedra, edge lengths).
    """
    from scipy.spatial import cKDTree

    lo = np.asarray(skin.bounds[::2]) - 2 * spacing
    hi = np.asarray(skin.bounds[1::2]) + 2 * spacing
    n = np.maximum(np.ceil((hi - lo) / spacing).astype(int), 1)
    grid = fem.box_mesh(tuple(hi - lo), tuple(n), origin=tuple(lo), element="tetra")
    tips = np.concatenate([np.asarray(b.points) for k, b in bones.items() if k.endswith("_distal")])
    d, _ = cKDTree(tips).query(grid.points)
    size = np.clip(tip + TIP_GROWTH * (d - TIP_REACH), tip, far)
    return grid.points, grid.cells["tetra"], size


def write_hand(hand: Hand, directory: str | os.PathLike | None = None) -> dict[str, Path]:
    """Write the skin, bones and flesh files of a hand (the rig file is not touched)."""
    import pyvista as pv

    files = hand_files(hand.resolution, directory)
    pts, tri = surface_arrays(hand.skin)
    pv.PolyData.from_regular_faces(pts, tri).save(files["skin"])
    parts = []
    for i, poly in enumerate(hand.bones.values()):
        p = pv.PolyData.from_regular_faces(*surface_arrays(poly))
        p.cell_data["bone_id"] = np.full(p.n_cells, i, dtype=np.int64)
        parts.append(p)
    pv.merge(parts, merge_points=False).save(files["bones"])
    fem.write_mesh(
        files["flesh"],
        hand.flesh,
        point_data={"bone_id": hand.bone_id},
        cell_data={"bone": {"tetra": hand.cell_bone}},
    )
    return files


def hand_report(hand: Hand) -> dict[str, Any]:
    """Key numbers of a hand for ``quality.json``: sizes, flesh, gaps, mesh quality."""
    pts, tri = surface_arrays(hand.skin)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    thick = flesh_thickness(hand.skin, hand.bones)
    gaps = bone_gaps(hand.bones)
    counts = np.bincount(hand.bone_id[hand.bone_id >= 0], minlength=len(hand.bones))
    return {
        "skin": {
            "points": len(pts),
            "triangles": len(tri),
            "volume_cm3": round(enclosed_volume(pts, tri) * 1e6, 1),
            "bounds_m": [[round(float(a), 4), round(float(b), 4)] for a, b in zip(lo, hi)],
        },
        "bones": {
            "count": len(hand.bones),
            "triangles": int(sum(p.n_cells for p in hand.bones.values())),
            "min_flesh_mm": round(min(thick.values()) * 1e3, 2),
            "min_flesh_bone": min(thick, key=thick.get),
            "min_gap_mm": round(min(gaps.values()) * 1e3, 3),
            "prescribed_nodes": {n: int(c) for n, c in zip(hand.bones, counts)},
        },
        "flesh": quality_summary(hand.flesh),
    }
