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
    marked = np.unique(body.solver.marked_dofs // 3).size
    overlap = int((body.mesh.points[:, 2] < depth * R).sum())  # nodes inside the table
    assert overlap > 1.5 * patch  # the overlap is about twice the patch
    assert marked < 0.8 * overlap  # the zone: the patch and a ring of two elements
    # taken as if the ball were free (every overlapping node a candidate): the same answer
    monkeypatch.setattr(ContactPair, "wide_start", property(lambda self: True))
    body2, res2 = _press(h, depth)
    assert np.unique(body2.solver.marked_dofs // 3).size > 1.3 * marked  # the wider zone
    u, u2 = res.displacement["ball"], res2.displacement["ball"]
    assert np.abs(u - u2).max() <= 1e-12 * np.abs(u).max()
    np.testing.assert_array_equal(np.sort(res.contacts["node"]), np.sort(res2.contacts["node"]))


def test_a_frictionless_table_marks_only_its_normal_components_with_the_same_answer(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # rows along z touch z only: x and y need no partial solves (a cheaper factorisation)
    body, res = _press(0.03, 0.05)
    dofs = body.solver.marked_dofs
    assert dofs.size > 20 and np.all(dofs % 3 == 2)
    assert res.converged
    monkeypatch.setattr(ContactPair, "touched", property(lambda self: np.ones(3, dtype=bool)))
    body3, res3 = _press(0.03, 0.05)
    assert np.unique(body3.solver.marked_dofs % 3).size == 3  # every component, as before
    assert np.unique(body3.solver.marked_dofs // 3).size == dofs.size
    u, u3 = res.displacement["ball"], res3.displacement["ball"]
    assert np.abs(u - u3).max() <= 1e-12 * np.abs(u).max()
    assert res3.iterations == res.iterations


@pytest.mark.parametrize(
    ("normal", "friction", "want"),
    [
        ((0, 0, 1), 0.0, [False, False, True]),
        ((0, 0, -2), 0.0, [False, False, True]),
        ((1, 0, 1), 0.0, [True, False, True]),
        ((1, 2, 3), 0.0, [True, True, True]),
        ((0, 0, 1), 0.3, [True, True, True]),  # tangential rows
    ],
)
def test_the_components_a_pair_s_rows_touch(normal: tuple, friction: float, want: list) -> None:
    mesh = graded_ball_mesh(R, 0.1, 0.3, part="octant", center=(0, 0, R))
    body = ElasticBody("ball", mesh, fem.LinearElastic(E, NU))
    plane = Plane([0, 0, 0], normal, name="table")
    np.testing.assert_array_equal(ContactPair(body, plane, friction=friction).touched, want)
    other = ElasticBody("other", mesh, fem.LinearElastic(E, NU))
    assert ContactPair(body, other).touched.all()  # a body master's normals vary
