"""The first contact set and zone of a pair whose two sides are held.

A ball held on its symmetry planes pressed by a rigid frictionless table: no side is
placed by the contacts, so the first set and the zone marked for partial solves are the nodes deeper
than half the deepest overlap (about Hertz's patch) and a ring, not the whole overlap
(twice its area). The answer is the same as with the whole overlap taken, in one update.
"""

from __future__ import annotations

import numpy as np
import pytest

import fem
from contact.geometry.plane import Plane
from contact.solver import ContactPair, ContactSettings, solve_frame
from contact.solver.body import ElasticBody
from fem.generators import graded_ball_mesh

R, E, NU = 1.0, 1.0, 0.3


def _press(h: float, depth: float) -> tuple[ElasticBody, object]:
    mesh = graded_ball_mesh(R, h, 0.25, part="octant", center=(0, 0, R))
    d = mesh.points - np.array([0.0, 0.0, R])
    sym = np.concatenate([3 * np.flatnonzero(np.abs(d[:, k]) <= 1e-9) + k for k in range(3)])
    body = ElasticBody("ball", mesh, fem.LinearElastic(E, NU), prescribed=sym, bbar=False)
    table = Plane([0, 0, 0], [0, 0, 1], motion=[0, 0, depth * R], name="table")
    res = solve_frame([body], [ContactPair(body, table)], [table], ContactSettings())
    return body, res


@pytest.mark.parametrize(("h", "depth"), [(0.03, 0.05), (0.025, 0.03)])
def test_a_held_press_marks_about_its_patch_and_solves_as_with_the_whole_overlap(
    h: float, depth: float, monkeypatch: pytest.MonkeyPatch
) -> None:
    body, res = _press(h, depth)
    assert res.converged and res.iterations == 1  # the patch and its ring hold it all
    patch = np.unique(res.contacts["node"]).size
    marked = body.solver.marked.size // 3
    overlap = int((body.mesh.points[:, 2] < depth * R).sum())  # nodes inside the table
    assert overlap > 1.5 * patch  # the overlap is about twice the patch
    assert marked < 0.7 * overlap  # the zone: the patch and a ring
    # taken as if the ball were free (every overlapping node a candidate): the same answer
    monkeypatch.setattr(ContactPair, "wide_start", property(lambda self: True))
    body2, res2 = _press(h, depth)
    assert body2.solver.marked.size > 1.3 * body.solver.marked.size  # the wider zone
    u, u2 = res.displacement["ball"], res2.displacement["ball"]
    assert np.abs(u - u2).max() <= 1e-12 * np.abs(u).max()
    np.testing.assert_array_equal(np.sort(res.contacts["node"]), np.sort(res2.contacts["node"]))
