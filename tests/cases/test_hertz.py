"""Hertz verification of the rigid-plane contact solver (part of #6).

An elastic ball (R = 1 m, E = 1 Pa, nu = 0.3: HEX8 locks near nu = 0.5, so a compressible
material is used for the check) is pressed between two rigid frictionless plates, each
advancing by 0.01 R, which gives a contact radius a of about 0.1 R (small strain, the
regime of Hertz's theory). The mesh is :func:`fem.generators.graded_ball_mesh`: fine
cubes at the poles, coarse elsewhere. Unless named "full", the model is the octant
``x, y >= 0, z <= R`` with its three symmetry planes held normally (exact for this
symmetric problem; checked against the full ball below) and one plate, the table.

Radius and peak pressure come from the solver's nodal contact forces and the tributary
areas (see :mod:`contact.cases.hertz`) and are compared with Hertz for the solver's own total
force F: a = (3 F R / 4 E*)^(1/3), p0 = (6 F E*^2 / (pi^3 R^2))^(1/3), E* = E / (1 - nu^2).
"""

import math

import numpy as np
import pytest

import fem
from contact.cases.hertz import (
    effective_modulus,
    hertz_check,
    hertz_sphere_on_plane,
    interpolation_excess,
    measure_contact_patch,
    moment_radius,
)
from contact.errors import ContactError
from contact.geometry.plane import Plane
from contact.solver.results import ContactResult
from fem.generators import graded_ball_mesh, graded_spacing

R, E, NU, DEPTH = 1.0, 1.0, 0.3, 0.01


@pytest.fixture(scope="module")
def test_sized():
    """About 9k DOFs, 3.4 cells across the contact radius; well under a second."""
    return hertz_check(R, E, NU, depth=DEPTH, fine_size=0.03)


# --- analytic side ----------------------------------------------------------------------


def test_hertz_formulas():
    hz = hertz_sphere_on_plane(2.0, 0.5, 3.0, 0.25)
    es = 3.0 / (1 - 0.25**2)
    assert hz.modulus == pytest.approx(es, rel=1e-14)
    assert hz.contact_radius == pytest.approx((3 * 2.0 * 0.5 / (4 * es)) ** (1 / 3), rel=1e-14)
    assert hz.peak_pressure == pytest.approx(
        (6 * 2.0 * es**2 / (math.pi**3 * 0.5**2)) ** (1 / 3), rel=1e-14
    )
    assert hz.mean_pressure == pytest.approx(2 / 3 * hz.peak_pressure, rel=1e-14)
    assert hz.approach == pytest.approx(hz.contact_radius**2 / 0.5, rel=1e-14)
    # the profile carries the force
    r = np.linspace(0.0, hz.contact_radius, 20001)
    p = hz.pressure(r)
    force = np.trapezoid(2 * np.pi * r * p, r)
    assert force == pytest.approx(2.0, rel=1e-4)
    assert hz.pressure([2 * hz.contact_radius])[0] == 0.0
    assert effective_modulus(1.0, 0.0, 1.0, 0.0) == pytest.approx(0.5)
    with pytest.raises(ContactError, match="positive force"):
        hertz_sphere_on_plane(-1.0, 1.0, 1.0, 0.3)


def test_moment_radius_of_the_hertz_profile():
    """sum f r^2 / sum f = 2 a^2 / 5 for p = p0 sqrt(1 - r^2/a^2) (fine rings)."""
    a = 0.7
    edges = np.linspace(0.0, a, 4001)
    r = 0.5 * (edges[1:] + edges[:-1])
    f = np.sqrt(1 - (r / a) ** 2) * 2 * np.pi * r * np.diff(edges)
    assert moment_radius(r, f) == pytest.approx(a, rel=1e-6)


def test_interpolation_excess_of_a_flat_grid():
    """On a grid of squares of side h, I(r^2) - r^2 averages h^2/6 per direction: h^2/3."""
    h = 0.1
    box = fem.box_mesh((1.0, 1.0, 0.1), (10, 10, 1), origin=(-0.5, -0.5, -0.1))
    bottom = {k: f[np.all(box.points[f, 2] < -0.05, axis=1)] for k, f in box.boundary.faces.items()}
    area, excess = interpolation_excess(box, list(bottom.values()), [0, 0, 0], [0, 0, 1])
    inside = (np.abs(box.points[:, :2]).max(axis=1) < 0.45) & (box.points[:, 2] < -0.05)
    assert area[inside] == pytest.approx(h * h, rel=1e-12)
    assert excess[inside] == pytest.approx(h * h / 3, rel=1e-12)
    assert area.sum() == pytest.approx(1.0, rel=1e-12)


def hertz_nodal_forces(mesh, a, p0, sub=4):
    """Consistent nodal forces int N_i p dA of the Hertz pressure on the faces facing -z.

    Each face's parameter square is cut into sub x sub squares with 3x3 Gauss points in
    each, a finer rule than the estimators use.
    """
    faces = np.concatenate([f for f in mesh.boundary.faces.values() if f.shape[1] == 4])
    x = mesh.points[faces]
    normal = np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 1])
    faces, x = faces[normal[:, 2] < 0], x[normal[:, 2] < 0]
    g, w = np.sqrt(0.6) * np.array([-1.0, 0.0, 1.0]), np.array([5.0, 8.0, 5.0]) / 9.0
    u1 = (-1 + (2 * np.arange(sub)[:, None] + 1 + g[None, :]) / sub).ravel()
    w1 = np.tile(w, sub) / sub
    u, v = (a_.ravel() for a_ in np.meshgrid(u1, u1, indexing="ij"))
    wq = np.outer(w1, w1).ravel()
    n = 0.25 * np.stack(
        [(1 - u) * (1 - v), (1 + u) * (1 - v), (1 + u) * (1 + v), (1 - u) * (1 + v)], 1
    )
    du = 0.25 * np.stack([-(1 - v), 1 - v, 1 + v, -(1 + v)], 1)
    dv = 0.25 * np.stack([-(1 - u), -(1 + u), 1 + u, 1 - u], 1)
    xq = np.einsum("qk,fkd->fqd", n, x)
    jac = np.linalg.norm(
        np.cross(np.einsum("qk,fkd->fqd", du, x), np.einsum("qk,fkd->fqd", dv, x)), axis=2
    )
    p = p0 * np.sqrt(np.clip(1 - (xq[..., 0] ** 2 + xq[..., 1] ** 2) / a**2, 0, None))
    nodal = np.einsum("qk,fq->fk", n, p * jac * wq)
    return np.bincount(faces.ravel(), nodal.ravel(), mesh.n_points)


@pytest.mark.parametrize("h", [0.03, 0.0125])
def test_estimators_on_exact_hertz_forces(h):
    """Fed the consistent nodal forces of the exact Hertz pressure, the estimators return it.

    So what the FE checks measure is the FE solution's error, not the estimators'. The
    uncorrected nodal moment radius and the lumped pressure fit are biased by the mesh.
    """
    a, p0 = 0.1, 1.0
    mesh = graded_ball_mesh(R, h, 0.13, part="octant", center=(0, 0, R))
    force = np.zeros((mesh.n_points, 3))
    force[:, 2] = hertz_nodal_forces(mesh, a, p0)
    res = ContactResult(
        True, "converged", 1, (), np.zeros_like(force), force, {}, np.flatnonzero(force[:, 2]), 0.0
    )
    table = Plane([0, 0, 0], [0, 0, 1], name="table")
    patch = measure_contact_patch(mesh, res, table, center=(0, 0, 0), fraction=0.25)
    # the faceted cap is 0.2 % larger than the disc it covers
    assert patch.force == pytest.approx(2 / 3 * np.pi * a**2 * p0, rel=0.003)
    assert patch.contact_radius == pytest.approx(a, rel=6e-4)  # measured +0.045 %
    assert patch.peak_pressure == pytest.approx(p0, rel=1e-4)
    assert patch.fit_radius == pytest.approx(a, rel=1e-4)
    nodal = patch.contact_radius_nodal / a - 1
    lumped = patch.peak_pressure_lumped / p0 - 1
    assert (nodal, lumped) == pytest.approx(
        {0.03: (0.0433, -0.0179), 0.0125: (0.0074, -0.0027)}[h], abs=2e-4
    )


# --- the mesh ---------------------------------------------------------------------------


def test_graded_spacing():
    t = graded_spacing(0.02, 0.2, 0.15, 1.25)
    d = np.diff(t)
    assert t[0] == 0.0 and t[-1] == 1.0 and (d > 0).all()
    assert d[:10] == pytest.approx(0.02, rel=1e-12)  # 10 cells fill [0, 0.2]
    ratio = d[11:] / d[10:-1]
    assert (ratio <= 1.25 + 1e-9).all() and (ratio >= 1 - 1e-9).all()
    assert np.linspace(0, 1, 5) == pytest.approx(graded_spacing(0.25, 1.0, 0.25, 1.2))
    with pytest.raises(fem.MeshError, match="growth"):
        graded_spacing(0.1, 0.5, 0.2, 3.0)


def test_graded_ball_mesh():
    full = graded_ball_mesh(R, 0.03, 0.13, center=(0, 0, R))
    octant = graded_ball_mesh(R, 0.03, 0.13, part="octant", center=(0, 0, R))
    assert full.n_cells == 8 * octant.n_cells
    assert octant.n_dofs == 9240
    # every boundary node on the sphere or on a symmetry plane; the poles are nodes
    d = octant.points - (0, 0, R)
    b = octant.boundary.nodes
    on_sphere = np.abs(np.linalg.norm(d[b], axis=1) - R) < 1e-12
    on_plane = (np.abs(d[b]) < 1e-12).any(axis=1)
    assert (on_sphere | on_plane).all()
    assert np.linalg.norm(d - (0, 0, -R), axis=1).min() < 1e-12
    assert octant.volume == pytest.approx(full.volume / 8, rel=1e-12)
    # fine cubes at the pole: nodes within the fine zone are 0.13/4 = 0.0325 apart
    near = b[on_sphere & (np.linalg.norm(d[b] - (0, 0, -R), axis=1) < 0.1)]
    x = np.sort(d[near][np.abs(d[near, 1]) < 1e-12, 0])
    assert np.diff(x)[:3] == pytest.approx(0.0325, rel=0.01)
    with pytest.raises(fem.MeshError, match="part must be one of"):
        graded_ball_mesh(R, 0.03, 0.13, part="wedge")
    with pytest.raises(fem.MeshError, match="fine_radius"):
        graded_ball_mesh(R, 0.03, 0.5)


# --- the check ------------------------------------------------------------------------


def check_solution(chk):
    """Converged, action = reaction, equilibrium, no penetration."""
    res, body = chk.result, chk.body
    assert res.converged and res.stop_reason == "converged"
    scale = float(np.abs(res.contact_force).sum())
    total = res.contact_force.sum(axis=0)
    assert np.abs(total + sum(res.obstacle_forces.values())).max() <= 1e-10 * scale
    # equilibrium: K u - f is the contact force at every DOF that is not held by symmetry
    resid = body.stiffness @ res.displacement.ravel() - body.loads - res.contact_force.ravel()
    free = np.setdiff1d(np.arange(body.mesh.n_dofs), body.solver.prescribed)
    assert np.abs(resid[free]).max() <= 1e-10 * scale
    # the whole body is in balance: contact forces and the symmetry reactions
    assert np.abs(resid.reshape(-1, 3).sum(axis=0) + total).max() <= 1e-10 * scale
    # no node behind a plane by more than 1e-3 of its local element size
    x = body.mesh.points + res.displacement
    local = np.sqrt(body.node_areas)
    for plane in chk.planes:
        nodes = body.surface_nodes
        assert (plane.signed_distance(x[nodes]) >= -1e-3 * local[nodes]).all(), plane.name
    assert (res.contact_force[res.contact_nodes] @ np.array([0, 0, 1.0]) != 0).all()


def test_hertz_on_a_test_sized_mesh(test_sized):
    chk = test_sized
    check_solution(chk)
    assert chk.mesh.n_dofs == 9240
    assert chk.hertz.contact_radius / R == pytest.approx(0.102, abs=0.002)
    # measured (B-bar bricks): radius -0.83 %, peak pressure -0.23 %; nodal moment radius
    # +3.37 %, fitted radius +2.26 %, lumped fit: peak pressure -1.89 %, radius -0.44 %
    hz, patch = chk.hertz, chk.patch
    assert abs(chk.radius_error) < 0.015
    assert abs(chk.pressure_error) < 0.01
    assert abs(patch.contact_radius_nodal / hz.contact_radius - 1) < 0.04
    assert abs(patch.fit_radius / hz.contact_radius - 1) < 0.03
    assert abs(patch.peak_pressure_lumped / hz.peak_pressure - 1) < 0.03
    assert abs(patch.fit_radius_lumped / hz.contact_radius - 1) < 0.03


def test_octant_is_the_full_ball():
    """The symmetry model gives the full ball's solution on the same (coarse) mesh."""
    octant = hertz_check(R, E, NU, depth=DEPTH, fine_size=0.06)
    full = hertz_check(R, E, NU, depth=DEPTH, fine_size=0.06, model="full")
    check_solution(full)
    check_solution(octant)
    assert full.mesh.n_dofs == 21231 and octant.mesh.n_dofs == 3192
    f_table, f_plate = full.result.obstacle_forces["table"], full.result.obstacle_forces["plate"]
    assert np.abs(f_table + f_plate).max() <= 1e-10 * abs(f_table[2])
    assert full.patch.force == pytest.approx(octant.patch.force, rel=1e-8)
    assert full.patch.force == pytest.approx(-f_table[2], rel=1e-12)
    assert np.abs(full.patch.center[:2]).max() < 1e-9
    assert full.patch.contact_radius == pytest.approx(octant.patch.contact_radius, rel=1e-8)
    assert full.patch.peak_pressure == pytest.approx(octant.patch.peak_pressure, rel=1e-8)


def test_patch_needs_contact(test_sized):
    chk = test_sized
    ceiling = Plane([0, 0, 3], [0, 0, -1], name="ceiling")
    with pytest.raises(ContactError, match="ceiling: 0 contact nodes, too few to measure"):
        measure_contact_patch(chk.mesh, chk.result, ceiling)


def within_30_percent(counts):
    """The counts fit in a band of +-30 % about a central value (their mid-range)."""
    mid = 0.5 * (max(counts) + min(counts))
    return all(abs(n - mid) <= 0.3 * mid for n in counts)


def test_iterations_on_small_meshes():
    """Contact-set updates from the test-sized mesh over two refinements (2.2x the DOFs)."""
    sizes = (0.03, 0.025, 0.02)
    its = [hertz_check(R, E, NU, depth=DEPTH, fine_size=h).result.iterations for h in sizes]
    assert max(its) <= 10
    assert within_30_percent(its), its  # measured: 3, 4, 4


@pytest.mark.slow
def test_hertz_on_a_refined_mesh():
    """71k DOFs, 10 cells across the contact radius."""
    chk = hertz_check(R, E, NU, depth=DEPTH, fine_size=0.01)
    check_solution(chk)
    assert chk.mesh.n_dofs == 70860
    # measured: radius -0.19 %, peak pressure -0.18 % (lumped fit -0.31 %)
    assert abs(chk.radius_error) < 0.005
    assert abs(chk.pressure_error) < 0.01


@pytest.mark.slow
def test_iterations_over_refinements():
    """Three meshes doubling the cells across the patch: 3.4, 6.8, 13.6 per contact radius."""
    sizes = (0.03, 0.015, 0.0075)
    its = [hertz_check(R, E, NU, depth=DEPTH, fine_size=h).result.iterations for h in sizes]
    assert within_30_percent(its), its  # measured: 3, 3, 5
