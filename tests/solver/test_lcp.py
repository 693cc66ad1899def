"""The unilateral contact solve: the frictionless LCP of candidate rows."""

import itertools

import numpy as np
import pytest

import fem
from contact.solver.lcp import solve_lcp


def _spd(m, seed, cond=1e2):
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.normal(size=(m, m)))
    return (q * np.geomspace(1.0, 1.0 / cond, m)) @ q.T


def _brute(w, rhs):
    """The LCP's solution by trying every set of closed rows (W positive definite)."""
    m = rhs.size
    for k in range(m + 1):
        for closed in itertools.combinations(range(m), k):
            idx = list(closed)
            lam = np.zeros(m)
            if idx:
                lam[idx] = np.linalg.solve(w[np.ix_(idx, idx)], rhs[idx])
            gap = w @ lam - rhs
            if (lam >= -1e-12).all() and (gap >= -1e-12).all():
                return lam
    raise AssertionError("no solution")


@pytest.mark.parametrize("seed", range(6))
def test_lcp_equals_the_solution_found_by_trying_every_contact_set(seed):
    m = 8
    w = _spd(m, seed)
    rhs = np.random.default_rng(100 + seed).normal(size=m)
    res = solve_lcp(w, np.zeros((m, 0)), rhs, np.zeros(0), tol=1e-12)
    assert res.solved
    ref = _brute(w, rhs)
    assert 0 < (ref > 0).sum() < m  # some rows open, some closed
    np.testing.assert_allclose(res.lam, ref, atol=1e-10)
    assert res.lam.min() >= 0
    assert res.gap.min() >= -1e-10
    assert abs(res.lam @ res.gap) < 1e-10
    # started from another set (a set that grew), the same answer
    warm = solve_lcp(w, np.zeros((m, 0)), rhs, np.zeros(0), tol=1e-12, start=np.abs(rhs))
    np.testing.assert_allclose(warm.lam, ref, atol=1e-10)


def test_a_free_body_is_balanced_and_its_rows_complementary():
    # a body free to move along x and y, pressed by a load c against rows of both modes
    m = 10
    rng = np.random.default_rng(3)
    w = _spd(m, 7)
    g = np.column_stack([np.cos(np.linspace(0, np.pi, m)), np.sin(np.linspace(0, np.pi, m))])
    rhs = rng.normal(scale=0.1, size=m)
    c = np.array([0.3, 1.0])  # minus the load in each mode
    res = solve_lcp(w, g, rhs, c, tol=1e-12)
    assert res.solved
    np.testing.assert_allclose(g.T @ res.lam, c, atol=1e-12)
    assert res.lam.min() >= 0 and res.gap.min() >= -1e-10
    assert abs(res.lam @ res.gap) < 1e-10
    closed = res.lam > 0
    np.testing.assert_allclose(res.gap[closed], 0.0, atol=1e-10)


def test_a_free_body_that_nothing_loads_moves_off_every_row_at_no_force():
    # a ball in a cup rising under it: the cup's rows are closed by the ball's rigid motion
    # alone; every force is zero (round-off forces are not taken as pulling)
    n = np.array([[0.0, 0.6, 0.8], [0.0, -0.6, 0.8], [0.6, 0.0, 0.8], [-0.6, 0.0, 0.8]])
    g = np.repeat(n, 3, axis=0)
    w = 1e-3 * _spd(12, 1)
    rhs = np.full(12, 0.005)  # every row 5 mm inside
    res = solve_lcp(w, g, rhs, np.zeros(3), tol=1e-9)
    assert res.solved
    np.testing.assert_array_equal(res.lam, 0.0)
    assert res.gap.min() >= -1e-9
    np.testing.assert_allclose(res.a, [0.0, 0.0, 0.005 / 0.8], atol=1e-12)


def test_rows_that_repeat_one_another_share_the_force_of_one():
    # two-pass contact node on node: the same row twice (dependent) and a third one
    w1 = _spd(2, 4)
    w = np.zeros((3, 3))
    w[np.ix_([0, 1], [0, 1])] = w1
    w[2] = w[0]
    w[:, 2] = w[:, 0]
    rhs = np.array([1.0, 0.5, 1.0])
    res = solve_lcp(w, np.zeros((3, 0)), rhs, np.zeros(0), tol=1e-9)
    single = solve_lcp(w1, np.zeros((2, 0)), rhs[:2], np.zeros(0), tol=1e-9)
    assert res.solved
    assert res.lam[0] + res.lam[2] == pytest.approx(single.lam[0], rel=1e-9)
    assert res.lam[1] == pytest.approx(single.lam[1], rel=1e-9, abs=1e-12)
    assert res.gap.min() >= -1e-9


def test_a_free_body_the_start_leaves_loaded_moves_onto_the_open_rows():
    # a ball pressed by two pads along x starts on their rows alone; its weight along z
    # has no closed row: it moves onto the table row, open by 0.1 mm, which carries it
    w = 1e-4 * _spd(3, 5)
    g = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0]])  # left pad, right pad, table
    rhs = np.array([0.0, 0.0, -1e-4])
    weight = 0.36
    c = np.array([0.0, weight])
    res = solve_lcp(w, g, rhs, c, tol=1e-12, start=np.array([0.5, 0.5, 0.0]))
    assert res.solved
    np.testing.assert_allclose(g.T @ res.lam, c, atol=1e-12)
    assert res.lam[2] == pytest.approx(weight, rel=1e-12)
    assert res.lam.min() >= 0 and res.gap.min() >= -1e-12


def test_a_loaded_free_body_that_nothing_holds_is_an_error():
    w = np.eye(2)
    g = np.array([[1.0], [1.0]])
    rhs = np.array([-1.0, -1.0])  # both rows open by 1
    with pytest.raises(fem.LoadError):
        # pushed away from both rows (c = -load along the mode, here pulling)
        solve_lcp(w, g, rhs, np.array([-1.0]), tol=1e-9)


def test_a_rigid_sphere_on_a_half_space_closes_hertz_patch():
    # Boussinesq's compliance between the nodes of a grid, pressed by a rigid sphere: the
    # LCP's force and patch are Hertz's to the grid's resolution, whichever rows start
    # closed (all of them: the steps open most again, bordering one factorisation)
    import math

    from benchmarks.lcp import NU, PRESS, RADIUS, E, half_space

    w, gap, x, h = half_space(20)
    cold = solve_lcp(w, np.zeros((gap.size, 0)), -gap, np.zeros(0), tol=1e-9 * PRESS)
    first = np.where(gap < -0.5 * PRESS, 1.0, 0.0)
    warm = solve_lcp(w, np.zeros((gap.size, 0)), -gap, np.zeros(0), tol=1e-9 * PRESS, start=first)
    assert cold.solved and warm.solved and cold.steps > 3
    np.testing.assert_allclose(cold.lam, warm.lam, rtol=1e-9, atol=1e-12 * warm.lam.max())
    force = 4.0 / 3.0 * E / (1 - NU**2) * math.sqrt(RADIUS) * PRESS**1.5
    assert warm.lam.sum() == pytest.approx(force, rel=0.02)
    closed = warm.lam > 0
    a = math.sqrt(RADIUS * PRESS)
    r = np.linalg.norm(x, axis=1)
    assert r[closed].max() < a + h and r[~closed].min() > a - h  # the patch's edge
    assert warm.gap[~closed].min() >= 0


def test_a_row_that_repeats_a_closed_one_is_solved_anew():
    # a row with the same compliance as a closed one, needing its gap closed further:
    # both closed, the equality problem would be singular (least squares would split the
    # force and leave one row inside); the force moves onto the new row and the laxer
    # one opens
    w1 = _spd(3, 9)
    w = np.zeros((4, 4))
    w[:3, :3] = w1
    w[3], w[:, 3] = w[0], w[:, 0]
    rhs = np.array([1.0, -0.2, 0.3, 1.1])
    start = np.array([1.0, 0.0, 1.0, 0.0])  # row 0 closed at first, row 3 open
    res = solve_lcp(w, np.zeros((4, 0)), rhs, np.zeros(0), tol=1e-9, start=start)
    ref = solve_lcp(w1, np.zeros((3, 0)), rhs[[3, 1, 2]], np.zeros(0), tol=1e-9)
    assert res.solved
    assert res.lam[0] == 0 and res.lam[3] == pytest.approx(ref.lam[0], rel=1e-9)
    np.testing.assert_allclose(res.lam[1:3], ref.lam[1:3], rtol=1e-9, atol=1e-12)
    assert res.gap[0] == pytest.approx(0.1, rel=1e-9) and res.gap.min() >= -1e-9
