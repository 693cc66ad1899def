"""Mortar coupling: integral identities, consistency on flat patches, the contact patch test."""

import time

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.spatial import cKDTree

import fem
from contact.solver.mortar import MortarCoupling, mortar_coupling


def _grid(
    nx,
    ny,
    lengths=(1.0, 1.0),
    origin=(0.0, 0.0),
    z=0.0,
    *,
    rot=0.0,
    pert=0.0,
    shear=0.0,
    seed=0,
    quads=False,
    down=False,
):
    """A planar grid at height ``z``; interior nodes moved by up to ``pert`` of a cell.

    ``shear`` moves x by ``shear * y`` (the quads stay parallelograms); ``down`` turns the
    facets clockwise seen from +z (outward -z, a body above).
    """
    x, y = np.meshgrid(
        np.linspace(0, lengths[0], nx + 1), np.linspace(0, lengths[1], ny + 1), indexing="xy"
    )
    p = np.stack([x.ravel(), y.ravel(), np.full(x.size, z)], axis=1)
    inner = (p[:, 0] > 0) & (p[:, 0] < lengths[0]) & (p[:, 1] > 0) & (p[:, 1] < lengths[1])
    rng = np.random.default_rng(seed)
    h = np.array(lengths) / [nx, ny]
    p[inner, :2] += rng.uniform(-pert, pert, (inner.sum(), 2)) * h
    p[:, 0] += shear * (p[:, 1] - lengths[1] / 2)
    c, s = np.cos(rot), np.sin(rot)
    p[:, :2] = (p[:, :2] - np.array(lengths) / 2) @ np.array([[c, s], [-s, c]])
    p[:, :2] += np.array(lengths) / 2 + origin
    idx = np.arange(len(p)).reshape(ny + 1, nx + 1)
    q = np.stack([idx[:-1, :-1], idx[:-1, 1:], idx[1:, 1:], idx[1:, :-1]], axis=-1)
    q = q.reshape(-1, 4)
    f = q if quads else np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])
    return p, (f[:, ::-1] if down else f)


def _facet_areas(p, f):
    x = p[f]
    if f.shape[1] == 3:
        return 0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), axis=1)
    return 0.5 * np.linalg.norm(np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 1]), axis=1)


def _row_sums(a):
    return np.asarray(a.sum(axis=1)).ravel()


KINDS = [(False, False), (True, True), (False, True), (True, False)]  # (slave quads, master)


@pytest.mark.parametrize(("sq", "mq"), KINDS)
def test_identities_slave_inside_master(sq, mq):
    # slave: a 5x5 grid on [0.2, 0.8]^2 (rotated 0.3 rad, kept inside); master: a perturbed,
    # rotated 7x3 grid that covers it, facing it, 1 mm below
    ps, fs = _grid(5, 5, (0.5, 0.5), (0.25, 0.25), rot=0.3, quads=sq, down=True)
    pm, fm = _grid(7, 3, (1.0, 1.0), z=-1e-3, rot=-0.1, pert=0.25, seed=1, quads=mq)
    c = mortar_coupling(ps, fs, pm, fm, search=0.01)
    assert isinstance(c, MortarCoupling)
    assert c.slave_nodes.tolist() == list(range(len(ps)))  # every slave node has a row
    slave_area = _facet_areas(ps, fs).sum()
    assert slave_area == pytest.approx(0.25, rel=1e-14)
    assert np.abs(_row_sums(c.d) - c.area).max() < 1e-12 * slave_area
    assert np.abs(_row_sums(c.m) - c.area).max() < 1e-12 * slave_area
    assert abs(c.d.sum() - slave_area) < 1e-12 and abs(c.m.sum() - slave_area) < 1e-12
    # the tributary areas of a flat grid, fully covered
    trib = np.zeros(len(ps))
    np.add.at(trib, fs, (_facet_areas(ps, fs) / fs.shape[1])[:, None])
    assert np.abs(c.area - trib).max() < 1e-14  # quads: A / 4 on parallelograms only
    # normals point from the master into the slave (+z); gap 1 mm
    assert np.allclose(c.normals, [0.0, 0.0, 1.0], atol=1e-15)
    assert np.abs(c.mean_gap0 - 1e-3).max() < 1e-14
    # D is symmetric on the slave nodes
    dd = c.d[:, c.slave_nodes].toarray()
    assert np.abs(dd - dd.T).max() < 1e-16


@pytest.mark.parametrize(("sq", "mq"), KINDS)
def test_linear_fields_pass_exactly(sq, mq):
    ps, fs = _grid(5, 5, (0.5, 0.5), (0.25, 0.25), rot=0.3, pert=0.2, seed=3, quads=sq, down=True)
    pm, fm = _grid(7, 3, (1.0, 1.0), rot=-0.1, pert=0.25, seed=1, quads=mq)
    c = mortar_coupling(ps, fs, pm, fm, search=0.01)
    a = np.array([[0.3, -1.2, 0.5], [2.0, 0.1, -0.4], [0.7, 0.2, 1.0]])

    def field(x):
        return x @ a.T + [0.1, -0.2, 0.3]

    dd = c.d[:, c.slave_nodes].toarray()
    xs = np.linalg.solve(dd, c.m @ field(pm))
    assert np.abs(xs - field(ps)).max() < 1e-12
    # matching surfaces: zero weighted gap
    assert np.abs(c.gap0).max() < 1e-15


@pytest.mark.parametrize(("sq", "mq"), KINDS)
def test_consistent_master_forces(sq, mq):
    # master inside the slave's projection: a uniform pressure p on the slave reaches each
    # master node as p * int N_k over its facets (area / 3 per triangle corner, the bilinear
    # integral of the quads by 2x2 Gauss). Triangles: a perturbed grid; quads: sheared
    # parallelograms (on a general quad N_k is not a polynomial of x, y: the integration on
    # the clip triangles is then accurate to ~1e-5 only)
    ps, fs = _grid(5, 5, (1.4, 1.4), (-0.2, -0.2), rot=0.2, pert=0.2, seed=4, quads=sq, down=True)
    if mq:
        pm, fm = _grid(7, 3, (0.8, 0.8), (0.1, 0.1), rot=0.1, shear=0.2, quads=True)
    else:
        pm, fm = _grid(7, 3, (1.0, 1.0), rot=0.0, pert=0.3, seed=2)
    c = mortar_coupling(ps, fs, pm, fm, search=0.01)
    p = 2.5e3
    lam = p * c.area  # row forces of a uniform pressure
    _, e_master = c.rows(len(ps), len(pm))
    f_master = (e_master.T @ lam).reshape(-1, 3)
    x = pm[fm]
    if mq:  # 2x2 Gauss on the bilinear quads
        g = (1 - 1 / np.sqrt(3)) / 2, (1 + 1 / np.sqrt(3)) / 2
        expected = np.zeros(len(pm))
        for xi in g:
            for eta in g:
                n = np.array([(1 - xi) * (1 - eta), xi * (1 - eta), xi * eta, (1 - xi) * eta])
                dxi = (1 - eta) * (x[:, 1] - x[:, 0]) + eta * (x[:, 2] - x[:, 3])
                deta = (1 - xi) * (x[:, 3] - x[:, 0]) + xi * (x[:, 2] - x[:, 1])
                jac = np.linalg.norm(np.cross(dxi, deta), axis=1) / 4
                np.add.at(expected, fm, jac[:, None] * n)
    else:
        expected = np.zeros(len(pm))
        np.add.at(expected, fm, (_facet_areas(pm, fm) / 3)[:, None])
    # the master is pushed down (-z) by p * its tributary area
    assert np.abs(f_master[:, 2] + p * expected).max() < 1e-12 * p * expected.max()
    assert np.abs(f_master[:, :2]).max() == 0.0
    assert f_master[:, 2].sum() == pytest.approx(-p * _facet_areas(pm, fm).sum(), rel=1e-13)


def test_rows():
    ps, fs = _grid(3, 3, (0.5, 0.5), (0.25, 0.25), down=True)
    pm, fm = _grid(2, 2)
    c = mortar_coupling(ps, fs, pm, fm, search=0.01)
    es, em = c.rows(len(ps) + 2, len(pm))
    assert es.shape == (len(c), 3 * (len(ps) + 2)) and em.shape == (len(c), 3 * len(pm))
    u = np.tile([0.0, 0.0, 1e-3], len(ps) + 2)  # the slave moved 1 mm up: gap + 1 mm
    assert np.allclose(es @ u, 1e-3, rtol=1e-13)
    assert np.allclose(em @ np.tile([0.0, 0.0, 1e-3], len(pm)), -1e-3, rtol=1e-13)
    raw_s, raw_m = c.rows(len(ps), len(pm), per_area=False)
    assert np.allclose((raw_s @ np.tile([0, 0, 1.0], len(ps))), c.area, rtol=1e-13)
    assert np.allclose(raw_s[:, 2::3].toarray(), c.d.toarray())
    assert np.allclose(raw_m[:, 2::3].toarray(), -c.m.toarray())
    with pytest.raises(ValueError, match="spans"):
        c.rows(len(ps) - 1, len(pm))
    # a master facing away is ignored: nothing to couple
    with pytest.raises(ValueError, match="no master"):
        mortar_coupling(ps, fs, pm, np.zeros((0, 3), int), search=0.01)
    away = mortar_coupling(ps, fs, pm, fm[:, ::-1], search=0.01)
    assert len(away) == 0 and away.d.shape == (0, len(ps))


# ---------------------------------------------------------------- the contact patch test

P = 1.0e4  # Pa


def _block(lengths, divisions, z0, young):
    mesh = fem.box_mesh(lengths, divisions, origin=(0.0, 0.0, z0))
    mat = fem.LinearElastic(young, 0.3)
    return mesh, mat, fem.assemble_stiffness(mesh, mat)


def _faces_at(mesh, z):
    quads = mesh.boundary.faces["quad"]
    return quads[np.isclose(mesh.points[quads][:, :, 2], z).all(axis=1)]


def _patch_problem(ratio):
    """Upper block (E * ratio, 4x4) on a lower one (7x5), 1 x 1 footprint, interface z = 1.

    Symmetry rollers on x = 0 and y = 0 (both blocks) and on the lower's bottom: the exact
    solution is uniaxial stress sigma_zz = -P, free to expand laterally (and to slip).
    """
    up, mat_up, k_up = _block((1.0, 1.0, 0.5), (4, 4, 2), 1.0, 1e6 * ratio)
    lo, mat_lo, k_lo = _block((1.0, 1.0, 1.0), (7, 5, 3), 0.0, 1e6)
    top = _faces_at(up, 1.5)
    f_up = fem.pressure_load(up, {"quad": top}, P)

    def fixed(mesh, bottom):
        x = mesh.points
        dofs = [fem.node_dofs(np.flatnonzero(np.isclose(x[:, 0], 0.0)), [0])]
        dofs.append(fem.node_dofs(np.flatnonzero(np.isclose(x[:, 1], 0.0)), [1]))
        if bottom:
            dofs.append(fem.node_dofs(np.flatnonzero(np.isclose(x[:, 2], 0.0)), [2]))
        return np.unique(np.concatenate(dofs))

    return (up, mat_up, k_up, f_up, fixed(up, False)), (lo, mat_lo, k_lo, fixed(lo, True))


def _solve_tied(upper, lower, e_up, e_lo):
    """The saddle system [[K1, 0, E1^T], [0, K2, E2^T], [E1, E2, 0]] on the free DOFs."""
    _, _, k_up, f_up, fix_up = upper
    _, _, k_lo, fix_lo = lower
    free_up = np.setdiff1d(np.arange(k_up.shape[0]), fix_up)
    free_lo = np.setdiff1d(np.arange(k_lo.shape[0]), fix_lo)
    # rows scaled to the stiffness (a well-conditioned saddle matrix: ~1e-15 instead of
    # ~1e-9 on the stresses), the multipliers scaled back
    scale = np.abs(k_up.diagonal()).mean()
    e1, e2 = scale * e_up[:, free_up], scale * e_lo[:, free_lo]
    a = sp.bmat(
        [
            [k_up[free_up][:, free_up], None, e1.T],
            [None, k_lo[free_lo][:, free_lo], e2.T],
            [e1, e2, None],
        ],
        format="csc",
    )
    rhs = np.concatenate([f_up[free_up], np.zeros(free_lo.size + e1.shape[0])])
    x = spla.spsolve(a, rhs)
    u_up, u_lo = np.zeros(k_up.shape[0]), np.zeros(k_lo.shape[0])
    u_up[free_up] = x[: free_up.size]
    u_lo[free_lo] = x[free_up.size : free_up.size + free_lo.size]
    # K u + E^T x = f: the contact forces (positive apart, acting as E^T lambda) are -x
    return u_up, u_lo, -scale * x[free_up.size + free_lo.size :]


def _stress_error(upper, lower, u_up, u_lo):
    exact = np.zeros((3, 3))
    exact[2, 2] = -P
    err = 0.0
    for (mesh, mat, *_), u in ((upper, u_up), (lower, u_lo)):
        for s in fem.cell_stress(mesh, mat, u, at="gauss").values():
            err = max(err, np.abs(s - exact).max() / P)
    return err


@pytest.mark.parametrize("upper_slave", [True, False])
@pytest.mark.parametrize("ratio", [0.01, 1.0, 100.0])
def test_contact_patch_test_mortar(ratio, upper_slave):
    upper, lower = _patch_problem(ratio)
    up, lo = upper[0], lower[0]
    bottom_up, top_lo = _faces_at(up, 1.0), _faces_at(lo, 1.0)
    if upper_slave:
        c = mortar_coupling(up.points, bottom_up, lo.points, top_lo, search=1e-6)
        e_up, e_lo = c.rows(up.n_points, lo.n_points)
        assert len(c) == 25
    else:
        c = mortar_coupling(lo.points, top_lo, up.points, bottom_up, search=1e-6)
        e_lo, e_up = c.rows(lo.n_points, up.n_points)
        assert len(c) == 48
    assert abs(c.area.sum() - 1.0) < 1e-14 and np.abs(c.gap0).max() < 1e-15
    u_up, u_lo, lam = _solve_tied(upper, lower, e_up, e_lo)
    assert _stress_error(upper, lower, u_up, u_lo) < 1e-11  # measured 5e-15 .. 1e-12
    # row forces: a uniform pressure P (the nodal pressure lambda_i / area_i)
    assert np.abs(lam / c.area - P).max() < 1e-10 * P


def _node_to_surface_rows(up, lo):
    """One row per upper-bottom node: its projection's bilinear weights on the lower's top."""
    nx, ny = 7, 5
    top_lo = np.flatnonzero(np.isclose(lo.points[:, 2], 1.0))
    tree = cKDTree(lo.points[top_lo, :2])
    slave = np.flatnonzero(np.isclose(up.points[:, 2], 1.0))
    xy = up.points[slave, :2] * [nx, ny]
    ij = np.minimum(np.floor(xy).astype(int), [nx - 1, ny - 1])
    xi, eta = (xy - ij).T
    corners = np.array([[0, 0], [1, 0], [1, 1], [0, 1]])
    weights = np.stack([(1 - xi) * (1 - eta), xi * (1 - eta), xi * eta, (1 - xi) * eta], 1)
    master = np.stack([top_lo[tree.query((ij + cn) / [nx, ny])[1]] for cn in corners], axis=1)
    m = len(slave)
    e_up = sp.csr_matrix((np.ones(m), (np.arange(m), 3 * slave + 2)), shape=(m, 3 * up.n_points))
    e_lo = sp.csr_matrix(
        (-weights.ravel(), (np.repeat(np.arange(m), 4), 3 * master.ravel() + 2)),
        shape=(m, 3 * lo.n_points),
    )
    return e_up, e_lo


@pytest.mark.parametrize("ratio", [0.01, 1.0, 100.0])
def test_node_to_surface_fails_the_patch_test(ratio):
    upper, lower = _patch_problem(ratio)
    e_up, e_lo = _node_to_surface_rows(upper[0], lower[0])
    u_up, u_lo, _ = _solve_tied(upper, lower, e_up, e_lo)
    assert _stress_error(upper, lower, u_up, u_lo) > 0.3  # measured 0.33 .. 0.54


def test_quads_split_in_triangles_fail_the_patch_test():
    # the hex faces' trace is bilinear: integrating them as triangle pairs is inconsistent
    upper, lower = _patch_problem(1.0)
    up, lo = upper[0], lower[0]

    def split(q):
        return np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])

    c = mortar_coupling(
        up.points, split(_faces_at(up, 1.0)), lo.points, split(_faces_at(lo, 1.0)), search=0
    )
    u_up, u_lo, _ = _solve_tied(upper, lower, *c.rows(up.n_points, lo.n_points))
    assert _stress_error(upper, lower, u_up, u_lo) > 0.05  # measured 0.077


@pytest.mark.parametrize("ratio", [0.01, 1.0, 100.0])
def test_patch_test_through_the_contact_space(ratio):
    # the solver's own contact-space solve (W lambda = -gap), unchanged, on the mortar rows:
    # the upper block free (held by the contacts; its loads balance in the free directions)
    from contact.solver.body import ElasticBody
    from contact.solver.delassus import ContactSpace

    (up, mat_up, _, f_up, _), (lo, mat_lo, _, fix_lo) = _patch_problem(ratio)
    upper = ElasticBody("upper", up, mat_up, loads=f_up)
    lower = ElasticBody("lower", lo, mat_lo, prescribed=fix_lo)
    c = mortar_coupling(up.points, _faces_at(up, 1.0), lo.points, _faces_at(lo, 1.0), search=0)
    e_up, e_lo = c.rows(up.n_points, lo.n_points)
    lam, states = ContactSpace([upper, lower]).solve({"upper": e_up, "lower": e_lo}, c.mean_gap0)
    assert np.abs(lam / c.area - P).max() < 1e-10 * P  # measured 7e-14 .. 2e-12
    err = _stress_error((up, mat_up), (lo, mat_lo), states["upper"].u, states["lower"].u)
    assert err < 1e-10  # measured 2e-14 .. 5e-13


# ---------------------------------------------------------------- curved surfaces


def test_concentric_spheres():
    # slave: an icosphere of radius 1 (triangles, outward); master: the cubed-sphere quads
    # of a hex ball of radius 1.01, turned inward (a cavity around the slave)
    ps, fs = fem.sphere_surface(1.0, refinement=3)
    ball = fem.ball_mesh(1.01, divisions=6, layers=3)
    quads = ball.boundary.faces["quad"]
    r = np.linalg.norm(ball.points[quads], axis=2)
    outer = quads[np.isclose(r, 1.01).all(axis=1)][:, ::-1]
    c = mortar_coupling(ps, fs, ball.points, {"quad": outer}, search=0.05)
    assert len(c) == len(ps)
    slave_area = _facet_areas(ps, fs).sum()
    sphere = 4 * np.pi
    assert abs(c.d.sum() - c.m.sum()) < 1e-12 * sphere
    assert abs(c.d.sum() - slave_area) < 1e-3 * sphere  # every point covered once
    assert abs(c.d.sum() - sphere) < 2e-2 * sphere
    assert np.abs(_row_sums(c.m) - c.area).max() < 1e-13
    # normals point inward (from the master cavity into the slave), the mean gap ~ 1 cm
    radial = ps[c.slave_nodes] / np.linalg.norm(ps[c.slave_nodes], axis=1)[:, None]
    assert np.einsum("si,si->s", c.normals, -radial).min() > 0.99
    # gap 1 cm less the facets' sag: the master's quads are coarse (0.26 m), their centres
    # dip ~1.7 cm below the 1.01 m sphere, locally below the slave's nodes
    assert -0.002 < c.mean_gap0.min() and c.mean_gap0.max() < 0.012
    assert 0.0 < c.gap0.sum() / c.area.sum() < 0.01


def test_speed_a_few_thousand_pairs():
    ps, fs = _grid(40, 40, (1.0, 1.0), rot=0.05, down=True)
    pm, fm = _grid(30, 30, (1.2, 1.2), (-0.1, -0.1), pert=0.2)
    t = time.perf_counter()
    c = mortar_coupling(ps, fs, pm, fm, search=1e-3)
    dt = time.perf_counter() - t
    assert abs(c.d.sum() - 1.0) < 1e-12
    assert dt < 5.0
