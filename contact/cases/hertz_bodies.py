"""Hertz contact of two deformable bodies: a sphere on an elastic block, two spheres.

The analytic side is Hertz's for two elastic bodies of radii ``R1``, ``R2`` (a flat block:
``R2 = inf``) pressed with force ``F``: that of :mod:`contact.cases.hertz_theory` with the
effective radius ``1/R = 1/R1 + 1/R2`` and the contact modulus
``1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2`` (:func:`hertz_two_bodies`).

The FE side solves the frame with :func:`contact.solver.iteration.solve_frame` (both bodies
deformable, node-to-surface pairs in both directions) on exact quarter models: the load
axis is z, the contact point the origin, and the planes ``x = 0`` and ``y = 0`` through
the axis are frictionless symmetry planes (the normal displacement held):

``"sphere-block"``
    A quarter of the hemisphere ``z <= zc`` of a ball of radius ``R`` (centre ``zc``),
    pole down, on a quarter box ``[0, L] x [0, L] x [-H, 0]``, graded towards the origin
    (:func:`graded_box_mesh`), its bottom held in z. The hemisphere's flat equator face is
    held in z: a rigid frictionless plate on it, which is also the exact symmetry plane
    of a whole ball pressed between two such blocks.
``"two-spheres"``
    Two such quarter hemispheres, radii ``R1`` (top, pole down) and ``R2`` (bottom, pole
    up), each held in z on its equator face.

The load is an interference: the top body is placed ``depth`` lower than touching, so its
pole lies ``depth`` inside the other body (the contact set starts from the nodes that
overlap). In small strain this is the same as pressing the plate on its equator face down
by ``depth`` (the gap rows are linear, measured from the reference positions): the two
equator planes (or the plate and the block's base) approach by ``depth``, giving
``a ~ sqrt(R depth)``.

Contact radius and peak pressure are measured from the nodal contact forces of one body
(:func:`contact.cases.contact_patch.measure_contact_patch`: the moment radius with the
interpolation excess removed, and the consistent Hertz-profile fit of the interior forces),
by default the top sphere's: ``contact_force`` of a body is everything the contact rows
put on its nodes, as slave and as master. The other body's forces give a second measure;
the two totals must be equal and opposite (action equals reaction).

Materials are compressible (``nu = 0.3`` by default): trilinear bricks lock as ``nu``
approaches 0.5, so the check uses a value where HEX8 is accurate.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np
from numpy.typing import NDArray

import fem
from fem.generators import graded_ball_mesh, graded_spacing, grid_mesh

from ..errors import ContactError
from ..geometry.plane import Plane
from ..solver import ContactSettings, solve_frame
from ..solver.body import ElasticBody
from ..solver.pairs import ContactPair
from ..solver.results import FrameResult
from .hertz import (
    ContactPatch,
    HertzErrors,
    HertzSolution,
    effective_modulus,
    measure_contact_patch,
)

__all__ = [
    "SCENES",
    "HertzBodiesCheck",
    "HertzScene",
    "graded_box_mesh",
    "hemisphere_mesh",
    "hertz_bodies_check",
    "hertz_scene",
    "hertz_two_bodies",
]

#: The two scenes of :func:`hertz_scene`.
SCENES = ("sphere-block", "two-spheres")


def hertz_two_bodies(
    force: float,
    R1: float,
    R2: float,
    E1: float,
    nu1: float,
    E2: float,
    nu2: float,
) -> HertzSolution:
    """Hertz solution of two elastic bodies with spherical tips pressed together.

    Parameters
    ----------
    force : float
        Normal force (N), positive.
    R1, R2 : float
        Radii of the two tips (m); ``math.inf`` for a flat body.
    E1, nu1, E2, nu2 : float
        Young's moduli (Pa) and Poisson's ratios; ``E2 = math.inf`` for a rigid body.

    Returns
    -------
    HertzSolution
        With ``radius`` the effective radius ``R = 1 / (1/R1 + 1/R2)`` and ``modulus``
        ``E*``, ``1/E* = (1-nu1^2)/E1 + (1-nu2^2)/E2``.
    """
    if not force > 0 or not R1 > 0 or not R2 > 0 or (math.isinf(R1) and math.isinf(R2)):
        raise ContactError(f"need a positive force and radii, one finite; got {force}, {R1}, {R2}")
    radius = 1.0 / (1.0 / R1 + 1.0 / R2)
    es = effective_modulus(E1, nu1, E2, nu2)
    a = (3.0 * force * radius / (4.0 * es)) ** (1.0 / 3.0)
    p0 = 3.0 * force / (2.0 * math.pi * a**2)
    return HertzSolution(force, radius, es, a, p0, force / (math.pi * a**2), a**2 / radius)


# --- meshes -----------------------------------------------------------------------------


def graded_box_mesh(
    lengths: tuple[float, float, float],
    fine_size: float,
    fine_extent: float,
    *,
    coarse_size: float | None = None,
    growth: float = 1.25,
) -> fem.Mesh:
    """The quarter block ``[0, Lx] x [0, Ly] x [-H, 0]`` of bricks, fine near the origin.

    Along each axis, cells of ``fine_size`` up to ``fine_extent`` from the origin (the
    contact point on the top face ``z = 0``), then growing by ``growth`` per cell up to
    ``coarse_size`` (:func:`fem.generators.graded_spacing`). Being a tensor grid, the fine
    spacing also runs along the planes through the origin.

    Parameters
    ----------
    lengths : tuple of float
        ``(Lx, Ly, H)`` (m).
    fine_size : float
        Cell size near the origin (m).
    fine_extent : float
        Extent of the uniformly fine zone along each axis (m).
    coarse_size : float, optional
        Largest cell (m); a fifth of the largest side by default.
    growth : float
        Ratio of neighbouring cells where the grid coarsens, in [1, 2].

    Returns
    -------
    fem.Mesh
        Hexahedra with positive Jacobians.
    """
    lx, ly, h = (float(v) for v in lengths)
    if min(lx, ly, h) <= 0:
        raise ContactError(f"block lengths must be positive, got {lengths}")
    coarse = max(lx, ly, h) / 5 if coarse_size is None else coarse_size
    axes = []
    for length in (lx, ly, h):
        fe = min(fine_extent, length)
        axes.append(
            length * graded_spacing(fine_size / length, fe / length, coarse / length, growth)
        )
    return grid_mesh(axes[0], axes[1], -axes[2][::-1])


def hemisphere_mesh(
    radius: float,
    fine_size: float,
    fine_radius: float,
    *,
    pole: str = "down",
    tip: tuple[float, float, float] = (0.0, 0.0, 0.0),
    coarse_size: float | None = None,
    growth: float = 1.25,
) -> fem.Mesh:
    """A quarter hemisphere (``x, y >= 0``) of :func:`fem.generators.graded_ball_mesh`.

    Parameters
    ----------
    radius : float
        Sphere radius (m).
    fine_size, fine_radius, coarse_size, growth : float
        Grading about the pole (see :func:`fem.generators.graded_ball_mesh`).
    pole : {"down", "up"}
        Whether the pole (the contact tip) points to ``-z`` or to ``+z``; the flat
        equator face is on the other side.
    tip : tuple of float
        Where the pole is (m).

    Returns
    -------
    fem.Mesh
        Hexahedra with positive Jacobians.
    """
    if pole not in ("down", "up"):
        raise ContactError(f"pole must be 'down' or 'up', got {pole!r}")
    m = graded_ball_mesh(
        radius, fine_size, fine_radius, coarse_size=coarse_size, growth=growth, part="octant"
    )
    pts = m.points + np.array([0.0, 0.0, radius])  # pole at the origin, equator z = R
    hexes = m.cells["hexahedron"]
    if pole == "up":
        pts = pts * np.array([1.0, 1.0, -1.0])
        hexes = hexes[:, [4, 5, 6, 7, 0, 1, 2, 3]]  # a mirror: swap the brick's two faces
    return fem.Mesh(pts + np.asarray(tip, dtype=np.float64), {"hexahedron": hexes})


# --- scenes -----------------------------------------------------------------------------


@dataclass(frozen=True)
class HertzScene:
    """Two deformable bodies pressed together along z, touching at the origin.

    Attributes
    ----------
    name : str
        One of :data:`SCENES`.
    bodies : tuple of ElasticBody
        The top sphere, then the block or the bottom sphere.
    pairs : tuple of ContactPair
        Node-to-surface pairs in both directions.
    radii : tuple of float
        ``(R1, R2)`` (m), ``inf`` for the block.
    moduli : tuple of float
        ``(E1, E2)`` (Pa).
    nu : float
        Poisson's ratio of both.
    depth : float
        Interference (m): how far the two bodies' far faces approach.
    seconds : dict of str to float
        ``mesh`` and ``body`` (assembly and factorisation of both) times.
    """

    name: str
    bodies: tuple[ElasticBody, ElasticBody]
    pairs: tuple[ContactPair, ...]
    radii: tuple[float, float]
    moduli: tuple[float, float]
    nu: float
    depth: float
    seconds: dict[str, float] = field(default_factory=dict)

    @property
    def dofs(self) -> int:
        """DOFs of both bodies."""
        return sum(b.mesh.n_dofs for b in self.bodies)


def _sphere_faces(mesh: fem.Mesh, center: NDArray, radius: float) -> fem.BoundaryFaces:
    """The boundary faces whose nodes all lie on the sphere."""
    bnd = mesh.boundary
    on = np.abs(np.linalg.norm(mesh.points - center, axis=1) - radius) <= 1e-9 * radius
    return bnd.subset({k: on[f].all(axis=1) for k, f in bnd.faces.items()})


def _plane_faces(mesh: fem.Mesh, axis: int, value: float, tol: float) -> fem.BoundaryFaces:
    """The boundary faces whose nodes all lie on the plane ``x[axis] = value``."""
    bnd = mesh.boundary
    on = np.abs(mesh.points[:, axis] - value) <= tol
    return bnd.subset({k: on[f].all(axis=1) for k, f in bnd.faces.items()})


def _held(mesh: fem.Mesh, tol: float, z_plane: float) -> NDArray[np.int64]:
    """DOFs held: x on ``x = 0``, y on ``y = 0``, z on ``z = z_plane``."""
    p = mesh.points
    return np.concatenate(
        [
            3 * np.flatnonzero(np.abs(p[:, 0]) <= tol),
            3 * np.flatnonzero(np.abs(p[:, 1]) <= tol) + 1,
            3 * np.flatnonzero(np.abs(p[:, 2] - z_plane) <= tol) + 2,
        ]
    )


def hertz_scene(
    name: str,
    ratio: float,
    *,
    fine_size: float,
    depth: float | None = None,
    radii: tuple[float, float] = (1.0, 1.0),
    E: float = 1.0,
    nu: float = 0.3,
    fine_radius: float | None = None,
    block: tuple[float, float] = (2.0, 2.0),
    growth: float = 1.25,
    coarse_size: float | None = None,
    both_directions: bool = True,
) -> HertzScene:
    """Build a quarter-model Hertz scene of two deformable bodies (see the module notes).

    Parameters
    ----------
    name : {"sphere-block", "two-spheres"}
    ratio : float
        ``E1 / E2``: the top sphere's modulus over the other body's.
    fine_size : float
        Cell size at the contact, on both bodies (m).
    depth : float, optional
        Interference (m); ``a`` is about ``sqrt(R depth)``, ``R`` the effective radius.
        ``0.01 R`` by default: ``a/R`` about 0.1.
    radii : tuple of float
        ``(R1, R2)``: the top sphere's radius, and the bottom sphere's (``"two-spheres"``;
        ignored for the block).
    E : float
        The other body's modulus ``E2`` (Pa); the top sphere has ``ratio * E``.
    nu : float
        Poisson's ratio of both bodies.
    fine_radius : float, optional
        Extent of the fine zone about the contact (m): ``1.3 sqrt(R depth)`` by default,
        ``R`` the effective radius.
    block : tuple of float
        ``(L, H)``: the block's side and height, as multiples of ``R1``.
    growth, coarse_size : float
        Grading of the meshes; ``coarse_size`` defaults to a fifth of each body's size.
    both_directions : bool
        Pairs in both directions (default), or the top sphere's nodes against the other
        body only.

    Returns
    -------
    HertzScene
    """
    if name not in SCENES:
        raise ContactError(f"scene must be one of {', '.join(SCENES)}, got {name!r}")
    r1 = float(radii[0])
    r2 = float(radii[1]) if name == "two-spheres" else math.inf
    reff = 1.0 / (1.0 / r1 + 1.0 / r2)
    depth = 0.01 * reff if depth is None else float(depth)
    if not ratio > 0 or not depth > 0:
        raise ContactError(f"need a positive ratio and depth, got {ratio!r}, {depth!r}")
    fr = 1.3 * math.sqrt(reff * depth) if fine_radius is None else fine_radius
    fr = max(fr, fine_size)
    t0 = time.perf_counter()
    top = hemisphere_mesh(
        r1,
        fine_size,
        min(fr, 0.4 * r1),
        pole="down",
        tip=(0.0, 0.0, -depth),
        coarse_size=coarse_size,
        growth=growth,
    )
    if name == "sphere-block":
        side, height = block[0] * r1, block[1] * r1
        other = graded_box_mesh(
            (side, side, height), fine_size, fr, coarse_size=coarse_size, growth=growth
        )
        other_faces = _plane_faces(other, 2, 0.0, 1e-9 * r1)
        other_plane = -height
    else:
        other = hemisphere_mesh(
            r2, fine_size, min(fr, 0.4 * r2), pole="up", coarse_size=coarse_size, growth=growth
        )
        other_faces = _sphere_faces(other, np.array([0.0, 0.0, -r2]), r2)
        other_plane = -r2
    t1 = time.perf_counter()
    tol = 1e-9 * r1
    top_center = np.array([0.0, 0.0, r1 - depth])
    sphere = ElasticBody(
        "top",
        top,
        fem.LinearElastic(ratio * E, nu),
        prescribed=_held(top, tol, r1 - depth),
        contact_faces=_sphere_faces(top, top_center, r1),
    )
    lower = ElasticBody(
        "block" if name == "sphere-block" else "bottom",
        other,
        fem.LinearElastic(E, nu),
        prescribed=_held(other, tol, other_plane),
        contact_faces=other_faces,
    )
    t2 = time.perf_counter()
    pairs = [ContactPair(sphere, lower)]
    if both_directions:
        pairs.append(ContactPair(lower, sphere))
    return HertzScene(
        name,
        (sphere, lower),
        tuple(pairs),
        (r1, r2),
        (ratio * E, E),
        nu,
        depth,
        {"mesh": t1 - t0, "body": t2 - t1},
    )


# --- the check --------------------------------------------------------------------------


@dataclass(frozen=True)
class HertzBodiesCheck(HertzErrors):
    """A Hertz scene solved, measured and compared.

    Attributes
    ----------
    scene : HertzScene
    result : FrameResult
    patch : ContactPatch
        The top sphere's patch (forces of the whole patch, the model holding a quarter).
    patch_other : ContactPatch
        The other body's.
    hertz : HertzSolution
        Hertz for the top sphere's total force.
    action_reaction : float
        ``|F_top + F_other| / |F_top|`` over the three components.
    seconds : dict of str to float
        ``mesh``, ``body`` (assembly and factorisation) and ``contact`` (the frame) times.
    """

    scene: HertzScene
    result: FrameResult
    patch: ContactPatch
    patch_other: ContactPatch
    hertz: HertzSolution
    action_reaction: float
    seconds: dict[str, float] = field(default_factory=dict)

    @property
    def radius_error_other(self) -> float:
        """The same from the other body's nodal forces."""
        return self.patch_other.errors(self.hertz)[0]

    @property
    def pressure_error_other(self) -> float:
        """The same from the other body's nodal forces."""
        return self.patch_other.errors(self.hertz)[1]


def _measure(
    scene: HertzScene, result: FrameResult, edge_cells: float
) -> tuple[ContactPatch, ContactPatch, HertzSolution, float]:
    """The two bodies' patches, Hertz for the top one's force, and the action-reaction gap.

    :func:`contact.cases.hertz.measure_contact_patch` reads only the nodal ``contact_force``
    of its result: each body's is given as such, against a plane through the origin
    whose normal points away from the body (the side its forces push it to).
    """
    top, other = scene.bodies
    f_top = result.total_contact_force(top.name)
    f_other = result.total_contact_force(other.name)
    ar = float(np.abs(f_top + f_other).max() / max(np.abs(f_top).max(), 1e-300))
    up = Plane([0, 0, 0], [0, 0, 1], name="up")
    down = Plane([0, 0, 0], [0, 0, -1], name="down")
    patch = measure_contact_patch(
        top.mesh,
        SimpleNamespace(contact_force=result.contact_force[top.name]),  # type: ignore[arg-type]
        up,
        center=np.zeros(3),
        fraction=0.25,
        edge_cells=edge_cells,
    )
    patch_other = measure_contact_patch(
        other.mesh,
        SimpleNamespace(contact_force=result.contact_force[other.name]),  # type: ignore[arg-type]
        down,
        center=np.zeros(3),
        fraction=0.25,
        edge_cells=edge_cells,
    )
    hz = hertz_two_bodies(
        patch.force,
        scene.radii[0],
        scene.radii[1],
        scene.moduli[0],
        scene.nu,
        scene.moduli[1],
        scene.nu,
    )
    return patch, patch_other, hz, ar


def hertz_bodies_check(
    scene: HertzScene, settings: ContactSettings | None = None, *, edge_cells: float = 2.0
) -> HertzBodiesCheck:
    """Solve a scene's frame and measure it against Hertz.

    Parameters
    ----------
    scene : HertzScene
    settings : ContactSettings, optional
        The contact algorithm (contact space by default).
    edge_cells : float
        Passed to :func:`contact.cases.hertz.measure_contact_patch`.

    Returns
    -------
    HertzBodiesCheck
    """
    t = time.perf_counter()
    res = solve_frame(list(scene.bodies), list(scene.pairs), (), settings)
    secs = dict(scene.seconds, contact=time.perf_counter() - t)
    patch, other, hz, ar = _measure(scene, res, edge_cells)
    return HertzBodiesCheck(scene, res, patch, other, hz, ar, secs)
