"""Cubed-sphere mesh generators: solid balls and spherical shells of 8-node bricks.

The ball is a mapped cube: a rounded cubic core surrounded by six blocks that run from
the core to the sphere (a "cubed sphere"); the shell is the six cubed-sphere blocks
between two radii. Neither needs degenerate bricks: every cell is a proper hexahedron.
:func:`graded_ball_mesh` is the same ball with its grid lines drawn together towards the
two poles on the z axis (where plates press it), whole or cut along its symmetry planes.
Boxes, tensor grids and :func:`hex_to_tet` live in :mod:`fem.grids`, ``node_dofs`` in
:mod:`fem.dofs`; both are re-exported here.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .dofs import node_dofs
from .errors import MeshError
from .grids import box_mesh, grid_hexes, grid_index, grid_mesh, hex_to_tet, merge_points
from .mesh import Mesh

__all__ = [
    "BALL_PARTS",
    "ball_mesh",
    "box_mesh",
    "graded_ball_mesh",
    "graded_spacing",
    "grid_mesh",
    "hex_to_tet",
    "merge_points",
    "node_dofs",
    "shell_mesh",
]


def _face_frames() -> list[tuple[int, int, int, float]]:
    """(axis, b, c, sign) for the six cube faces, (b, c, outward) right-handed."""
    out = []
    for a in range(3):
        b, c = (a + 1) % 3, (a + 2) % 3
        out.append((a, b, c, 1.0))
        out.append((a, c, b, -1.0))
    return out


def _cube_face_points(t: NDArray[np.float64], frame: tuple[int, int, int, float]) -> NDArray:
    """Points ``s e_a + t_i e_b + t_j e_c`` on a cube face, shape (n, n, 3) indexed [j, i]."""
    a, b, c, s = frame
    n = len(t)
    q = np.zeros((n, n, 3))
    q[..., a] = s
    q[..., b] = t[None, :]
    q[..., c] = t[:, None]
    return q


def _sphere_dirs(n: int, frame: tuple[int, int, int, float]) -> NDArray[np.float64]:
    """Equiangular unit directions of one cubed-sphere face, shape (n+1, n+1, 3)."""
    t = np.tan(np.linspace(-math.pi / 4, math.pi / 4, n + 1))
    t[0], t[-1] = -1.0, 1.0
    q = _cube_face_points(t, frame)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def _block_hexes(n: int, layers: int, offset: int) -> NDArray[np.int64]:
    idx = np.arange((layers + 1) * (n + 1) * (n + 1)).reshape(layers + 1, n + 1, n + 1)
    return grid_hexes(idx) + offset


def _finish(points: list[NDArray], hexes: list[NDArray], scale: float) -> Mesh:
    pts = np.concatenate(points)
    cells = {"hexahedron": np.concatenate(hexes)}
    pts, cells = merge_points(pts, cells, 1e-9 * scale)
    return Mesh(pts, cells)


def _count(size: float | None, n: int | None, length: float, name: str, least: int) -> int:
    if n is not None:
        if int(n) != n or n < least:
            raise MeshError(f"{name} must be an integer >= {least}, got {n!r}")
        return int(n)
    if size is None or not size > 0:
        raise MeshError(f"give a positive mesh size or {name}, got size={size!r}")
    return max(least, math.ceil(length / size - 1e-9))


def shell_mesh(
    inner: float,
    outer: float,
    size: float | None = None,
    *,
    divisions: int | None = None,
    layers: int | None = None,
    center: ArrayLike = (0.0, 0.0, 0.0),
) -> Mesh:
    """A spherical shell of hexahedra (cubed sphere), e.g. a hollow ball's envelope.

    Parameters
    ----------
    inner, outer : float
        Radii (m), ``0 < inner < outer``.
    size : float, optional
        Target edge length (m); sets ``divisions`` and ``layers`` when they are omitted.
    divisions : int, optional
        Cells along each edge of each of the six faces.
    layers : int, optional
        Cells through the wall.
    center : array_like, shape (3,)
    """
    if not 0 < inner < outer:
        raise MeshError(f"shell radii must satisfy 0 < inner < outer, got {inner}, {outer}")
    rm = 0.5 * (inner + outer)
    n = _count(size, divisions, 0.5 * math.pi * rm, "divisions", 1)
    nl = _count(size, layers, outer - inner, "layers", 1)
    radii = np.linspace(inner, outer, nl + 1)
    pts, hexes = [], []
    for frame in _face_frames():
        d = _sphere_dirs(n, frame)
        p = radii[:, None, None, None] * d[None]
        hexes.append(_block_hexes(n, nl, sum(len(x) for x in pts)))
        pts.append(p.reshape(-1, 3))
    mesh = _finish(pts, hexes, outer)
    return Mesh(mesh.points + np.asarray(center, float), mesh.cells)


def ball_mesh(
    radius: float,
    size: float | None = None,
    *,
    divisions: int | None = None,
    layers: int | None = None,
    center: ArrayLike = (0.0, 0.0, 0.0),
    core: float = 0.5,
) -> Mesh:
    """A solid ball of hexahedra: a rounded cubic core and six cubed-sphere blocks.

    Parameters
    ----------
    radius : float
        Ball radius (m).
    size : float, optional
        Target edge length (m); sets ``divisions`` and ``layers`` when omitted.
    divisions : int, optional
        Cells along each edge of the core cube (and of each outer block's faces). An
        even number puts a node at each of the six poles; with an odd one the facets
        there sit inside the sphere (``radius`` 0.02 m, ``size`` 0.003 m: its lowest
        nodes 0.25 mm above the sphere's bottom), so that a plane touching the sphere
        touches no node until it has moved that far.
    layers : int, optional
        Cells from the core to the sphere.
    center : array_like, shape (3,)
    core : float
        Core half-width as a fraction of the radius, in (0.2, 0.7).
    """
    if not radius > 0:
        raise MeshError(f"ball radius must be positive, got {radius!r}")
    if not 0.2 <= core <= 0.7:
        raise MeshError(f"core must lie in [0.2, 0.7], got {core!r}")
    a = core * radius
    n = _count(size, divisions, 2 * a, "divisions", 1)
    nl = _count(size, layers, radius - a * 1.2, "layers", 1)
    gamma = 0.5  # how far the core's faces bulge towards a sphere through its corners

    def core_map(q: NDArray[np.float64]) -> NDArray[np.float64]:
        """Map the cube [-1, 1]^3 onto the rounded core, scaling rays from the centre."""
        inf = np.abs(q).max(axis=-1, keepdims=True)
        l2 = np.linalg.norm(q, axis=-1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            qs = np.where(inf > 0, q / inf, 0.0)  # on the cube surface
            l2s = np.where(inf > 0, l2 / inf, 1.0)
        surf = a * ((1 - gamma) * qs + gamma * math.sqrt(2.0) * qs / l2s)
        return inf * surf

    t = np.linspace(-1.0, 1.0, n + 1)
    z, y, x = np.meshgrid(t, t, t, indexing="ij")
    cube = np.stack([x, y, z], axis=-1)
    pts = [core_map(cube).reshape(-1, 3)]
    hexes = [grid_hexes(grid_index(n, n, n))]
    for frame in _face_frames():
        inner = core_map(_cube_face_points(t, frame))
        outer = radius * _sphere_dirs(n, frame)
        s = np.linspace(0.0, 1.0, nl + 1)[:, None, None, None]
        p = inner[None] + s * (outer - inner)[None]
        hexes.append(_block_hexes(n, nl, sum(len(v) for v in pts)))
        pts.append(p.reshape(-1, 3))
    mesh = _finish(pts, hexes, radius)
    return Mesh(mesh.points + np.asarray(center, float), mesh.cells)


#: Parts of a graded ball: which half-spaces of its centre (x >= 0, y >= 0, z <= 0) keep.
BALL_PARTS: dict[str, tuple[bool, bool, bool]] = {
    "full": (False, False, False),
    "half": (False, False, True),
    "quarter": (True, True, False),
    "octant": (True, True, True),
}


def graded_spacing(first: float, fine: float, largest: float, growth: float) -> NDArray:
    """Nodes on ``[0, 1]``: uniform cells near 0, then cells growing geometrically.

    Cells of about ``first`` fill ``[0, fine]`` exactly; from there each cell is ``growth``
    times the previous one, up to ``largest``; the growing cells are then scaled together
    so that the last node is 1 (the last one is dropped first when it overshoots by more
    than half its size).

    Parameters
    ----------
    first : float
        Cell size in the uniform zone, in ``(0, 1]``.
    fine : float
        End of the uniform zone, in ``[0, 1]``; 1 gives a uniform grid.
    largest : float
        Largest cell size, at least ``first``.
    growth : float
        Ratio of neighbouring cells in the graded zone, in ``[1, 2]``.

    Returns
    -------
    ndarray
        Increasing nodes from 0 to 1.
    """
    if not 0 < first <= 1 or not 0 <= fine <= 1 or not largest >= first:
        raise MeshError(
            f"spacing needs 0 < first <= 1, 0 <= fine <= 1, largest >= first; got {first}, "
            f"{fine}, {largest}"
        )
    if not 1.0 <= growth <= 2.0:
        raise MeshError(f"growth must lie in [1, 2], got {growth!r}")
    n_fine = max(1, round(fine / first)) if fine > 0 else 0
    sizes = [fine / n_fine] * n_fine if n_fine else []
    h = sizes[-1] if sizes else first
    grow: list[float] = []
    rest = 1.0 - fine
    while sum(grow) < rest - 1e-12:
        h = min(h * growth, largest)
        grow.append(h)
    if len(grow) > 1 and sum(grow) - rest > 0.5 * grow[-1]:
        grow.pop()
    if grow:
        sizes += [g * rest / sum(grow) for g in grow]
    t = np.concatenate([[0.0], np.cumsum(sizes)])
    t[-1] = 1.0
    return t


def _core_map(q: NDArray[np.float64], a: float, gamma: float = 0.5) -> NDArray[np.float64]:
    """Map the cube ``[-1, 1]^3`` onto a rounded core of half-width ``a`` (rays scaled)."""
    inf = np.abs(q).max(axis=-1, keepdims=True)
    l2 = np.linalg.norm(q, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        qs = np.where(inf > 0, q / inf, 0.0)
        l2s = np.where(inf > 0, l2 / inf, 1.0)
    return inf * a * ((1 - gamma) * qs + gamma * math.sqrt(2.0) * qs / l2s)


def graded_ball_mesh(
    radius: float,
    fine_size: float,
    fine_radius: float,
    *,
    coarse_size: float | None = None,
    growth: float = 1.25,
    part: str = "full",
    center: ArrayLike = (0.0, 0.0, 0.0),
    core: float = 0.35,
) -> Mesh:
    """A solid ball of hexahedra, fine near its two poles on the z axis, coarse elsewhere.

    The topology is that of :func:`ball_mesh` (a rounded cubic core and six cubed-sphere
    blocks), with one grid per axis and one through the blocks, so that every cell stays a
    proper brick and the mesh conforms:

    - along x and y (the core's grid and the equiangular grid of the blocks), cells of
      ``fine_size`` (arc length on the sphere) within ``fine_radius`` of the z axis, then
      growing by ``growth`` per cell up to ``coarse_size``;
    - from the core to the sphere, cells of ``fine_size`` within ``fine_radius`` of the
      sphere, growing inward the same way;
    - along z, uniform cells of about ``coarse_size``.

    So the two pole caps (the contact patches of a ball pressed along z) are covered by
    cubes of ``fine_size`` to a depth and a radius of ``fine_radius``. Being a tensor
    grid, the fine spacing also runs along the lines through the caps (thin slabs along
    the planes x = 0 and y = 0, thin layers under the whole sphere): that is the price of
    conforming bricks without hanging nodes. The grids are symmetric and have nodes on the
    planes x = 0, y = 0 and z = 0, so the ball can be cut exactly along them (``part``).

    Parameters
    ----------
    radius : float
        Ball radius (m).
    fine_size : float
        Cell size near the poles (m).
    fine_radius : float
        Radius (and depth) of the uniformly fine zone about each pole (m), at most
        ``0.4 * radius``; a contact patch of radius ``a`` wants about ``1.3 a``.
    coarse_size : float, optional
        Largest cell size (m); ``radius / 5`` by default.
    growth : float
        Ratio of neighbouring cells where the grid coarsens, in [1, 2].
    part : {"full", "half", "quarter", "octant"}
        The whole ball; the half with ``z <= 0`` (one pole, the equator face a symmetry
        plane); the quarter with ``x, y >= 0`` (both poles); or the octant with
        ``x, y >= 0, z <= 0``. Coordinates relative to ``center``.
    center : array_like, shape (3,)
    core : float
        Core half-width as a fraction of the radius, in [0.2, 0.5].

    Returns
    -------
    Mesh
        Hexahedra with positive Jacobians.

    Raises
    ------
    MeshError
        On sizes out of range or an unknown part.
    """
    if not radius > 0:
        raise MeshError(f"ball radius must be positive, got {radius!r}")
    if not 0.2 <= core <= 0.5:
        raise MeshError(f"core must lie in [0.2, 0.5], got {core!r}")
    if part not in BALL_PARTS:
        raise MeshError(f"part must be one of {sorted(BALL_PARTS)}, got {part!r}")
    coarse = radius / 5 if coarse_size is None else coarse_size
    if not 0 < fine_size <= coarse:
        raise MeshError(
            f"need 0 < fine_size <= coarse_size, got fine_size={fine_size!r}, "
            f"coarse_size={coarse!r}"
        )
    if not fine_size <= fine_radius <= 0.4 * radius:
        raise MeshError(
            f"fine_radius must lie in [fine_size, 0.4 * radius] = [{fine_size:.6g}, "
            f"{0.4 * radius:.6g}], got {fine_radius!r}"
        )
    a = core * radius
    arc = 0.25 * math.pi * radius  # sphere arc of the half grid [0, 1] of a cube face
    half = graded_spacing(fine_size / arc, fine_radius / arc, coarse / arc, growth)
    t_xy = np.concatenate([-half[:0:-1], half])  # symmetric, node at 0
    nz = max(1, math.ceil(arc / coarse - 1e-9))
    t_z = np.linspace(-1.0, 1.0, 2 * nz + 1)
    depth = radius - a * (1 - 0.5 + 0.5 * math.sqrt(2.0))  # core face to sphere at a pole
    if fine_radius > 0.9 * depth:
        raise MeshError(
            f"fine_radius = {fine_radius!r} must stay within 0.9 of the {depth:.6g} from the "
            "core to the sphere at a pole: take a smaller core"
        )
    s = 1.0 - graded_spacing(fine_size / depth, fine_radius / depth, coarse / depth, growth)
    s = s[::-1]
    grids = (t_xy, t_xy, t_z)

    z, y, x = np.meshgrid(t_z, t_xy, t_xy, indexing="ij")
    pts = [_core_map(np.stack([x, y, z], axis=-1), a).reshape(-1, 3)]
    hexes = [grid_hexes(grid_index(len(t_xy) - 1, len(t_xy) - 1, len(t_z) - 1))]
    for ax, b, c, sign in _face_frames():
        tb, tc = grids[b], grids[c]
        q = np.zeros((len(tc), len(tb), 3))
        q[..., ax] = sign
        q[..., b] = tb[None, :]
        q[..., c] = tc[:, None]
        inner = _core_map(q, a)
        d = q.copy()
        d[..., b] = np.tan(0.25 * math.pi * tb)[None, :]
        d[..., c] = np.tan(0.25 * math.pi * tc)[:, None]
        d[..., b][:, [0, -1]] = np.sign(tb[[0, -1]])  # exact cube edges
        d[..., c][[0, -1], :] = np.sign(tc[[0, -1]])[:, None]
        outer = radius * d / np.linalg.norm(d, axis=-1, keepdims=True)
        p = inner[None] + s[:, None, None, None] * (outer - inner)[None]
        idx = np.arange(p.shape[0] * p.shape[1] * p.shape[2]).reshape(p.shape[:3])
        hexes.append(grid_hexes(idx) + sum(len(v) for v in pts))
        pts.append(p.reshape(-1, 3))
    points = np.concatenate(pts)
    cells = np.concatenate(hexes)
    keep_x, keep_y, keep_z = BALL_PARTS[part]
    ctr = points[cells].mean(axis=1)
    keep = np.ones(len(cells), dtype=bool)
    if keep_x:
        keep &= ctr[:, 0] > 0
    if keep_y:
        keep &= ctr[:, 1] > 0
    if keep_z:
        keep &= ctr[:, 2] < 0
    cells = cells[keep]
    used = np.unique(cells)
    renum = np.full(len(points), -1, dtype=np.int64)
    renum[used] = np.arange(len(used))
    points, merged = merge_points(points[used], {"hexahedron": renum[cells]}, 1e-9 * radius)
    return Mesh(points + np.asarray(center, float), merged)
