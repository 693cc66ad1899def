"""The contact zone of a pair: the nodes its rows will act on, chosen before factoring.

Marked DOFs (:meth:`fem.StaticSolver.mark`) are ordered last by the factorisation: a
row on them gets its compliance from a partial solve through the factor's trailing
block, but every marked DOF makes the factorisation dearer (that block is dense). The
zone is therefore the expected patch and a ring around it, not every node that might
touch: a row outside it costs one back-solve, nothing else.

Where the bodies overlap, the zone is the first contact set (the rows the first solve
needs: most of them); where they do not yet (a free ball that a plate will move onto a
hand), the nodes within ``APPROACH`` of an element of the closest approach. Around it,
the slave nodes within ``RING`` of their own element sizes, and the master's nodes that
those can reach: within one element plus the slave node's overlap.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

__all__ = ["APPROACH", "HELD_RING", "RING", "master_zone", "slave_zone"]

#: Width of the ring around the expected patch, in element sizes: a wider ring marks more
#: DOFs (a dearer factorisation) for fewer back-solves of rows outside it; see
#: benchmarks/results/frame.md.
RING = 1.0
#: The ring of a pair whose sides are both held and frictionless, whose first contact set
#: is Hertz's patch, the nodes deeper than half the deepest overlap, and this ring
#: (:mod:`contact.solver.contactset`): the discrete patch reaches up to about two
#: elements past it, and a first set that holds it takes one update on every mesh.
HELD_RING = 2.0
#: Where nothing overlaps yet (a free ball a plate will move onto a hand), the expected
#: patch is the nodes within this many element sizes of the closest approach: the patch
#: of a body that moves half an element further (a whole one marked up to four times as
#: many nodes, against a sphere: the Hertz radius grows with the root of the approach).
APPROACH = 0.5


def slave_zone(
    points: NDArray[np.float64],
    nodes: NDArray[np.int64],
    gap: NDArray[np.float64],
    first: NDArray[np.bool_],
    local: NDArray[np.float64],
    ring: float | None = None,
) -> NDArray[np.bool_]:
    """Which slave nodes are in the zone: the first contact set and a ring around it.

    Parameters
    ----------
    points : ndarray, shape (N, 3)
        The slave body's node coordinates.
    nodes : ndarray of int, shape (k,)
        Slave nodes measured near the master.
    gap : ndarray, shape (k,)
        Their signed gaps (m), negative inside.
    first : ndarray of bool, shape (k,)
        Those in the first contact set.
    local : ndarray, shape (k,)
        Their element sizes (m).
    ring : float, optional
        The ring's width, in element sizes (default :data:`RING`).

    Returns
    -------
    ndarray of bool, shape (k,)
    """
    if not nodes.size:
        return np.zeros(0, dtype=bool)
    core = first & (gap < 0)
    if not core.any():  # nothing overlaps: the nodes nearest to touching
        j = int(np.argmin(gap))
        core = gap <= gap[j] + APPROACH * local[j]
    x = points[nodes]
    # the query's bound is strict: a node exactly RING away is still in the ring
    ring = RING if ring is None else ring
    bound = np.nextafter(ring * float(local.max()), np.inf)
    d, _ = cKDTree(x[core]).query(x, distance_upper_bound=bound)
    return core | (d <= ring * local)


def master_zone(
    slave_points: NDArray[np.float64],
    gap: NDArray[np.float64],
    local: NDArray[np.float64],
    master_points: NDArray[np.float64],
) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
    """Which master nodes zone slave nodes can reach, and how near (m).

    Parameters
    ----------
    slave_points : ndarray, shape (k, 3)
        The zone's slave nodes.
    gap, local : ndarray, shape (k,)
        Their gaps and element sizes (m).
    master_points : ndarray, shape (q, 3)
        The master's contact nodes.

    Returns
    -------
    within : ndarray of bool, shape (q,)
        Master nodes within one element plus the overlap of the nearest zone node.
    nearness : ndarray, shape (q,)
        Distance to that node plus its gap (a gap-like measure; infinite outside).
    """
    reach = local + np.maximum(-gap, 0.0)
    bound = np.nextafter(float(reach.max()), np.inf)  # the query's bound is strict
    d, k = cKDTree(slave_points).query(master_points, distance_upper_bound=bound)
    ok = np.isfinite(d)
    ok[ok] = d[ok] <= reach[k[ok]]
    near = np.full(d.shape, np.inf)
    near[ok] = d[ok] + gap[k[ok]]
    return ok, near
