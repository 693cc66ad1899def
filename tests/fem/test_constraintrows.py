"""Rows off the marked DOFs: rented as back-solves until they cost a factorisation, then bought.

:class:`fem.constraintrows.ConstraintRows` widens the marks (the DOFs of every row off
them) and the body refactors once its back-solves have cost more than the factorisation;
the compliance is the same either way.
"""

import numpy as np
import pytest
import scipy.sparse as sp

import fem
from fem.constraintrows import ConstraintRows
from tests.helpers import distort

pytestmark = pytest.mark.skipif(
    "pardiso" not in fem.available_backends(), reason="partial solves need PARDISO"
)


def _rows(n_dofs: int, nodes: np.ndarray, seed: int) -> sp.csr_matrix:
    """One row per node along a random unit normal."""
    rng = np.random.default_rng(seed)
    n = rng.standard_normal((nodes.size, 3))
    n /= np.linalg.norm(n, axis=1)[:, None]
    cols = 3 * nodes[:, None] + np.arange(3)
    rows = np.repeat(np.arange(nodes.size), 3)
    return sp.csr_matrix((n.ravel(), (rows, cols.ravel())), shape=(nodes.size, n_dofs))


@pytest.fixture
def beam():
    mesh = distort(
        fem.box_mesh((1.0, 0.5, 0.5), (8, 4, 4), element="tetra"), 0.1, seed=3, boundary=False
    )
    k = fem.assemble_stiffness(mesh, fem.LinearElastic(1e6, 0.3))
    x = mesh.points
    top = np.flatnonzero(np.isclose(x[:, 2], x[:, 2].max()))  # the marked zone
    side = np.flatnonzero(np.isclose(x[:, 1], x[:, 1].min()) & (x[:, 2] < x[:, 2].max()))
    return mesh, k, fem.node_dofs(np.flatnonzero(x[:, 0] == 0)), top, side


@pytest.mark.parametrize("free", [False, True])
def test_rows_off_the_marks_past_a_factorisation_s_cost_are_marked_and_refactored(beam, free):
    mesh, k, held, top, side = beam
    x = mesh.points
    low, high = side[: side.size // 2], side[side.size // 2 :]

    def make(lazy: bool) -> fem.StaticSolver:
        return fem.StaticSolver(k, None if free else held, points=x, lazy=lazy)

    ref, s = make(False), make(True)
    assert s.mark(fem.node_dofs(top))
    s.factorize()
    s._factor_cost = lambda: 0.0  # a factorisation that costs nothing: any rent passes it
    e1 = sp.vstack([_rows(mesh.n_dofs, top, 1), _rows(mesh.n_dofs, low, 2)]).tocsr()
    e2 = sp.vstack([e1, _rows(mesh.n_dofs, high, 3)]).tocsr()
    for e in (e1, e2):
        want = ref.compliance(e)
        np.testing.assert_allclose(s.compliance(e), want, rtol=1e-9, atol=1e-12 * abs(want).max())
    # the first rows off the marks were rented; the next ones bought: all now marked
    assert s.n_factorizations == 2
    marked = set(s.marked_dofs.tolist())
    for nodes in (low, high):
        dofs = set(fem.node_dofs(nodes).tolist()) - set(held.tolist() if not free else [])
        assert len(dofs - marked) <= 6  # a free body's six support DOFs are never marked
    solves = s.n_back_solves
    e3 = sp.vstack([e2, _rows(mesh.n_dofs, low, 4)]).tocsr()  # new rows on the widened marks
    want = ref.compliance(e3)
    np.testing.assert_allclose(s.compliance(e3), want, rtol=1e-9, atol=1e-12 * abs(want).max())
    assert s.n_back_solves == solves and s.n_factorizations == 2


def test_rows_off_the_marks_are_rented_while_they_cost_less_than_a_factorisation(beam):
    mesh, k, held, top, side = beam
    x = mesh.points
    side = side[x[side, 0] > 0]  # not the held end
    s = fem.StaticSolver(k, held, lazy=True)
    s.mark(fem.node_dofs(top))
    s.factorize()
    s._factor_cost = lambda: np.inf  # a factorisation dearer than any back-solve
    for i, nodes in enumerate(np.array_split(side, 4)):
        s.compliance(_rows(mesh.n_dofs, nodes, i))
    assert s.n_factorizations == 1 and s.n_back_solves == side.size


def test_a_refused_widening_rents_from_then_on() -> None:
    # a 4 x 4 SPD matrix, row 0 marked; widening refused (past the marks' capacity)
    a = np.diag([4.0, 3.0, 2.0, 1.0]) + 0.1
    inv = np.linalg.inv(a)
    asked: list[np.ndarray] = []

    def widen(frows: np.ndarray) -> bool:
        asked.append(frows)
        return False

    rows = ConstraintRows(
        lambda r: inv @ r,
        lambda b: inv[:1, :1] @ b,
        np.arange(4),
        np.array([0]),
        4,
        widen=widen,
        buy=-1.0,  # bought at once, were it allowed
    )
    e = sp.csr_matrix(np.eye(4))
    got = [rows.compliance(e[[i]]) for i in range(1, 4)]
    assert [g[0, 0] for g in got] == pytest.approx(np.diag(inv)[1:], rel=1e-14)
    assert len(asked) == 1 and asked[0].tolist() == [1]  # asked once, refused
    assert rows.compliance(e) == pytest.approx(inv, rel=1e-14)


def test_renting_ends_where_the_back_solves_operations_pass_the_factorisation_s() -> None:
    # rows off the marks cost `column` operations each; the row after the rent passes
    # `buy` widens the marks: counted operations, not seconds, so the same rows take the
    # same path on any machine at any load
    a = np.diag([5.0, 4.0, 3.0, 2.0, 1.0]) + 0.1
    inv = np.linalg.inv(a)
    asked: list[int] = []

    def widen(frows: np.ndarray) -> bool:
        asked.append(len(seen))
        return False

    rows = ConstraintRows(
        lambda r: inv @ r, lambda b: inv[:1, :1] @ b, np.arange(5), np.array([0]), 5,
        widen=widen, buy=2.5, column=1.0,
    )  # fmt: skip
    e = sp.csr_matrix(np.eye(5))
    seen = []
    for i in range(1, 5):
        seen.append(i)
        rows.compliance(e[[i]])
    assert rows.rent == 4.0  # every row rented: the widening was refused
    assert asked == [4]  # asked once, at the fourth row: after three rented rows cost 3 > 2.5
