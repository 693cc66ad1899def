"""One BLAS thread for small dense work (fem.threads)."""

from __future__ import annotations

import numpy as np
import pytest

from fem import threads

threadpoolctl = pytest.importorskip("threadpoolctl")


def _openblas_threads() -> list[int]:
    info = threadpoolctl.threadpool_info()
    return [d["num_threads"] for d in info if d["internal_api"] == "openblas"]


def test_small_dense_work_runs_on_one_openblas_thread():
    if threads._openblas() is None:
        pytest.skip("no OpenBLAS loaded")
    before = _openblas_threads()
    with threads.dense_threads(threads.SMALL_DENSE - 1):
        assert set(_openblas_threads()) == {1}
        x = np.linalg.solve(np.diag(np.arange(1.0, 11.0)), np.ones(10))
    assert _openblas_threads() == before  # restored
    np.testing.assert_allclose(x, 1.0 / np.arange(1.0, 11.0))


def test_large_dense_work_keeps_its_threads():
    before = _openblas_threads()
    with threads.dense_threads(threads.SMALL_DENSE):
        assert _openblas_threads() == before


def test_sparse_work_runs_openblas_on_one_thread_but_large_dense_work_gets_its_threads():
    if threads._openblas() is None:
        pytest.skip("no OpenBLAS loaded")
    before = _openblas_threads()
    full = threads._openblas().full
    with threads.sparse_threads():
        assert set(_openblas_threads()) == {1}
        with threads.dense_threads(threads.SMALL_DENSE):
            assert set(_openblas_threads()) == {full}
        with threads.dense_threads(10):
            assert set(_openblas_threads()) == {1}
        assert set(_openblas_threads()) == {1}
    assert _openblas_threads() == before


def test_a_frame_runs_with_openblas_on_one_thread(monkeypatch):
    """solve_frame's work (factorisations included) sees OpenBLAS on one thread."""
    if threads._openblas() is None:
        pytest.skip("no OpenBLAS loaded")
    import fem
    from contact.cases.hertz_bodies import hertz_scene
    from contact.solver.iteration import solve_frame

    seen: list[set[int]] = []
    factorize = fem.StaticSolver.factorize

    def spy(self):
        seen.append(set(_openblas_threads()))
        return factorize(self)

    monkeypatch.setattr(fem.StaticSolver, "factorize", spy)
    sc = hertz_scene("sphere-block", 1.0, fine_size=0.05)
    before = _openblas_threads()
    res = solve_frame(sc.bodies, sc.pairs)
    assert res.converged
    assert seen and all(s == {1} for s in seen)
    assert _openblas_threads() == before
