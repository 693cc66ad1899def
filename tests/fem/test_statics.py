"""The partitioned solve (seed equations 6-8), extra prescribed DOFs and free bodies."""

import numpy as np
import pytest
import scipy.sparse as sp

import fem
from fem.saddle import free_columns
from tests.helpers import distort

BACKENDS = fem.available_backends()


@pytest.fixture
def body():
    mesh = distort(
        fem.box_mesh((1.0, 0.5, 0.5), (4, 2, 2), element="tetra"), 0.1, seed=5, boundary=False
    )
    k = fem.assemble_stiffness(mesh, fem.LinearElastic(1e6, 0.3))
    return mesh, k


def _held_k11(mesh, k):
    """``K11`` of the body held at ``x = 0``: the matrix a held body factors."""
    held = fem.node_dofs(np.flatnonzero(mesh.points[:, 0] == 0))
    free = np.setdiff1d(np.arange(k.shape[0]), held)
    return k[free][:, free].tocsr()


def _reference(k, f, prescribed, values):
    """Dense re-partitioned solve of equations (7) and (8)."""
    kd = k.toarray()
    n = kd.shape[0]
    free = np.setdiff1d(np.arange(n), prescribed)
    u = np.zeros(n)
    u[prescribed] = values
    u[free] = np.linalg.solve(
        kd[np.ix_(free, free)], f[free] - kd[np.ix_(free, prescribed)] @ values
    )
    r = kd[prescribed] @ u - f[prescribed]
    return u, r


@pytest.mark.parametrize("backend", BACKENDS)
def test_partitioned_solve_equals_dense_reference(body, backend):
    mesh, k = body
    rng = np.random.default_rng(0)
    fixed = fem.node_dofs(np.flatnonzero(np.isclose(mesh.points[:, 0], mesh.points[:, 0].min())))
    f = rng.normal(size=k.shape[0])
    uk = rng.normal(size=fixed.size) * 1e-3
    sol = fem.StaticSolver(k, fixed, backend=backend).solve(f, uk)
    u_ref, r_ref = _reference(k, f, fixed, uk)
    assert np.abs(sol.u - u_ref).max() <= 1e-10 * np.abs(u_ref).max()
    assert np.abs(sol.reactions[fixed] - r_ref).max() <= 1e-10 * np.abs(r_ref).max()
    # equation (8) literally: Ru = K21 Uu + K22 Uk (minus the load applied there)
    free = np.setdiff1d(np.arange(k.shape[0]), fixed)
    k21, k22 = k[fixed][:, free], k[fixed][:, fixed]
    assert np.allclose(sol.reactions[fixed], k21 @ sol.u[free] + k22 @ uk - f[fixed])
    assert np.all(sol.reactions[free] == 0.0)


def test_equilibrium_forces_and_moments(body):
    mesh, k = body
    rng = np.random.default_rng(1)
    fixed = fem.node_dofs(np.flatnonzero(np.isclose(mesh.points[:, 0], mesh.points[:, 0].min())))
    f = fem.point_load(mesh.n_points, rng.integers(0, mesh.n_points, 7), rng.normal(size=(7, 3)))
    f += fem.gravity_load(mesh, fem.LinearElastic(1e6, 0.3, density=1000.0))
    sol = fem.StaticSolver(k, fixed).solve(f, rng.normal(size=fixed.size) * 1e-4)
    total = (sol.reactions + f).reshape(-1, 3)
    scale = np.abs(f).sum()
    assert np.abs(total.sum(axis=0)).max() <= 1e-10 * scale
    moment = np.cross(mesh.points, total).sum(axis=0)
    assert np.abs(moment).max() <= 1e-10 * scale


@pytest.mark.parametrize("backend", BACKENDS)
def test_extra_prescribed_equals_refactoring(body, backend):
    mesh, k = body
    rng = np.random.default_rng(2)
    base = fem.node_dofs(np.flatnonzero(np.isclose(mesh.points[:, 0], mesh.points[:, 0].min())))
    others = np.setdiff1d(np.arange(k.shape[0]), base)
    extra = rng.choice(others, 11, replace=False)
    f = rng.normal(size=k.shape[0])
    ub, ue = rng.normal(size=base.size) * 1e-3, rng.normal(size=extra.size) * 1e-3
    solver = fem.StaticSolver(k, base, backend=backend)
    sol = solver.solve(f, ub, extra=extra, extra_values=ue)
    both = np.concatenate([base, extra])
    order = np.argsort(both)
    ref = fem.StaticSolver(k, both).solve(f, np.concatenate([ub, ue])[order])
    assert np.abs(sol.u - ref.u).max() <= 1e-10 * np.abs(ref.u).max()
    assert np.abs(sol.reactions - ref.reactions).max() <= 1e-9 * np.abs(ref.reactions).max()
    assert np.allclose(sol.extra_reactions, ref.reactions[extra], rtol=1e-9, atol=1e-12)
    assert np.allclose(sol.u[extra], ue, atol=1e-15)
    # the compliance of rows already met is kept: no back-solve for a known set, one
    # per new row for a set that grows
    solves = solver.n_back_solves
    c1 = solver.compliance(extra)
    assert solver.n_back_solves == solves
    more = np.concatenate([extra, rng.choice(np.setdiff1d(others, extra), 3, replace=False)])
    c2 = solver.compliance(more)
    assert solver.n_back_solves == solves + 3
    assert np.allclose(c2[:11, :11], c1, rtol=1e-14, atol=0)
    fresh = fem.StaticSolver(k, base, backend=backend).compliance(more)
    assert np.abs(c2 - fresh).max() <= 1e-12 * np.abs(fresh).max()


def test_general_constraint_rows(body):
    """A constraint n . u = g (normal component only) through a sparse E."""
    mesh, k = body
    base = fem.node_dofs(np.flatnonzero(np.isclose(mesh.points[:, 0], mesh.points[:, 0].min())))
    node = int(np.argmax(mesh.points[:, 0]))
    n = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    e = sp.csr_matrix((n, ([0, 0, 0], 3 * node + np.arange(3))), shape=(1, k.shape[0]))
    sol = fem.StaticSolver(k, base).solve(extra=e, extra_values=[1e-3])
    assert n @ sol.u[3 * node : 3 * node + 3] == pytest.approx(1e-3, rel=1e-12)
    # the reaction acts along n only
    r = sol.reactions[3 * node : 3 * node + 3]
    assert np.allclose(r, sol.extra_reactions[0] * n)


def test_free_body_balanced_load_and_no_rigid_component():
    mesh = distort(fem.box_mesh((1.0, 1.0, 1.0), (3, 3, 3)), 0.1, seed=9)
    k = fem.assemble_stiffness(mesh, fem.LinearElastic(1e6, 0.3))
    rng = np.random.default_rng(3)
    f = rng.normal(size=k.shape[0])
    phi = fem.rigid_body_modes(mesh.points)
    f -= phi @ (phi.T @ f)  # balance it
    solver = fem.StaticSolver(k, points=mesh.points)
    sol = solver.solve(f)
    assert np.linalg.norm(k @ sol.u - f) <= 1e-10 * np.linalg.norm(f)
    assert np.abs(phi.T @ sol.u).max() <= 1e-12 * np.abs(sol.u).max()
    assert np.all(sol.reactions == 0.0)


def test_free_body_unbalanced_load_is_refused_with_force_and_moment():
    mesh = fem.box_mesh((1.0, 1.0, 1.0), (2, 2, 2))
    k = fem.assemble_stiffness(mesh, fem.LinearElastic(1e6, 0.3))
    f = fem.point_load(mesh.n_points, [0], [0.0, 0.0, -2.0])
    with pytest.raises(fem.LoadError, match=r"resultant force \[0, 0, -2\] N, moment"):
        fem.StaticSolver(k, points=mesh.points).solve(f)


def test_free_body_with_extra_constraints_equals_constrained_body():
    """Extra prescribed DOFs that hold a free body: same as prescribing them outright."""
    mesh = distort(fem.box_mesh((1.0, 1.0, 1.0), (3, 3, 3)), 0.1, seed=9, boundary=False)
    k = fem.assemble_stiffness(mesh, fem.LinearElastic(1e6, 0.3))
    rng = np.random.default_rng(4)
    bottom = np.flatnonzero(np.isclose(mesh.points[:, 2], mesh.points[:, 2].min()))
    extra = fem.node_dofs(bottom[:5])
    g = rng.normal(size=extra.size) * 1e-3
    f = rng.normal(size=k.shape[0])  # unbalanced: the constraints take the difference
    sol = fem.StaticSolver(k, points=mesh.points).solve(f, extra=extra, extra_values=g)
    ref = fem.StaticSolver(k, np.sort(extra)).solve(f, g[np.argsort(extra)])
    assert np.abs(sol.u - ref.u).max() <= 1e-9 * np.abs(ref.u).max()
    assert np.abs(sol.reactions - ref.reactions).max() <= 1e-8 * np.abs(ref.reactions).max()
    assert sol.rigid.shape == (6,)


def test_free_body_constraints_that_do_not_hold_it():
    """One prescribed node cannot hold a body against an unbalanced load."""
    mesh = fem.box_mesh((1.0, 1.0, 1.0), (2, 2, 2))
    k = fem.assemble_stiffness(mesh, fem.LinearElastic(1e6, 0.3))
    f = fem.point_load(mesh.n_points, [26], [1.0, 0.0, 0.0])
    with pytest.raises(fem.LoadError, match="do not hold the free body"):
        fem.StaticSolver(k, points=mesh.points).solve(f, extra=fem.node_dofs([0]))


def test_solver_errors():
    mesh = fem.box_mesh((1.0, 1.0, 1.0), (2, 2, 2))
    k = fem.assemble_stiffness(mesh, fem.LinearElastic(1e6, 0.3))
    with pytest.raises(fem.SolverError, match="free"):
        fem.StaticSolver(k)  # no points for a free body
    with pytest.raises(fem.SolverError, match="unknown linear solver 'mumps'"):
        fem.StaticSolver(k, [0, 1, 2], backend="mumps")
    for backend in BACKENDS:
        with pytest.raises(fem.SolverError, match=r"singular|positive definite"):
            fem.StaticSolver(k, [0, 1, 2], backend=backend)  # one node cannot hold it
    s = fem.StaticSolver(k, fem.node_dofs([0, 1, 2, 3, 4, 5, 6, 7, 8]))
    with pytest.raises(fem.SolverError, match="already prescribed"):
        s.solve(extra=[0])
    with pytest.raises(fem.SolverError, match="loads must have shape"):
        s.solve(np.zeros(5))
    with pytest.raises(fem.SolverError, match="prescribed values must have shape"):
        s.solve(values=np.zeros(4))


def test_backends_agree(body):
    if len(BACKENDS) < 2:
        pytest.skip("one backend only")
    mesh, k = body
    rng = np.random.default_rng(6)
    fixed = fem.node_dofs(np.flatnonzero(np.isclose(mesh.points[:, 0], mesh.points[:, 0].min())))
    f = rng.normal(size=k.shape[0])
    u = [fem.StaticSolver(k, fixed, backend=b).solve(f).u for b in BACKENDS]
    assert np.abs(u[0] - u[1]).max() <= 1e-10 * np.abs(u[0]).max()


def test_row_cache_overflow_starts_afresh(body, monkeypatch):
    mesh, k = body
    monkeypatch.setattr(fem.constraintrows, "ROW_CACHE", 10)
    base = fem.node_dofs(np.flatnonzero(np.isclose(mesh.points[:, 0], mesh.points[:, 0].min())))
    others = np.setdiff1d(np.arange(k.shape[0]), base)
    solver = fem.StaticSolver(k, base)
    a = solver.compliance(others[:8])
    b = solver.compliance(others[4:12])  # 4 new rows overflow the cache of 10
    ref = fem.StaticSolver(k, base).compliance(others[4:12])
    assert np.abs(b - ref).max() <= 1e-12 * np.abs(ref).max()
    assert np.allclose(a[4:, 4:], b[:4, :4], rtol=1e-12)


def _contact_like_rows(mesh, nodes, seed):
    """Rows like contact rows: a normal on a node minus weights on three other nodes."""
    rng = np.random.default_rng(seed)
    rows, cols, vals = [], [], []
    for i, a in enumerate(nodes):
        n = rng.standard_normal(3)
        n /= np.linalg.norm(n)
        others = rng.choice(np.setdiff1d(nodes, [a]), 3, replace=False)
        w = rng.dirichlet(np.ones(3))
        for node, c in [(a, 1.0), *zip(others, -w, strict=True)]:
            rows += [i] * 3
            cols += list(range(3 * node, 3 * node + 3))
            vals += list(c * n)
    return sp.csr_matrix((vals, (rows, cols)), shape=(len(nodes), mesh.n_dofs))


@pytest.mark.skipif("pardiso" not in BACKENDS, reason="partial solves need PARDISO")
@pytest.mark.parametrize("free", [False, True])
def test_marked_compliance_equals_full_back_solves(free):
    """Partial solves on marked DOFs give the compliance of full back-solves; rows off the
    marks take a full back-solve each and agree with the rows on them."""
    mesh = distort(
        fem.box_mesh((1.0, 0.5, 0.5), (8, 4, 4), element="tetra"), 0.1, seed=5, boundary=False
    )
    k = fem.assemble_stiffness(mesh, fem.LinearElastic(1e6, 0.3))
    x = mesh.points
    held = None if free else fem.node_dofs(np.flatnonzero(x[:, 0] == 0))
    top = np.flatnonzero(np.isclose(x[:, 2], x[:, 2].max()))
    e1 = _contact_like_rows(mesh, top, 1)
    e2 = _contact_like_rows(mesh, top, 2)
    far = np.flatnonzero(np.isclose(x[:, 2], x[:, 2].min()))
    e3 = sp.vstack([e1, _contact_like_rows(mesh, far, 3)]).tocsr()

    def make(lazy):
        return fem.StaticSolver(k, held, points=x, lazy=lazy, hold_rotation=False)

    ref = make(False)
    s = make(True)
    assert not s.factored
    assert s.mark(fem.node_dofs(top))
    for e in (e1, sp.vstack([e1, e2]).tocsr()):
        want, got = ref.compliance(e), s.compliance(e)
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12 * np.abs(want).max())
    assert s.n_factorizations == 1 and s.n_back_solves <= 6 and s.n_partial_solves == 2 * top.size
    # rows off the marks: a full back-solve each, the kept rows untouched, same numbers
    solves = s.n_back_solves
    np.testing.assert_allclose(
        s.compliance(e3), ref.compliance(e3), rtol=1e-9, atol=1e-12 * np.abs(want).max()
    )
    assert s.n_back_solves == solves + far.size
    # and rows on the marks met after them still agree with them
    e4 = sp.vstack([e3, _contact_like_rows(mesh, top, 5)]).tocsr()
    np.testing.assert_allclose(
        s.compliance(e4), ref.compliance(e4), rtol=1e-9, atol=1e-12 * np.abs(want).max()
    )
    assert s.n_back_solves == solves + far.size
    # marking more after the factorisation refactors; the solves still agree
    assert s.mark(fem.node_dofs(far))
    assert s.n_factorizations == 2
    np.testing.assert_allclose(
        s.compliance(e4), ref.compliance(e4), rtol=1e-9, atol=1e-12 * np.abs(want).max()
    )
    f = np.random.default_rng(4).standard_normal(mesh.n_dofs)
    if free:
        f -= ref.modes @ (ref.modes.T @ f)
    np.testing.assert_allclose(s.solve(f).u, ref.solve(f).u, rtol=1e-9, atol=1e-15)
    # contact forces on the marked zone only: the short forward sweep, the same answer
    r = (e1.T @ np.linspace(1.0, 2.0, e1.shape[0]))[s.free]
    want = ref.apply_inverse(r)
    np.testing.assert_allclose(s.apply_inverse(r), want, rtol=1e-9, atol=1e-12 * abs(want).max())
    # too many marks: refused, nothing refactored
    assert not s.mark(np.arange(mesh.n_dofs))
    assert s.n_factorizations == 2


@pytest.mark.skipif("pardiso" not in BACKENDS, reason="partial solves need PARDISO")
def test_partial_solves_in_chunks_keep_their_work_arrays(body, monkeypatch):
    """Partial solves taken in chunks of columns (kept full-length arrays, zero off the
    marks) equal the dense inverse on the marks, call after call; a right-hand side
    that is not one row per marked DOF is refused."""
    import fem.linsolve as fl

    a = _held_k11(*body)
    marked = np.arange(3, a.shape[0], 4)
    inv = np.linalg.inv(a.toarray())[np.ix_(marked, marked)]
    rng = np.random.default_rng(2)
    monkeypatch.setattr(fl, "SCHUR_MAX", 0)  # the partial solves, not the Schur complement
    # three columns a chunk, capped by the values kept, then by the columns a call
    for work, cols in ((3 * a.shape[0], 100), (100 * a.shape[0], 3)):
        monkeypatch.setattr(fl, "PARTIAL_WORK", work)
        monkeypatch.setattr(fl, "PARTIAL_COLUMNS", cols)
        f = fem.factorize(a, "pardiso", marked=marked)
        for ncol in (7, 2, 5):  # chunks of 3, 3, 1; then fewer columns than kept
            b = rng.standard_normal((marked.size, ncol))
            np.testing.assert_allclose(f.solve_marked(b), inv @ b, rtol=1e-10, atol=1e-14)
            assert f._work[0].shape[1] == 3
            assert not f._work[0][np.setdiff1d(np.arange(a.shape[0]), marked)].any()
    b = rng.standard_normal(marked.size)
    np.testing.assert_allclose(f.solve_marked(b), inv @ b, rtol=1e-10, atol=1e-14)
    with pytest.raises(fem.SolverError, match=f"expected {marked.size} rows"):
        f.solve_marked(np.ones(marked.size + 1))


@pytest.mark.skipif("pardiso" not in BACKENDS, reason="partial solves need PARDISO")
def test_past_a_third_of_the_marked_columns_the_schur_inverse_answers_sparse_or_dense(body):
    """The marked block's Cholesky answers the first columns; once they pass a third of
    the marks, its inverse, made once: the same numbers, for sparse and dense columns."""
    a = _held_k11(*body)
    marked = np.arange(0, a.shape[0], 2)
    want = np.linalg.inv(a.toarray())[np.ix_(marked, marked)]
    f = fem.factorize(a, "pardiso", marked=marked)
    m = marked.size
    first = sp.identity(m, format="csc")[:, : m // 4]  # unit columns, as contact rows are
    np.testing.assert_allclose(f.solve_marked(first), want[:, : m // 4], rtol=1e-9, atol=1e-14)
    assert f._schur_inv is None  # a quarter of the columns: the Cholesky
    q = m // 4
    rest = sp.csc_matrix(np.eye(m)[:, q : 2 * q] - 0.5 * np.eye(m)[:, :q])
    np.testing.assert_allclose(
        f.solve_marked(rest), want @ rest.toarray(), rtol=1e-9, atol=1e-12 * abs(want).max()
    )
    assert f._schur_inv is not None  # past a third: the inverse, kept
    b = np.random.default_rng(1).standard_normal(m)
    np.testing.assert_allclose(f.solve_marked(b), want @ b, rtol=1e-9, atol=1e-12 * abs(want).max())
    np.testing.assert_allclose(f._schur_inv, f._schur_inv.T, rtol=0, atol=0)


def test_the_marked_block_s_schur_complement_answers_partial_solves(body, monkeypatch):
    """Up to SCHUR_MAX marked DOFs, PARDISO's Schur complement of the marked block (its
    dense Cholesky) answers the partial solves: the dense inverse on the marks; full solves
    of the same factorisation stay exact; above it, the partial solves."""
    import fem.linsolve as fl

    a = _held_k11(*body)
    marked = np.arange(3, a.shape[0], 4)
    inv = np.linalg.inv(a.toarray())
    rng = np.random.default_rng(3)
    for limit, schur in ((marked.size, True), (marked.size - 1, False)):
        monkeypatch.setattr(fl, "SCHUR_MAX", limit)
        f = fem.factorize(a, "pardiso", marked=marked)
        assert (f._schur is not None) == schur
        b = rng.standard_normal((marked.size, 4))
        want = inv[np.ix_(marked, marked)] @ b
        np.testing.assert_allclose(f.solve_marked(b), want, rtol=1e-10, atol=1e-14)
        np.testing.assert_allclose(f.solve_marked(b[:, 0]), want[:, 0], rtol=1e-10, atol=1e-14)
        full = rng.standard_normal(a.shape[0])
        np.testing.assert_allclose(f.solve(full), inv @ full, rtol=1e-9, atol=1e-14)
        on_marks = np.zeros(a.shape[0])
        on_marks[marked] = b[:, 1]
        np.testing.assert_allclose(f.solve(on_marks), inv @ on_marks, rtol=1e-9, atol=1e-14)


@pytest.mark.parametrize("backend", BACKENDS)
def test_factorize_solves_right_hand_sides_with_its_test_solve(body, backend):
    """Right-hand sides handed to the factorisation come back solved (``first``), equal to
    a later solve; a free body with marks gets its J Phi that way, no separate solve."""
    mesh, k = body
    a = _held_k11(mesh, k)
    b = np.random.default_rng(3).standard_normal((a.shape[0], 2))
    f = fem.factorize(a, backend, rhs=b)
    np.testing.assert_allclose(f.first, f.solve(b), rtol=1e-12, atol=0)
    np.testing.assert_allclose(a @ f.first, b, rtol=1e-9, atol=1e-9 * np.abs(b).max())
    assert fem.factorize(a, backend).first is None
    assert fem.factorize(a, backend, rhs=b[:, 0]).first.shape == (a.shape[0],)
    with pytest.raises(fem.SolverError, match=f"must have {a.shape[0]} rows"):
        fem.factorize(a, backend, rhs=np.ones(3))
    if backend == "pardiso":
        x = mesh.points
        s = fem.StaticSolver(k, points=x, lazy=True, hold_rotation=False)
        assert s.mark(fem.node_dofs(np.flatnonzero(x[:, 2] == x[:, 2].max())))
        s.factorize()
        jphi = s.modes_response()
        assert s.n_back_solves == 6  # solved with the factorisation
        inner = s._inner
        ref = np.linalg.solve(s.factored_matrix.toarray(), s.modes[inner])
        np.testing.assert_allclose(jphi[inner], ref, rtol=1e-8, atol=1e-12 * np.abs(ref).max())
        assert not jphi[s._support].any()


def test_free_columns_equal_column_slicing(body):
    """The constraint rows' free columns, taken through the DOF map, equal scipy's slicing
    (values, order, and unsorted input); a free body's rows come back as a copy."""
    mesh, k = body
    held = fem.node_dofs(np.flatnonzero(mesh.points[:, 0] == 0))
    s = fem.StaticSolver(k, held)
    rng = np.random.default_rng(7)
    n = k.shape[0]
    cols = rng.integers(0, n, size=(40, 6))
    rows = np.repeat(np.arange(40), 6)
    e = sp.csr_matrix((rng.standard_normal(240), (rows, cols.ravel())), shape=(40, n))
    e.indices = e.indices.copy()
    for r in range(40):  # unsorted within rows
        a, b = e.indptr[r], e.indptr[r + 1]
        e.indices[a:b] = e.indices[a:b][::-1]
        e.data[a:b] = e.data[a:b][::-1]
    e.has_sorted_indices = False
    got, want = free_columns(e, s._pos, s.free.size), e[:, s.free].tocsr()
    want.sort_indices()
    assert got.has_sorted_indices
    np.testing.assert_array_equal(got.indptr, want.indptr)
    np.testing.assert_array_equal(got.indices, want.indices)
    np.testing.assert_array_equal(got.data, want.data)
    free = fem.StaticSolver(k, points=mesh.points, lazy=True)
    e.sort_indices()
    assert free_columns(e, free._pos, free.free.size) is not e
    np.testing.assert_array_equal(free_columns(e, free._pos, free.free.size).toarray(), e.toarray())


@pytest.mark.parametrize("case", ["held", "free", "free marked"])
def test_anticipated_loads_are_solved_with_the_factorisation(body, case):
    """Loads anticipated before the factorisation are answered from its sweeps: the same
    answer as a solve afterwards, and no solve of their own."""
    mesh, k = body
    x = mesh.points
    rng = np.random.default_rng(11)
    if case == "held":
        s = fem.StaticSolver(k, fem.node_dofs(np.flatnonzero(x[:, 0] == 0)), lazy=True)
    else:
        s = fem.StaticSolver(k, points=x, lazy=True, hold_rotation=False)
        if case == "free marked" and "pardiso" in BACKENDS:
            assert s.mark(fem.node_dofs(np.flatnonzero(x[:, 2] == x[:, 2].max())))
    ref = fem.StaticSolver(k, s.prescribed, points=x, hold_rotation=False)
    f = rng.standard_normal(s.free.size)
    with pytest.raises(fem.SolverError, match="anticipated loads must have shape"):
        s.anticipate(f[:-1])
    s.anticipate(f)
    s.factorize()
    answer = s.apply_inverse(f)

    def refuse(b):
        raise AssertionError("anticipated loads solved again")

    s._factorization.solve = refuse
    np.testing.assert_allclose(s.apply_inverse(f), answer, rtol=0, atol=0)
    want = ref.apply_inverse(f)
    np.testing.assert_allclose(answer, want, rtol=1e-9, atol=1e-9 * np.abs(want).max())
    with pytest.raises(AssertionError, match="solved again"):
        s.apply_inverse(2.0 * f)  # other loads: a solve
    s.anticipate(3.0 * f)  # factored already: nothing changes
    np.testing.assert_allclose(s.apply_inverse(f), answer, rtol=0, atol=0)
