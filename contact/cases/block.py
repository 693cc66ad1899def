"""A block pressed between two rigid frictionless plates, against uniaxial compression.

A prismatic block (sides ``Lx, Ly``, height ``H`` along z) lies between the base ``z = 0``
and a plate on its top face that comes down by ``d``. Frictionless plates leave the
lateral expansion free and the lateral faces carry nothing, so the exact solution is
uniaxial: ``sigma_zz = -E d / H`` everywhere, the plate force ``F = E A d / H`` (``A =
Lx Ly``), independent of Poisson's ratio. Linear elements reproduce a uniform strain
exactly on any conforming mesh whose plate faces are flat, so the discrete force equals
it to round-off: the check is of the contact solver's holding of the body, not of the
discretisation.

The frictionless plates fix neither the in-plane translations nor the rotation about z.
Two ways of holding them are offered (:func:`block_check`):

``"free"``
    A free body (:class:`contact.solver.body.ElasticBody` without supports) between the
    base and the plate, placed by the contacts. With ``hold_rotation=True`` (the library's
    default for a free ball) the solver holds the rotation part of ``u``, in the
    node-count-weighted sense of :func:`fem.rigid_body_modes`, at zero; a uniform strain
    about a block's centre has such a part on an irregular mesh (tetrahedra from
    pytetwild), so a small spurious moment is applied. ``hold_rotation=False`` (the
    default here) lets the plates hold the tilts and leaves the spin free: exact.
``"rollers"``
    The base replaced by rollers (``u_z = 0`` on the bottom face, the same as a fixed
    frictionless plate in full contact), with a minimal in-plane support: ``u_x = u_y = 0``
    at the bottom node nearest the centre and ``u_y = 0`` at the bottom node nearest the
    middle of the edge ``x = Lx``. For a balanced load those three supports carry nothing.

:attr:`BlockCheck.support_force` is what holds the body besides the plates and rollers:
the largest ``|K u - f - f_contact|`` over every other DOF, zero for an exact hold.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

import fem

from ..errors import ContactError
from ..geometry.plane import Plane
from ..solver.body import ElasticBody
from ..solver.results import ContactResult
from .rigid import solve_rigid_contact

__all__ = ["BLOCK_HOLDS", "BLOCK_MESHES", "BlockCheck", "block_check", "block_mesh"]

#: Meshes of :func:`block_mesh`: structured bricks, structured tetrahedra (six per brick,
#: conforming) and unstructured tetrahedra from pytetwild.
BLOCK_MESHES = ("hex", "tet", "tetwild")

#: Ways of holding the block's in-plane rigid modes (see the module notes).
BLOCK_HOLDS = ("free", "rollers")


def block_mesh(
    lengths: tuple[float, float, float] = (1.0, 1.0, 1.0), *, kind: str = "hex", size: float
) -> fem.Mesh:
    """The block ``[0, Lx] x [0, Ly] x [0, H]``.

    Parameters
    ----------
    lengths : tuple of float
        ``(Lx, Ly, H)`` (m).
    kind : {"hex", "tet", "tetwild"}
        See :data:`BLOCK_MESHES`. ``"tetwild"`` fills the box's 12-triangle surface with
        :func:`fem.tetrahedralize`: its nodes on the plate faces follow no grid.
    size : float
        Target cell size (m).

    Returns
    -------
    fem.Mesh
    """
    ln = np.asarray(lengths, dtype=np.float64)
    if ln.shape != (3,) or not (ln > 0).all() or not size > 0:
        raise ContactError(
            f"need three positive lengths and a positive size, got {lengths}, {size}"
        )
    if kind == "tetwild":
        box = fem.box_mesh(ln, (1, 1, 1), element="tetra")
        return fem.tetrahedralize((box.points, box.boundary.faces["triangle"]), size)
    if kind not in ("hex", "tet"):
        raise ContactError(f"mesh kind must be one of {', '.join(BLOCK_MESHES)}, got {kind!r}")
    div = tuple(max(1, round(float(v) / size)) for v in ln)
    return fem.box_mesh(ln, div, element="hexahedron" if kind == "hex" else "tetra")


@dataclass(frozen=True)
class BlockCheck:
    """A block compressed between plates, against ``F = E A d / H``.

    Attributes
    ----------
    mesh : fem.Mesh
    body : ElasticBody
    planes : tuple of Plane
        The plate, then the base (``"free"`` only).
    result : ContactResult
    force : float
        Force on the plate along its motion (N).
    base_force : float
        Force on the base (or the rollers' reactions), downward positive (N).
    exact : float
        ``E A d / H`` (N).
    support_force : float
        Largest force of whatever else holds the body (N); see the module notes.
    seconds : dict of str to float
        ``mesh``, ``body`` and ``contact`` times.
    """

    mesh: fem.Mesh
    body: ElasticBody
    planes: tuple[Plane, ...]
    result: ContactResult
    force: float
    base_force: float
    exact: float
    support_force: float
    seconds: dict[str, float] = field(default_factory=dict)

    @property
    def error(self) -> float:
        """Relative error of the plate's force."""
        return self.force / self.exact - 1.0


def _nearest(points: NDArray, nodes: NDArray[np.int64], target: NDArray) -> int:
    """The node of ``nodes`` nearest to ``target``."""
    return int(nodes[np.argmin(np.linalg.norm(points[nodes] - target, axis=1))])


def _rollers(mesh: fem.Mesh, lengths: NDArray) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """The rollers' DOFs (``u_z`` of the bottom face) and the three in-plane support DOFs."""
    p = mesh.points
    bottom = np.flatnonzero(np.abs(p[:, 2]) <= 1e-9 * lengths.max())
    centre = _nearest(p, bottom, np.array([0.5 * lengths[0], 0.5 * lengths[1], 0.0]))
    edge = _nearest(p, bottom, np.array([lengths[0], 0.5 * lengths[1], 0.0]))
    if edge == centre:
        raise ContactError("the block's base needs two nodes apart in x for its supports")
    return 3 * bottom + 2, np.array([3 * centre, 3 * centre + 1, 3 * edge + 1])


def block_check(
    lengths: tuple[float, float, float] = (1.0, 1.0, 1.0),
    E: float = 1.0,
    nu: float = 0.3,
    *,
    strain: float = 0.01,
    kind: str = "hex",
    size: float = 0.2,
    hold: str = "free",
    hold_rotation: bool = False,
    mesh: fem.Mesh | None = None,
) -> BlockCheck:
    """Press a block between two rigid frictionless plates and compare the force.

    Parameters
    ----------
    lengths : tuple of float
        ``(Lx, Ly, H)`` (m); the plates press along z.
    E, nu : float
        The block's material (Pa, -).
    strain : float
        ``d / H``: the plate's travel over the height, in (0, 0.2).
    kind, size
        The mesh (:func:`block_mesh`).
    hold : {"free", "rollers"}
        How the in-plane rigid modes are held (see the module notes).
    hold_rotation : bool
        ``"free"`` only: passed to :class:`ElasticBody`.
    mesh : fem.Mesh, optional
        A mesh of the block to use instead of :func:`block_mesh`'s (``kind`` and ``size``
        are then ignored): one pytetwild mesh for several checks.

    Returns
    -------
    BlockCheck
    """
    if hold not in BLOCK_HOLDS:
        raise ContactError(f"hold must be one of {', '.join(BLOCK_HOLDS)}, got {hold!r}")
    if not 0 < strain < 0.2:
        raise ContactError(f"strain must lie in (0, 0.2), got {strain!r}")
    ln = np.asarray(lengths, dtype=np.float64)
    t0 = time.perf_counter()
    if mesh is None:
        mesh = block_mesh(tuple(ln), kind=kind, size=size)
    t1 = time.perf_counter()
    mat = fem.LinearElastic(E, nu)
    d = strain * ln[2]
    plate = Plane([0, 0, ln[2]], [0, 0, -1], motion=[0, 0, -d], name="plate")
    if hold == "free":
        body = ElasticBody("block", mesh, mat, hold_rotation=hold_rotation)
        planes: tuple[Plane, ...] = (plate, Plane([0, 0, 0], [0, 0, 1], name="base"))
        rollers = np.zeros(0, dtype=np.int64)
    else:
        rollers, support = _rollers(mesh, ln)
        body = ElasticBody("block", mesh, mat, prescribed=np.concatenate([rollers, support]))
        planes = (plate,)
    t2 = time.perf_counter()
    result = solve_rigid_contact(body, planes)
    t3 = time.perf_counter()
    r = body.stiffness @ result.displacement.ravel() - body.loads - result.contact_force.ravel()
    other = np.ones(r.size, dtype=bool)
    other[rollers] = False
    force = float(result.obstacle_forces["plate"][2])
    base = -float(result.obstacle_forces["base"][2]) if hold == "free" else float(r[rollers].sum())
    return BlockCheck(
        mesh,
        body,
        planes,
        result,
        force,
        base,
        E * ln[0] * ln[1] * d / ln[2],
        float(np.abs(r[other]).max()),
        {"mesh": t1 - t0, "body": t2 - t1, "contact": t3 - t2},
    )
