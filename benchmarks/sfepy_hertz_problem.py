"""SfePy's side of the Hertz comparison: the press set up as a SfePy problem, solved, measured.

:func:`solve_sfepy_press` hands a mesh (bricks or tetrahedra), our body's material and
prescribed DOFs and a rigid plane to SfePy (``dw_lin_elastic`` + ``dw_contact_plane``,
``nls.newton``) and measures its contact patch as ours is measured;
:func:`solve_sfepy_hertz` does so for the scene of a Hertz check. Used by
:mod:`benchmarks.sfepy_hertz` and :mod:`benchmarks.sfepy_patch`.
"""

from __future__ import annotations

import importlib.metadata
import io
import math
import time
from collections.abc import Callable
from contextlib import redirect_stderr, redirect_stdout
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

import fem
from contact.cases.hertz import (
    ContactPatch,
    HertzCheck,
    HertzErrors,
    HertzSolution,
    hertz_sphere_on_plane,
    measure_contact_patch,
)
from contact.geometry import Plane
from contact.solver import ElasticBody

__all__ = [
    "CONTACT_ORDER",
    "SFEPY_CELLS",
    "SfepyHertz",
    "sfepy_available",
    "sfepy_version",
    "solve_sfepy_hertz",
    "solve_sfepy_press",
]

#: Integral order of the contact term on the faces (3: 2x2 Gauss on a quad).
CONTACT_ORDER = 3

#: SfePy's names of the cell types it is handed (the node order is VTK's in both codes).
SFEPY_CELLS = {"hexahedron": "3_8", "tetra": "3_4"}


def sfepy_available() -> bool:
    """Whether SfePy can be imported here (the optional ``benchmarks`` extra)."""
    try:
        _sfepy()
    except ImportError:
        return False
    return True


def _sfepy() -> dict[str, Any]:
    """Import the parts of SfePy used here, its console output silenced."""
    sink = io.StringIO()
    with redirect_stdout(sink), redirect_stderr(sink):
        from sfepy.base.base import output

        output.set_output(quiet=True)
        from sfepy.discrete import (
            Equation,
            Equations,
            FieldVariable,
            Function,
            Functions,
            Integral,
            Material,
            Problem,
        )
        from sfepy.discrete.conditions import Conditions, EssentialBC
        from sfepy.discrete.fem import FEDomain, Field, Mesh
        from sfepy.mechanics.matcoefs import stiffness_from_youngpoisson
        from sfepy.solvers.ls import PyPardisoSolver, ScipyDirect
        from sfepy.solvers.nls import Newton
        from sfepy.terms import Term
    return {
        "Conditions": Conditions,
        "Equation": Equation,
        "Equations": Equations,
        "EssentialBC": EssentialBC,
        "FEDomain": FEDomain,
        "Field": Field,
        "FieldVariable": FieldVariable,
        "Function": Function,
        "Functions": Functions,
        "Integral": Integral,
        "Material": Material,
        "Mesh": Mesh,
        "Newton": Newton,
        "Problem": Problem,
        "Term": Term,
        "stiffness": stiffness_from_youngpoisson,
        "ls": {"pypardiso": PyPardisoSolver, "scipy_direct": ScipyDirect},
    }


def sfepy_version() -> str:
    """SfePy's installed version, or ``"not installed"``."""
    try:
        return importlib.metadata.version("sfepy")
    except importlib.metadata.PackageNotFoundError:
        return "not installed"


@dataclass
class SfepyHertz(HertzErrors):
    """SfePy's solve of a Hertz scene, measured as ours is.

    Attributes
    ----------
    penalty : float
        Penalty stiffness ``k`` of the contact plane (Pa/m).
    linear_solver : str
        SfePy's linear solver (``"pypardiso"`` or ``"scipy_direct"``).
    displacement : ndarray, shape (N, 3)
    contact_force : ndarray, shape (N, 3)
        Nodal reactions ``K u`` of the contact nodes along the plane's normal (N), zero
        elsewhere.
    equilibrium : float
        Largest difference of those reactions and the penalty term's nodal forces
        (normal components), relative to the largest nodal force.
    patch : ContactPatch
        The table's patch, forces of the whole patch.
    hertz : HertzSolution
        Hertz for SfePy's own total force.
    iterations : int
        Newton iterations.
    converged : bool
        Newton met its tolerance.
    seconds : dict of str to float
        ``setup`` (mesh arrays to problem), ``matrix`` (tangent assembly), ``solve``
        (linear solves), ``residual``, ``newton`` (the whole Newton solve) and
        ``total`` (set-up and Newton).
    """

    penalty: float
    linear_solver: str
    displacement: NDArray[np.float64]
    contact_force: NDArray[np.float64]
    equilibrium: float
    patch: ContactPatch
    hertz: HertzSolution
    iterations: int
    converged: bool
    seconds: dict[str, float] = field(default_factory=dict)


@dataclass
class _Forces:
    """The one field of a contact result that :func:`measure_contact_patch` reads."""

    contact_force: NDArray[np.float64]


def _perpendiculars(n: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    """Two unit vectors perpendicular to the unit vector ``n`` and to each other."""
    t = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    t /= np.linalg.norm(t)
    return t, np.cross(n, t)


def solve_sfepy_hertz(
    check: HertzCheck,
    penalty: float,
    *,
    linear_solver: str = "pypardiso",
    order: int = CONTACT_ORDER,
    max_iterations: int = 50,
) -> SfepyHertz:
    """Solve the scene of a Hertz check with SfePy's penalty contact plane and measure it.

    :func:`solve_sfepy_press` on the check's mesh, body and table.

    Parameters
    ----------
    check : HertzCheck
        Our solve of the scene (octant model: one plane).
    penalty : float
        Penalty stiffness ``k`` (Pa/m): traction ``k d`` at a penetration ``d``.
    linear_solver : {"pypardiso", "scipy_direct"}
        SfePy's linear solver in each Newton step.
    order : int
        Integral order of the contact term on the faces.
    max_iterations : int
        Newton's limit.

    Returns
    -------
    SfepyHertz
    """
    if len(check.planes) != 1:
        raise ValueError("solve_sfepy_hertz takes the octant model (one plane)")
    return solve_sfepy_press(
        check.mesh,
        check.body,
        check.planes[0],
        penalty,
        radius=check.hertz.radius,
        linear_solver=linear_solver,
        order=order,
        max_iterations=max_iterations,
    )


def solve_sfepy_press(
    mesh: fem.Mesh,
    body: ElasticBody,
    plane: Plane,
    penalty: float,
    *,
    radius: float,
    linear_solver: str = "pypardiso",
    order: int = CONTACT_ORDER,
    max_iterations: int = 50,
    fraction: float = 0.25,
    edge_cells: float = 2.0,
) -> SfepyHertz:
    """Solve an octant of a ball on a rigid plane with SfePy's penalty contact and measure it.

    The mesh (bricks ``3_8`` or tetrahedra ``3_4``: one cell type, VTK's node order,
    SfePy's too), the material and the prescribed DOFs of ``body`` and the plane are handed
    to SfePy as they are. The ball's centre is ``(0, 0, radius)``, the load axis the z axis.
    Contact is possible on the boundary faces with every node on the ball's sphere (those
    of the symmetry planes are left out), as our solver's candidates; the plane is bounded
    by a square of 8 R about the ball, wider than any of it.

    Parameters
    ----------
    mesh : fem.Mesh
        The body's mesh.
    body : ElasticBody
        Our body on it: its material and ``fixed_dofs``.
    plane : Plane
        The rigid plane, moved by its ``motion``.
    penalty : float
        Penalty stiffness ``k`` (Pa/m): traction ``k d`` at a penetration ``d``.
    radius : float
        The ball's radius (m).
    linear_solver : {"pypardiso", "scipy_direct"}
        SfePy's linear solver in each Newton step.
    order : int
        Integral order of the contact term on the faces.
    max_iterations : int
        Newton's limit.
    fraction, edge_cells : float
        Passed to :func:`~contact.cases.hertz.measure_contact_patch`.

    Returns
    -------
    SfepyHertz
    """
    sf = _sfepy()
    kinds = [k for k in SFEPY_CELLS if k in mesh.cells]
    if len(kinds) != 1 or len(mesh.cells) != 1:
        raise ValueError(f"one cell type of {sorted(SFEPY_CELLS)} expected, got {list(mesh.cells)}")
    mat = body.materials
    center = np.array([0.0, 0.0, radius])
    cells = mesh.cells[kinds[0]]
    fixed = body.fixed_dofs.reshape(-1, 3)

    t0 = time.perf_counter()
    smesh = sf["Mesh"].from_data(
        "ball",
        mesh.points,
        np.zeros(mesh.n_points, dtype=np.int32),
        [cells.astype(np.int32)],
        [np.zeros(len(cells), dtype=np.int32)],
        [SFEPY_CELLS[kinds[0]]],
    )
    domain = sf["FEDomain"]("domain", smesh)
    omega = domain.create_region("Omega", "all")

    def on_sphere(coors: NDArray, domain: Any = None) -> NDArray[np.int64]:
        d = np.linalg.norm(coors - center, axis=1)
        return np.flatnonzero(d >= radius * (1.0 - 1e-9))

    def held(k: int) -> Callable[..., NDArray[np.int64]]:
        return lambda coors, domain=None: np.flatnonzero(fixed[:, k])

    funs = sf["Functions"](
        [sf["Function"]("on_sphere", on_sphere)]
        + [sf["Function"](f"held{k}", held(k)) for k in range(3)]
    )
    surface = domain.create_region("Contact", "vertices by on_sphere", "facet", functions=funs)
    ebcs = []
    for k in range(3):
        if fixed[:, k].any():
            reg = domain.create_region(f"Held{k}", f"vertices by held{k}", "vertex", functions=funs)
            ebcs.append(sf["EssentialBC"](f"held{k}", reg, {f"u.{k}": 0.0}))
    fld = sf["Field"].from_args("displacement", np.float64, "vector", omega, approx_order=1)
    u = sf["FieldVariable"]("u", "unknown", fld)
    v = sf["FieldVariable"]("v", "test", fld, primary_var_name="u")
    solid = sf["Material"]("solid", D=sf["stiffness"](3, mat.E, mat.nu))
    # SfePy's normal points into the obstacle, ours to the free side
    anchor = plane.point + plane.motion
    t1, t2 = _perpendiculars(plane.normal)
    span = 4.0 * radius
    bounds = np.array(
        [anchor + span * (a * t1 + b * t2) for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    )
    cp = sf["Material"](
        "cp",
        values={
            "f": np.array([[penalty, 0.0]]),
            ".n": -plane.normal,
            ".a": anchor,
            ".bs": bounds,
        },
    )
    vol = sf["Integral"]("iv", order=2)
    surf = sf["Integral"]("ic", order=order)
    elastic = sf["Term"].new("dw_lin_elastic(solid.D, v, u)", vol, omega, solid=solid, v=v, u=u)
    contact = sf["Term"].new(
        "dw_contact_plane(cp.f, cp.n, cp.a, cp.bs, v, u)", surf, surface, cp=cp, v=v, u=u
    )
    eqs = sf["Equations"]([sf["Equation"]("balance", elastic + contact)])
    status: dict[str, Any] = {}
    nls = sf["Newton"](
        {
            "i_max": max_iterations,
            "eps_a": 1e-13,
            "eps_r": 1e-10,
            "eps_mode": "or",
            "ls_on": 2.0,
        },
        lin_solver=sf["ls"][linear_solver]({}),
        status=status,
    )
    pb = sf["Problem"]("hertz", equations=eqs)
    pb.set_bcs(ebcs=sf["Conditions"](ebcs))
    pb.set_solver(nls)
    t_setup = time.perf_counter()
    pb.solve(save_results=False)
    t_end = time.perf_counter()

    disp = np.asarray(pb.get_variables()["u"](), dtype=np.float64).reshape(-1, 3).copy()
    pb.remove_bcs()  # the weak forms below over every DOF, held ones included
    ku = pb.evaluate(
        "dw_lin_elastic.2.Omega(solid.D, v, u)", mode="weak", dw_mode="vector", solid=solid
    ).reshape(-1, 3)
    term = -pb.evaluate(
        f"dw_contact_plane.{order}.Contact(cp.f, cp.n, cp.a, cp.bs, v, u)",
        mode="weak",
        dw_mode="vector",
        cp=cp,
    ).reshape(-1, 3)
    # normal components: nodes on the symmetry planes also carry their reactions there
    fn_term = term @ plane.normal
    fn_ku = ku @ plane.normal
    on = np.flatnonzero(fn_term > 0)
    force = np.zeros_like(ku)
    force[on] = fn_ku[on, None] * plane.normal
    scale = float(np.abs(fn_term).max()) or 1.0
    equilibrium = float(np.abs(fn_ku[on] - fn_term[on]).max()) / scale if on.size else math.nan
    patch = measure_contact_patch(
        mesh,
        _Forces(force),  # type: ignore[arg-type]
        plane,
        center=np.zeros(3),
        fraction=fraction,
        edge_cells=edge_cells,
    )
    hz = hertz_sphere_on_plane(patch.force, radius, mat.E, mat.nu)
    ts = status.get("time_stats", {})
    secs = {
        "setup": t_setup - t0,
        "matrix": float(ts.get("matrix", math.nan)),
        "solve": float(ts.get("solve", math.nan)),
        "residual": float(ts.get("residual", math.nan)),
        "newton": t_end - t_setup,
        "total": t_end - t0,
    }
    return SfepyHertz(
        penalty=penalty,
        linear_solver=linear_solver,
        displacement=disp,
        contact_force=force,
        equilibrium=equilibrium,
        patch=patch,
        hertz=hz,
        iterations=int(status.get("n_iter", -1)),
        converged=status.get("condition", 1) == 0,
        seconds=secs,
    )
