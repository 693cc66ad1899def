"""Helpers shared by the tests: randomly distorted meshes and a mixed wedge-brick box."""

from __future__ import annotations

import numpy as np

import fem


def distort(mesh: fem.Mesh, amount: float, seed: int = 0, boundary: bool = True) -> fem.Mesh:
    """Move nodes randomly by up to ``amount`` times the smallest grid spacing."""
    rng = np.random.default_rng(seed)
    pts = mesh.points.copy()
    span = np.ptp(pts, axis=0)
    h = span.min() / max(4, round(len(pts) ** (1 / 3)))
    move = rng.uniform(-amount * h, amount * h, pts.shape)
    if not boundary:
        move[mesh.boundary.nodes] = 0.0
    return fem.Mesh(pts + move, mesh.cells, mesh.regions)


def mixed_mesh() -> fem.Mesh:
    """A 3x2x2 brick box: its left third split into wedges, the rest hexahedra; conforming."""
    box = fem.box_mesh((3.0, 2.0, 2.0), (3, 2, 2))
    hexes = box.cells["hexahedron"]
    left = box.points[hexes].mean(axis=1)[:, 0] < 1.0
    wedges = np.concatenate(
        [hexes[left][:, [0, 1, 2, 4, 5, 6]], hexes[left][:, [0, 2, 3, 4, 6, 7]]]
    )
    return fem.Mesh(
        box.points,
        {"hexahedron": hexes[~left], "wedge": wedges},
        {"hexahedron": np.zeros((~left).sum(), int), "wedge": np.ones(len(wedges), int)},
    )
