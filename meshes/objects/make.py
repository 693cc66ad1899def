"""Write the shipped object surfaces: ``python -m meshes.objects.make``.

``can.stl``: a closed cylinder, radius 26 mm, height 100 mm, axis along z, centred at the
origin, edges about 4 mm (rings staggered by half a step, caps Delaunay-triangulated on
concentric rings). ``cube.stl``: a cube of edge 40 mm centred at the origin, edges 5 mm.
Both in metres, binary STL, triangles facing out; each is checked by
:func:`contact.objects.check_object_surface` before it is written. The output is
deterministic.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from contact.objects import check_object_surface

__all__ = ["OBJECTS_DIR", "can_surface", "cube_surface", "main", "write_stl"]

OBJECTS_DIR = Path(__file__).resolve().parent

Surface = tuple[NDArray[np.float64], NDArray[np.int64]]


def _merge(points: NDArray[np.float64], triangles: NDArray[np.int64]) -> Surface:
    """Coincident points (equal bit for bit) merged."""
    uniq, inverse = np.unique(points, axis=0, return_inverse=True)
    return uniq, inverse.reshape(-1)[triangles]


def cube_surface(edge: float = 0.04, size: float = 0.005) -> Surface:
    """A cube of edge ``edge`` centred at the origin, each face a grid of about ``size``."""
    n = max(1, math.ceil(edge / size - 1e-9))
    g = np.linspace(-edge / 2, edge / 2, n + 1)
    u, v = (a.ravel() for a in np.meshgrid(g, g, indexing="ij"))
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
    c, d = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    quads = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])  # ccw in (u, v)
    pts, tris = [], []
    for axis in range(3):
        for side in (-1.0, 1.0):
            p = np.empty((len(u), 3))
            p[:, axis] = side * edge / 2
            p[:, (axis + 1) % 3], p[:, (axis + 2) % 3] = u, v  # (u, v, axis) right-handed
            t = quads if side > 0 else quads[:, ::-1]
            tris.append(t + sum(len(q) for q in pts))
            pts.append(p)
    return _merge(np.concatenate(pts), np.concatenate(tris))


def _cap(ring: NDArray[np.float64], radius: float, size: float, z: float, up: bool) -> Surface:
    """A disc at height ``z`` bounded by ``ring`` (k, 2), on concentric rings inside."""
    from scipy.spatial import Delaunay

    m = max(1, round(radius / (size * math.sqrt(3) / 2)))
    inner = [np.zeros((1, 2))]
    for k in range(1, m):
        r = radius * k / m
        count = max(6, round(2 * math.pi * r / size))
        phi = 2 * math.pi * (np.arange(count) + 0.5 * (k % 2)) / count
        inner.append(r * np.stack([np.cos(phi), np.sin(phi)], axis=1))
    xy = np.concatenate([ring, *inner])
    tri = Delaunay(xy).simplices.astype(np.int64)
    e1, e2 = xy[tri[:, 1]] - xy[tri[:, 0]], xy[tri[:, 2]] - xy[tri[:, 0]]
    ccw = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] > 0
    tri[ccw != up] = tri[ccw != up][:, ::-1]
    return np.column_stack([xy, np.full(len(xy), z)]), tri


def can_surface(radius: float = 0.026, height: float = 0.10, size: float = 0.004) -> Surface:
    """A closed cylinder about z, centred at the origin, edges about ``size``."""
    n = math.ceil(2 * math.pi * radius / size)
    rows = math.ceil(height / (size * math.sqrt(3) / 2))
    z = np.linspace(-height / 2, height / 2, rows + 1)
    phi = 2 * math.pi * (np.arange(n)[None, :] + 0.5 * (np.arange(rows + 1)[:, None] % 2)) / n
    side = np.stack(
        [radius * np.cos(phi), radius * np.sin(phi), np.broadcast_to(z[:, None], phi.shape)], -1
    ).reshape(-1, 3)
    tris = []
    for r in range(rows):
        lo, hi = r * n + np.arange(n), (r + 1) * n + np.arange(n)
        lo1, hi1 = np.roll(lo, -1), np.roll(hi, -1)
        if r % 2 == 0:  # the upper ring is shifted half a step forward
            tris += [np.stack([lo, lo1, hi], 1), np.stack([lo1, hi1, hi], 1)]
        else:  # the lower ring is
            tris += [np.stack([lo, hi1, hi], 1), np.stack([lo, lo1, hi1], 1)]
    pts, out = [side], [np.concatenate(tris)]
    for ring, zc, up in ((side[:n], -height / 2, False), (side[-n:], height / 2, True)):
        p, t = _cap(ring[:, :2], radius, size, zc, up)
        p[:n] = ring  # bit-equal to the side's ring, so that the merge closes the seam
        out.append(t + sum(len(q) for q in pts))
        pts.append(p)
    return _merge(np.concatenate(pts), np.concatenate(out))


def write_stl(path: Path, surface: Surface) -> None:
    """Write a triangle surface as binary STL (checked first)."""
    import meshio

    points, tris = check_object_surface(*surface, path.name, where="make")
    meshio.write_points_cells(path, points, [("triangle", tris)], file_format="stl", binary=True)


def main(argv: list[str] | None = None) -> None:
    """Write ``can.stl`` and ``cube.stl`` into ``--out`` (this folder by default)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OBJECTS_DIR)
    args = parser.parse_args(argv)
    for name, surface in (("can.stl", can_surface()), ("cube.stl", cube_surface())):
        write_stl(args.out / name, surface)
        x = surface[0][surface[1]]
        edges = np.linalg.norm(x - np.roll(x, 1, axis=1), axis=2)
        print(
            f"{name}: {len(surface[0])} points, {len(surface[1])} triangles, edges "
            f"{edges.min() * 1e3:.2f}..{edges.max() * 1e3:.2f} mm (mean {edges.mean() * 1e3:.2f})"
        )


if __name__ == "__main__":
    main()
