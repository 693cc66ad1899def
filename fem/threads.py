"""One BLAS thread for small dense linear algebra and beside sparse factorisations.

OpenBLAS's worker threads spin while they wait for work. Where another process keeps the
other cores busy, a threaded Cholesky factorisation or product of a few hundred rows then
takes tens of times longer than on one thread, and on an idle machine the threads gain
little at that size: dense problems below :data:`SMALL_DENSE` rows (every contact set met
so far) run on one thread. MKL, behind PARDISO's sparse factorisations, is left alone:
only OpenBLAS is limited.

The same spinning slows the sparse factorisations themselves: OpenBLAS workers woken by a
dense product spin on for a while after it, on the cores MKL PARDISO is factoring on. A
contact frame therefore runs all its work with OpenBLAS on one thread
(:func:`sparse_threads`), and a dense problem of :data:`SMALL_DENSE` rows or more inside
it gets OpenBLAS's threads back.

The limit uses threadpoolctl; where it finds no OpenBLAS, nothing is limited.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from functools import lru_cache
from typing import Any

__all__ = ["SMALL_DENSE", "dense_threads", "sparse_threads"]

#: Dense problems with fewer rows than this run OpenBLAS on one thread.
SMALL_DENSE = 4096


@lru_cache(maxsize=1)
def _openblas() -> Any:
    """A threadpoolctl controller of the OpenBLAS libraries loaded (None: none).

    Its ``full`` attribute is OpenBLAS's thread count when first asked (the count that
    large dense work gets back inside :func:`sparse_threads`).
    """
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:  # pragma: no cover - a dependency; degrade to no limit
        return None
    sel = ThreadpoolController().select(internal_api="openblas")
    if not sel.lib_controllers:
        return None
    sel.full = max(c.num_threads for c in sel.lib_controllers)
    return sel


@contextmanager
def dense_threads(rows: int) -> Iterator[None]:
    """Within the block, OpenBLAS uses one thread if the dense problem is small.

    A large one (:data:`SMALL_DENSE` rows or more) gets OpenBLAS's full thread count,
    also inside :func:`sparse_threads`.

    Parameters
    ----------
    rows : int
        Rows of the dense matrices the block works on.

    Examples
    --------
    >>> import numpy as np
    >>> with dense_threads(200):
    ...     x = np.linalg.solve(np.eye(200) * 2.0, np.ones(200))
    >>> float(x[0])
    0.5
    """
    ctrl = _openblas()
    if ctrl is None:
        yield
        return
    with ctrl.limit(limits=1 if rows < SMALL_DENSE else ctrl.full):
        yield


@contextmanager
def sparse_threads() -> Iterator[None]:
    """Within the block, OpenBLAS uses one thread: the cores are MKL PARDISO's.

    For work that mixes sparse factorisations with numpy's dense products (a contact
    frame): OpenBLAS workers left spinning by a product would slow the factorisation
    that follows (see the module's notes). Dense problems of
    :data:`SMALL_DENSE` rows or more still get their threads (:func:`dense_threads`).

    Examples
    --------
    >>> import numpy as np
    >>> with sparse_threads():
    ...     x = np.ones((300, 300)) @ np.ones(300)
    >>> float(x[0])
    300.0
    """
    with dense_threads(0):  # the limit of small dense work
        yield
