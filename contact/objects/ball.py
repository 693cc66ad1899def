"""The ball: solid, or a rubber envelope under internal pressure, as tets or 8-node bricks.

A :class:`BallSpec` says what ball a scene wants (the ``[ball]`` table of a scene file);
:func:`make_ball` meshes it, or reads and checks a mesh file, and returns a :class:`Ball`:
the mesh, its material, its inner surface (where the pressure acts), its outer surface
(what can touch) and the pressure load. Inner and outer faces are told apart by the
radius of their centroids against the mid-wall radius. An external force and moment on
the ball in time (``ball.load``) is the spec's too (:meth:`BallSpec.load_at`); the run
spreads it over the placed ball's nodes.
"""

from __future__ import annotations

import logging
import math
import os
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

import fem

from ..errors import BallError, ObjectError
from .cache import cached

__all__ = [
    "LOCKING_NOTE",
    "LOCKING_NU",
    "MAX_LOAD_FORCE",
    "MAX_LOAD_MOMENT",
    "RADIUS_TOL",
    "STRAIN_WARN",
    "Ball",
    "BallError",
    "BallSpec",
    "make_ball",
    "nodal_pressure",
]

#: Boundary nodes of a ball read from a file must lie within this fraction of the radius
#: of their sphere (and within a quarter of a hollow ball's wall thickness).
RADIUS_TOL = 0.02
#: Linear tetrahedra with a Poisson's ratio above this lock (too stiff, as Lame's thick
#: sphere shows): a tet ball then takes averaged nodal pressures, and the hand's flesh warns.
LOCKING_NU = 0.45
#: A hollow ball whose internal pressure alone strains its wall by more than this (Lame's
#: thick sphere) is beyond the small strains linear elasticity describes: a warning.
STRAIN_WARN = 0.05
#: What plain linear tetrahedra do near nu = 1/2, for the warnings (ball and flesh).
LOCKING_NOTE = (
    "they lock as nu nears 1/2 and come out too stiff (on Lame's thick sphere 7 % at "
    "nu = 0.45, 16 % at 0.49)"
)


def nodal_pressure(
    tets: bool,
    nu: float,
    asked: bool | None,
    where: str,
    remedy: str = "averaged nodal pressures (the default) do not lock",
) -> bool:
    """Whether a body takes averaged nodal pressures: on tetrahedra whose ``nu`` would lock.

    ``asked`` is the scene's ``nodal_pressure`` (None: not given, then chosen by ``nu``).
    Refused on linear tetrahedra above :data:`LOCKING_NU`: a warning that they lock,
    naming the keys under ``where`` (``"ball.material"``, ``"hand.flesh"``...) and the
    ``remedy``.
    """
    if asked is None:
        return tets and nu > LOCKING_NU
    if not asked and tets and nu > LOCKING_NU:
        table = where.rsplit(".", 1)[0]
        warnings.warn(
            f"{where}.nu = {nu:g} on linear tetrahedra with {table}.nodal_pressure = false: "
            f"{LOCKING_NOTE}; {remedy}",
            stacklevel=3,
        )
    return bool(asked)


#: The largest external force (N) ``ball.load`` may give, and the scene's bound on any force
#: (:data:`contact.scene.model.MAX_FORCE`): far above a grip.
MAX_LOAD_FORCE = 1.0e4
#: The largest external moment (N m) ``ball.load`` may give: that force at 0.1 m, a lever
#: longer than any ball a hand holds.
MAX_LOAD_MOMENT = 1.0e3
#: How a ``ball.load`` key is written.
_LOAD_FORM = "[t, fx, fy, fz, mx, my, mz]"
log = logging.getLogger(__name__)
_ICO_EDGE = 4.0 / math.sqrt(10.0 + 2.0 * math.sqrt(5.0))  # icosahedron edge / circumradius


def _number(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise BallError(f"ball.{name} = {value!r}: must be a number")
    if not math.isfinite(float(value)):
        raise BallError(f"ball.{name} = {value!r}: must be finite")
    return float(value)


def _load_keys(load: object) -> tuple[tuple[float, ...], ...]:
    """``ball.load`` checked: keys of 7 finite numbers, times increasing, bounded magnitudes."""
    if isinstance(load, (str, bytes)) or not isinstance(load, (list, tuple)):
        raise BallError(f"ball.load = {load!r}: must be a list of {_LOAD_FORM}")
    keys: list[tuple[float, ...]] = []
    for j, key in enumerate(load):
        where = f"ball.load[{j}] = {key!r}"
        if isinstance(key, (str, bytes)) or not isinstance(key, (list, tuple)) or len(key) != 7:
            raise BallError(f"{where}: must be 7 numbers {_LOAD_FORM}")
        if any(isinstance(v, bool) or not isinstance(v, (int, float, np.number)) for v in key):
            raise BallError(f"{where}: must be 7 numbers {_LOAD_FORM}")
        k = tuple(float(v) for v in key)
        if not all(math.isfinite(v) for v in k):
            raise BallError(f"{where}: must be finite")
        if keys and not k[0] > keys[-1][0]:
            raise BallError(f"{where}: times must increase (previous {keys[-1][0]:g})")
        if math.hypot(*k[1:4]) > MAX_LOAD_FORCE:
            raise BallError(f"{where}: the force must be at most {MAX_LOAD_FORCE:g} N")
        if math.hypot(*k[4:7]) > MAX_LOAD_MOMENT:
            raise BallError(f"{where}: the moment must be at most {MAX_LOAD_MOMENT:g} N m")
        keys.append(k)
    return tuple(keys)


@dataclass(frozen=True)
class BallSpec:
    """A ball, validated on construction (SI units).

    Parameters
    ----------
    radius : float
        Outer radius (m), positive.
    kind : {"solid", "hollow"}
        A solid ball, or a hollow envelope of wall ``thickness`` under internal ``pressure``.
    thickness : float, optional
        Wall thickness (m) of a hollow ball, in (0, radius); not given for a solid one.
    pressure : float
        Internal pressure (Pa) on a hollow ball's inner surface; 0 for a solid one.
    element : {"tet", "hex"}
        Tetrahedra (pytetwild) or 8-node bricks (cubed sphere). Ignored for a mesh file.
    mesh_size : float, optional
        Target element edge length (m), in (0, radius]. Exactly one of ``mesh_size`` and
        ``mesh`` is given.
    mesh : str or path-like, optional
        A volume mesh file to use instead, or a closed surface file to fill with
        tetrahedra; it must be this ball (see :func:`make_ball`).
    center : tuple of 3 floats
        Centre (m).
    E, nu, density : float
        Young's modulus (Pa), Poisson's ratio and density (kg/m^3).
    nodal_pressure : bool or None
        Tetrahedra with averaged nodal pressures (Bonet and Burton 1998: no volumetric
        locking, the factorisation three to four times dearer; :mod:`fem.nodalpressure`).
        None (default): when the mesh is tetrahedra and ``nu`` is above
        :data:`LOCKING_NU`. Bricks are B-bar whatever it says.
    load : tuple of 7-tuples of float
        An external force and moment on the ball in time, ``(t, fx, fy, fz, mx, my, mz)``
        keys (s, N, N m), times increasing, piecewise linear between keys and constant
        outside (:meth:`load_at`); in the scene's frame, the moment about the ball's centre
        where the ball is placed at ``t``. Forces up to :data:`MAX_LOAD_FORCE`, moments up
        to :data:`MAX_LOAD_MOMENT`. Empty (default): no load.
    model : str
        ``"linear"`` (default) or ``"neo-hookean"``: solved at finite strain, a hollow
        ball's pressure following its deformed cavity.

    Raises
    ------
    BallError
        Naming the field and value, e.g. ``ball.thickness = 0.05: must be below the
        radius 0.035``.
    """

    radius: float
    kind: str = "solid"
    thickness: float | None = None
    pressure: float = 0.0
    element: str = "tet"
    mesh_size: float | None = None
    mesh: str | os.PathLike[str] | None = None
    center: tuple[float, float, float] = (0.0, 0.0, 0.0)
    E: float = 1.0e6
    nu: float = 0.45
    density: float = 1100.0
    nodal_pressure: bool | None = None
    load: tuple[tuple[float, ...], ...] = ()
    model: str = "linear"

    def __post_init__(self) -> None:
        r = _number("radius", self.radius)
        if r <= 0:
            raise BallError(f"ball.radius = {self.radius!r}: must be positive")
        for name, allowed in (("kind", ("solid", "hollow")), ("element", ("tet", "hex"))):
            if getattr(self, name) not in allowed:
                raise BallError(f"ball.{name} = {getattr(self, name)!r}: must be one of {allowed}")
        p = _number("pressure", self.pressure)
        if self.kind == "solid":
            if self.thickness is not None:
                raise BallError(f"ball.thickness = {self.thickness!r}: only a hollow ball has one")
            if p != 0.0:
                raise BallError(f"ball.pressure = {self.pressure!r}: only a hollow ball has one")
        else:
            if self.thickness is None:
                raise BallError("ball.thickness: a hollow ball needs a wall thickness")
            t = _number("thickness", self.thickness)
            if not 0 < t < r:
                why = "must be positive" if t <= 0 else f"must be below the radius {r}"
                raise BallError(f"ball.thickness = {self.thickness!r}: {why}")
        if self.model not in ("linear", "neo-hookean"):
            raise BallError(
                f"ball.material.model = {self.model!r}: must be linear or neo-hookean"
            )
        if self.nodal_pressure not in (None, True, False):
            raise BallError(
                f"ball.nodal_pressure = {self.nodal_pressure!r}: must be true, false or absent"
            )
        if (self.mesh_size is None) == (self.mesh is None):
            raise BallError(
                f"ball.mesh_size = {self.mesh_size!r}, ball.mesh = {self.mesh!r}: give exactly one"
            )
        if self.mesh_size is not None:
            h = _number("mesh_size", self.mesh_size)
            if not 0 < h <= r:
                raise BallError(
                    f"ball.mesh_size = {self.mesh_size!r}: must be positive and at most the "
                    f"radius {r}"
                )
        c = np.asarray(self.center, dtype=object).ravel()
        if c.shape != (3,):
            raise BallError(f"ball.center = {self.center!r}: must be 3 numbers")
        object.__setattr__(self, "center", tuple(_number("center", v) for v in c))
        try:
            self.material  # noqa: B018  (validates E, nu and density)
        except fem.MaterialError as exc:
            raise BallError(f"ball.material.{exc}") from None
        object.__setattr__(self, "load", _load_keys(self.load))

    def load_at(self, time: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The external force (N) and moment (N m) on the ball at ``time``, shapes (3,).

        Piecewise linear between the ``load`` keys, constant outside; zero without keys.
        """
        if not self.load:
            return np.zeros(3), np.zeros(3)
        k = np.array(self.load)
        fm = np.array([np.interp(time, k[:, 0], k[:, i]) for i in range(1, 7)])
        return fm[:3], fm[3:]

    @property
    def inner_radius(self) -> float:
        """Radius of the cavity (m); 0 for a solid ball."""
        return self.radius - self.thickness if self.kind == "hollow" else 0.0  # type: ignore[operator]

    @property
    def material(self) -> fem.LinearElastic:
        """The ball's material."""
        return fem.LinearElastic(self.E, self.nu, self.density)

    @property
    def pressure_strain(self) -> float:
        """The largest strain the internal pressure alone gives the wall (0 if solid).

        Lame's thick sphere: the hoop strain at the cavity, ``u(a) / a`` with ``u(r) = p
        a^3 / (E (b^3 - a^3)) ((1 - 2 nu) r + (1 + nu) b^3 / (2 r^2))``.
        """
        if self.kind != "hollow" or self.pressure == 0.0:
            return 0.0
        a, b, nu = self.inner_radius, self.radius, self.nu
        c = self.pressure * a**3 / (self.E * (b**3 - a**3))
        return abs(c * ((1 - 2 * nu) + (1 + nu) * b**3 / (2 * a**3)))


@dataclass(frozen=True)
class Ball:
    """A meshed ball.

    Attributes
    ----------
    spec : BallSpec
    mesh : fem.Mesh
    material : fem.LinearElastic
    inner : fem.BoundaryFaces
        Faces of the cavity, oriented into it (empty for a solid ball).
    outer : fem.BoundaryFaces
        Faces of the outer sphere: the ones that can touch.
    outer_nodes : ndarray of int
        Sorted nodes of ``outer``.
    loads : ndarray, shape (3N,)
        Nodal forces of the internal pressure (zero for a solid ball); self-balanced.
    nodal_pressure : bool
        Its tetrahedra with averaged nodal pressures (``spec.nodal_pressure`` resolved).
    """

    spec: BallSpec
    mesh: fem.Mesh
    material: fem.LinearElastic
    inner: fem.BoundaryFaces
    outer: fem.BoundaryFaces
    outer_nodes: NDArray[np.int64]
    loads: NDArray[np.float64]
    nodal_pressure: bool = False


def _refinement(radius: float, size: float) -> int:
    """Icosphere subdivisions whose edges are no longer than ``size`` (2 to 6)."""
    return min(6, max(2, math.ceil(math.log2(_ICO_EDGE * radius / size))))


def _generate(spec: BallSpec) -> fem.Mesh:
    r, a, h, c = spec.radius, spec.inner_radius, float(spec.mesh_size), spec.center  # type: ignore[arg-type]
    if spec.element == "hex":
        # an even number of cells along each cube edge puts a node at the six poles, where a
        # plate or a table first touches (with an odd number the facets there sit below the
        # sphere and a small press misses every node)
        n = 2 * math.ceil(0.25 * math.pi * r / h - 1e-9)
        if spec.kind == "solid":
            return fem.ball_mesh(r, h, divisions=n, center=c)
        layers = max(2, math.ceil((r - a) / h - 1e-9))
        return fem.shell_mesh(a, r, h, divisions=n, layers=layers, center=c)
    pts, tri = fem.sphere_surface(r, c, _refinement(r, h))
    if spec.kind == "hollow":
        if h > 0.5 * (r - a):
            warnings.warn(
                f"ball.mesh_size = {h} exceeds half the wall thickness ({r - a:.6g} / 2): the "
                "tet wall may be one element thick and too stiff in bending",
                stacklevel=3,
            )
        p2, t2 = fem.sphere_surface(a, c, _refinement(a, h))
        pts, tri = np.concatenate([pts, p2]), np.concatenate([tri, t2[:, ::-1] + len(pts)])
    # fTetWild is not deterministic: the fill is kept, so that every run meshes alike
    content = np.ascontiguousarray(pts, np.float64).tobytes() + tri.astype(np.int64).tobytes()
    return cached(
        Path(f"ball ({spec.kind}, tetrahedra)"), f"mesh_size {h!r}",
        lambda: fem.tetrahedralize((pts, tri), h), (pts, tri), content=content,
    )  # fmt: skip


def _split(mesh: fem.Mesh, spec: BallSpec) -> tuple[fem.BoundaryFaces, fem.BoundaryFaces]:
    """Inner and outer boundary faces, by centroid radius against the mid-wall radius."""
    mid = 0.5 * (spec.radius + spec.inner_radius) if spec.kind == "hollow" else 0.0
    c = np.asarray(spec.center)
    rad = {
        k: np.linalg.norm(x - c, axis=1)
        for k, x in mesh.face_centroids(mesh.boundary.faces).items()
    }
    inner = mesh.boundary.subset({k: v < mid for k, v in rad.items()})
    return inner, mesh.boundary.subset({k: v >= mid for k, v in rad.items()})


def _check_file(mesh: fem.Mesh, spec: BallSpec, path: Path) -> None:
    """Refuse a mesh that is not this ball: boundary node radii off their sphere."""
    r, a = spec.radius, spec.inner_radius
    tol = RADIUS_TOL * r if spec.kind == "solid" else min(RADIUS_TOL * r, 0.25 * (r - a))
    nodes = mesh.boundary.nodes
    rad = np.linalg.norm(mesh.points[nodes] - np.asarray(spec.center), axis=1)
    out = rad >= 0.5 * (r + a) if spec.kind == "hollow" else np.ones(len(rad), bool)
    where = f"ball.mesh = '{path}'"
    if not out.any() or np.abs(rad[out] - r).max() > tol:
        lo, hi = (rad[out].min(), rad[out].max()) if out.any() else (rad.min(), rad.max())
        raise BallError(
            f"{where}: not a {spec.kind} ball of radius {r} about {list(spec.center)}: "
            f"{'outer ' if spec.kind == 'hollow' else ''}boundary node radii range from "
            f"{lo:.6g} to {hi:.6g} (tolerance {tol:.3g})"
        )
    if spec.kind == "hollow" and (out.all() or np.abs(rad[~out] - a).max() > tol):
        got = "none" if out.all() else f"{rad[~out].min():.6g} to {rad[~out].max():.6g}"
        raise BallError(
            f"{where}: no inner surface of radius {a} (wall {spec.thickness}): inner boundary "
            f"node radii {got} (tolerance {tol:.3g})"
        )


def _read_file(path: Path) -> fem.Mesh:
    """The ball's volume mesh from a file; a closed surface is filled with tetrahedra."""
    from .formats import SURFACE_FORMATS, read_surface_file

    surface: Any = path
    if path.suffix.lower() in SURFACE_FORMATS:  # read and checked here, not by meshio or VTK
        try:
            surface = read_surface_file(path, f"ball.mesh = '{path}': ")
        except ObjectError as exc:
            raise BallError(str(exc)) from None
    else:
        try:
            return fem.read_mesh(path)
        except fem.NoVolumeCellsError as exc:
            if not exc.surface:
                raise
    log.info("ball.mesh = '%s' is a surface: tetrahedralised at its mean edge length", path)
    try:
        return fem.tetrahedralize(surface, None)
    except fem.MeshError as exc:
        raise BallError(f"ball.mesh = '{path}' is a surface that cannot be filled: {exc}") from None


def make_ball(spec: BallSpec) -> Ball:
    """Mesh a ball, or read and check its mesh file, and set up its pressure load.

    Bricks come from :func:`fem.ball_mesh` (solid; ``ceil(pi R / (2 h))`` cells along
    each cube edge rounded up to an even number, so that surface edges are about
    ``h = mesh_size`` long and a node sits at each pole) or
    :func:`fem.shell_mesh` (hollow, with ``ceil(thickness / h)``, but at least 2,
    elements through the wall, so that the wall can bend). Tets come from
    :func:`fem.tetrahedralize` of an icosphere whose edges are no longer than ``h``
    (hollow: with the inner sphere flipped inward to make the cavity); a hollow tet ball
    warns when ``h`` exceeds half the wall thickness. Any ball warns when its pressure
    alone strains the wall beyond :data:`STRAIN_WARN`. Tetrahedra with ``nu`` above
    :data:`LOCKING_NU` take averaged nodal pressures unless the spec says not (then a
    warning: they lock). A mesh file is read with
    :func:`fem.read_mesh` (a closed surface file is filled by :func:`fem.tetrahedralize`
    at its own mean edge length) and must be the ball of the spec: its outer (and for a hollow
    ball its inner) boundary nodes within :data:`RADIUS_TOL` of the radius about the
    centre.

    Parameters
    ----------
    spec : BallSpec

    Returns
    -------
    Ball

    Raises
    ------
    BallError
        A mesh file that is not this ball, naming the file and the radii measured.
    fem.MeshError
        A mesh file that cannot be read, or a failed meshing.
    """
    if spec.mesh is not None:
        path = Path(spec.mesh)
        mesh = _read_file(path)
        _check_file(mesh, spec, path)
    else:
        mesh = _generate(spec)
    nodal = nodal_pressure(
        "tetra" in mesh.cells,
        spec.nu,
        spec.nodal_pressure,
        "ball.material",
        'averaged nodal pressures (the default) or element = "hex" (B-bar bricks) do not '
        "lock",
    )
    if nodal and spec.nodal_pressure is None:
        log.info(
            "ball: nu = %g on linear tetrahedra: averaged nodal pressures (no locking)", spec.nu
        )
    strain = spec.pressure_strain
    if strain > STRAIN_WARN and spec.model == "linear":
        warnings.warn(
            f"ball.pressure = {spec.pressure:g} Pa strains the wall by {100 * strain:.3g} % "
            f"on its own (Lame's thick sphere, E = {spec.E:g} Pa): beyond the small strains "
            "linear elasticity describes, so its shape, stress and contact forces are "
            "qualitative",
            stacklevel=2,
        )
    inner, outer = _split(mesh, spec)
    loads = fem.pressure_load(mesh, inner, spec.pressure)
    return Ball(spec, mesh, spec.material, inner, outer, outer.nodes, loads, bool(nodal))
