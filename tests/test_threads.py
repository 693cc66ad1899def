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
