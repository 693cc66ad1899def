"""A graded tetrahedral octant of a ball from fTetWild, fine at one pole, coarse elsewhere.

The ball's octant ``x, y >= 0, z <= 0`` (about its centre) is filled by
:func:`fem.tetrahedralize` under a sizing field: target edge length ``fine_size`` within
``fine_radius`` of the pole ``center - radius e_z``, then growing linearly with the distance
to it up to ``coarse_size``. It is what a user gets from another mesher than the structured
bricks of :func:`fem.generators.graded_ball_mesh`: unstructured tetrahedra, graded freely.

The surface handed to fTetWild is the triangulated boundary of a graded brick octant (its
nodes exactly on the sphere and the three cut planes, fine at the pole); the background
mesh of the sizing field is the same kind of octant split into tetrahedra. fTetWild's
output only lies within its envelope ``epsilon`` of that surface, so its boundary nodes are
snapped back: onto the cut planes, then radially onto the sphere (a move of a small
fraction of the local size), so that symmetry conditions and the contact geometry are
exact. The mesh differs from run to run (fTetWild is not deterministic).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import MeshError
from .generators import graded_ball_mesh
from .mesh import Mesh, tet_volumes6
from .meshing import tetrahedralize

__all__ = ["SLIVER", "graded_octant_surface", "graded_tet_octant", "octant_sizing_field"]

#: A tetrahedron of boundary nodes left with less than this fraction of the mean volume
#: (or turned) once its nodes are snapped is a flattened sliver: it is dropped.
SLIVER = 1e-6


def _size_at(
    x: NDArray[np.float64],
    center: NDArray[np.float64],
    radius: float,
    fine_size: float,
    fine_radius: float,
    coarse_size: float,
    growth: float,
    depth_growth: float | None = None,
) -> NDArray[np.float64]:
    """Target edge length at the points ``x``: fine near the pole, growing linearly.

    With ``depth_growth``, the distance to the pole is that of the point's radial
    projection onto the sphere, and the size also grows with the depth below it.
    """
    pole = center - np.array([0.0, 0.0, radius])
    if depth_growth is None:
        d = np.linalg.norm(x - pole, axis=1)
        extra = 0.0
    else:
        r = np.linalg.norm(x - center, axis=1)
        out = (x - center) / np.maximum(r, 1e-300)[:, None]
        d = np.linalg.norm(center + radius * out - pole, axis=1)
        extra = (depth_growth - 1.0) * np.maximum(radius - r, 0.0)
    h = fine_size + (growth - 1.0) * np.maximum(d - fine_radius, 0.0) + extra
    return np.minimum(h, coarse_size)


def graded_octant_surface(
    radius: float,
    fine_size: float,
    fine_radius: float,
    *,
    coarse_size: float | None = None,
    center: ArrayLike = (0.0, 0.0, 0.0),
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The closed, outward oriented triangle surface of a ball's octant, fine at its pole.

    Parameters
    ----------
    radius, fine_size, fine_radius : float
        As :func:`fem.generators.graded_ball_mesh` (``part="octant"``).
    coarse_size : float, optional
        Largest triangle size; ``radius / 5`` by default.
    center : array_like, shape (3,)

    Returns
    -------
    points : ndarray, shape (N, 3)
        On the sphere or the planes ``x = 0``, ``y = 0``, ``z = 0`` about ``center``.
    triangles : ndarray, shape (M, 3)
        Counter-clockwise seen from outside.
    """
    fr = min(fine_radius, 0.4 * radius)
    bricks = graded_ball_mesh(
        radius, fine_size, fr, coarse_size=coarse_size, part="octant", center=center
    )
    quads = bricks.boundary.faces["quad"]
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    used, inv = np.unique(tris, return_inverse=True)
    return bricks.points[used].copy(), inv.reshape(-1, 3).astype(np.int64)


def octant_sizing_field(
    radius: float,
    fine_size: float,
    fine_radius: float,
    *,
    coarse_size: float | None = None,
    growth: float = 1.3,
    depth_growth: float | None = None,
    center: ArrayLike = (0.0, 0.0, 0.0),
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float64]]:
    """A background tetrahedral mesh of the octant with target edge lengths at its nodes.

    Parameters
    ----------
    radius, fine_size, fine_radius : float
        Ball radius, edge length near the pole and radius of the uniformly fine zone (m).
    coarse_size : float, optional
        Largest edge length; ``radius / 5`` by default.
    growth : float
        Edge length gained per unit of distance beyond the fine zone is ``growth - 1``.
    depth_growth : float, optional
        A fine surface layer instead of a fine solid zone: the distance to the pole is
        measured on the sphere, and ``depth_growth - 1`` is gained per unit of depth
        below it (None: no growth with depth).
    center : array_like, shape (3,)

    Returns
    -------
    points, tets, values : ndarray
        The ``sizing_field`` of :func:`fem.tetrahedralize`.
    """
    from scipy.spatial import Delaunay

    c = np.asarray(center, dtype=np.float64)
    coarse = radius / 5 if coarse_size is None else coarse_size
    fr = min(fine_radius, 0.4 * radius)
    bg_fine = min(max(2.0 * fine_size, fr / 4), coarse)
    nodes = graded_ball_mesh(
        radius, bg_fine, fr, coarse_size=coarse, part="octant", center=c
    ).points
    # a box a little wider than the octant, so that fTetWild's points (within its envelope
    # of the surface, or on the facets' far side of the sphere) all fall inside it
    lo = c + radius * np.array([-0.1, -0.1, -1.1])
    hi = c + radius * np.array([1.1, 1.1, 0.1])
    axes = [np.linspace(a, b, 8) for a, b in zip(lo, hi)]
    box = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    pts = np.concatenate([nodes, box])
    tets = Delaunay(pts).simplices.astype(np.int64)
    values = _size_at(pts, c, radius, fine_size, fr, coarse, growth, depth_growth)
    return pts, tets, values


def graded_tet_octant(
    radius: float,
    fine_size: float,
    fine_radius: float,
    *,
    coarse_size: float | None = None,
    growth: float = 1.3,
    depth_growth: float | None = None,
    surface_size: float | None = None,
    center: ArrayLike = (0.0, 0.0, 0.0),
    epsilon: float = 1e-3,
    **tetwild_options: object,
) -> Mesh:
    """Tetrahedra filling the octant ``x, y >= 0, z <= 0`` of a ball, fine at its pole.

    Parameters
    ----------
    radius : float
        Ball radius (m).
    fine_size : float
        Target edge length within ``fine_radius`` of the pole ``center - radius e_z`` (m).
    fine_radius : float
        Radius of the uniformly fine zone (m), at most ``0.4 radius``.
    coarse_size : float, optional
        Largest edge length (m); ``radius / 5`` by default.
    growth : float
        Beyond the fine zone the target grows by ``growth - 1`` per unit of distance.
    depth_growth : float, optional
        A fine surface layer: the target also grows by ``depth_growth - 1`` per unit of
        depth below the sphere (see :func:`octant_sizing_field`). Few nodes lie below a
        fine contact patch: its rows grow faster than the DOFs.
    surface_size : float, optional
        Edge length at the pole of the surface handed to fTetWild (``fine_size`` by
        default), which refines it as the field asks: a coarser one is quicker to make
        (its brick octant is fine in a solid zone) and within ``surface_size**2 / (8
        radius)`` of the sphere, where the boundary nodes are snapped.
    center : array_like, shape (3,)
    epsilon : float
        fTetWild's envelope, relative to the bounding box's diagonal.
    **tetwild_options
        Passed on to :func:`fem.tetrahedralize`.

    Returns
    -------
    Mesh
        Tetrahedra; boundary nodes exactly on the sphere and the three cut planes, but
        the few whose snap would turn a cell (left within fTetWild's envelope).

    Raises
    ------
    MeshError
        On sizes out of range, or from fTetWild.
    """
    if not 0 < fine_size <= (radius / 5 if coarse_size is None else coarse_size):
        raise MeshError(f"fine_size must lie in (0, coarse_size], got {fine_size!r}")
    if not growth > 1.0:
        raise MeshError(f"growth must exceed 1, got {growth!r}")
    c = np.asarray(center, dtype=np.float64)
    if depth_growth is not None and not depth_growth > 1.0:
        raise MeshError(f"depth_growth must exceed 1, got {depth_growth!r}")
    fs = fine_size if surface_size is None else surface_size
    if not fine_size <= fs <= (radius / 5 if coarse_size is None else coarse_size):
        raise MeshError(f"surface_size must lie in [fine_size, coarse_size], got {fs!r}")
    surface = graded_octant_surface(radius, fs, fine_radius, coarse_size=coarse_size, center=c)
    field = octant_sizing_field(
        radius,
        fine_size,
        fine_radius,
        coarse_size=coarse_size,
        growth=growth,
        depth_growth=depth_growth,
        center=c,
    )
    # fTetWild scales its ideal edge length down where the field asks: give it the largest
    coarse = radius / 5 if coarse_size is None else coarse_size
    mesh = tetrahedralize(surface, coarse, sizing_field=field, epsilon=epsilon, **tetwild_options)
    return _snapped(mesh, radius, c, 1.5 * epsilon * radius * np.sqrt(3.0))


def _snapped(mesh: Mesh, radius: float, center: NDArray[np.float64], tol: float) -> Mesh:
    """The mesh with its boundary nodes moved onto the cut planes and the sphere.

    The octant's boundary is the three cut planes and the sphere: a boundary node within
    ``tol`` of a plane ``x_k = 0`` goes onto it; one that is on no plane, or within ``tol``
    of the sphere, goes radially onto the sphere (a node on a plane stays on it).
    fTetWild leaves nodes up to about its envelope off the surface, a few near the
    sphere's coarse facets further: a node's own surfaces, not its triangles' normals,
    tell where it belongs. Where a snap would turn a cell with an inner node, the cell's
    furthest snapped node stays where fTetWild put it (within its envelope of the surface).
    """
    p = mesh.points.copy()
    tets = mesh.cells["tetra"]
    nodes = np.unique(mesh.boundary.faces["triangle"])
    d = p[nodes] - center
    near = np.abs(d) <= tol  # (m, 3): on the plane x_k = 0
    d[near] = 0.0
    r = np.linalg.norm(d, axis=1)
    sphere = ~near.any(axis=1) | (np.abs(r - radius) <= tol)
    sphere &= r > 0
    d[sphere] *= (radius / r[sphere])[:, None]
    p[nodes] = center + d
    on = np.zeros(len(p), dtype=bool)
    on[nodes] = True
    moved = np.linalg.norm(p - mesh.points, axis=1)
    for _ in range(4):  # each round takes back the furthest snapped node of each turned cell
        vol = tet_volumes6(p, tets)
        bad = tets[(vol <= SLIVER * np.abs(vol).mean()) & ~on[tets].all(axis=1)]
        if not len(bad):
            break
        back = bad[np.arange(len(bad)), np.argmax(moved[bad], axis=1)]
        p[back], moved[back] = mesh.points[back], 0.0
    return _without_flat(p, tets, on)


def _without_flat(
    points: NDArray[np.float64], tets: NDArray[np.int64], on: NDArray[np.bool_]
) -> Mesh:
    """The tetrahedra less the slivers that snapping flattened onto the boundary.

    A sliver whose four nodes all lie on the boundary (at an edge between a cut plane and
    the sphere) can come out flat, or turned by round-off, once they are snapped: its
    volume, below :data:`SLIVER` of the mean, is nothing of the octant's, and its
    neighbours' faces close the boundary where it lay (``on``: the boundary nodes). Nodes
    no cell keeps are dropped.
    """
    vol = tet_volumes6(points, tets)
    flat = (vol <= SLIVER * np.abs(vol).mean()) & on[tets].all(axis=1)
    if not flat.any():
        return Mesh(points, {"tetra": tets})
    kept = tets[~flat]
    used = np.unique(kept)
    renumber = np.full(len(points), -1, dtype=np.int64)
    renumber[used] = np.arange(used.size)
    return Mesh(points[used], {"tetra": renumber[kept]})
