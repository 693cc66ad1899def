"""Newton's steps on a frictional frame solve one friction law: the frame's anchors.

A neo-Hookean pad (bonded base) is pressed by a stiff linear ball off its axis, with
Coulomb friction both ways. Every Newton step measures slip from the frame's start and
from where the frame first met each contact; a step that anchored its new contacts where
it found them would solve a new increment each time, and Newton would creep at a linear
rate (it stalled here at 0.95 a step).
"""

import numpy as np
import pytest

import fem
from contact.solver import finite
from contact.solver.anchors import Anchors
from contact.solver.body import ElasticBody
from contact.solver.finite import FiniteBody, solve_finite_frame
from contact.solver.iteration import solve_frame
from contact.solver.pairs import ContactPair

H, R = 0.01, 0.008


def _pad_and_ball(depth: float, mu: float, jitter: float = 0.0):
    mesh = fem.box_mesh((2 * H, 2 * H, H), (8, 8, 4), (-H, -H, 0))
    base = np.flatnonzero(np.isclose(mesh.points[:, 2], 0.0))
    pad = FiniteBody("pad", mesh, fem.LinearElastic(5e4, 0.45), prescribed=fem.node_dofs(base))
    bm = fem.ball_mesh(R, R / 3, center=(0.001, 0.0005, H + R - depth * R))
    if jitter:
        bm = fem.Mesh(bm.points * (1 + jitter), bm.cells, bm.regions)
    top = np.flatnonzero(bm.points[:, 2] > bm.points[:, 2].max() - 0.3 * R)
    ball = ElasticBody("ball", bm, fem.LinearElastic(1e6, 0.45), prescribed=fem.node_dofs(top))
    pairs = [ContactPair(pad, ball, friction=mu), ContactPair(ball, pad, friction=mu)]
    return [pad, ball], pairs


@pytest.mark.parametrize("depth", [0.1, 0.25])
def test_a_frictional_frame_converges_at_newtons_rate(depth):
    bodies, pairs = _pad_and_ball(depth, 0.5)
    out = solve_finite_frame(bodies, pairs)
    assert out.converged, out.stop_reason
    assert out.steps <= 6
    res = out.frame_result()
    status = np.asarray(res.contacts["status"])
    assert (status == 1).any()  # contacts stick: the frame's friction is in force
    # the pad carries the ball's push: its contact force balances its base's reaction
    push = res.contact_force["pad"].sum(axis=0)
    assert push[2] < 0 and abs(push[0]) < 0.5 * abs(push[2])


def test_a_round_off_change_leaves_the_frame_as_it_was():
    a = solve_finite_frame(*_pad_and_ball(0.25, 0.5))
    b = solve_finite_frame(*_pad_and_ball(0.25, 0.5, jitter=1e-15))
    assert a.converged and b.converged and a.steps == b.steps
    ua, ub = a.displacement["pad"], b.displacement["pad"]
    assert np.abs(ua - ub).max() <= 1e-9 * np.abs(ua).max()


def test_anchors_start_where_the_frame_starts_and_keep_what_the_steps_met():
    pts = np.zeros((2, 3))
    given = Anchors(displacement={"ball": np.ones((2, 3))}, reference={"ball": pts})
    start = given.starting({"ball": np.zeros(6), "pad": np.full(6, 2.0)}, {"ball": pts, "pad": pts})
    np.testing.assert_array_equal(start.displacement["ball"], 1.0)  # its own kept
    np.testing.assert_array_equal(start.displacement["pad"], np.full((2, 3), 2.0))
    met = Anchors(
        pair=np.array(["pad/ball"], dtype=object),
        node=np.array([1]),
        facet=np.array([[0, 1, 2]]),
        weights=np.array([[0.2, 0.3, 0.5]]),
        point=np.full((1, 3), np.nan),
        displacement={"pad": np.zeros((2, 3))},
    )
    kept = start.keeping(met)
    assert list(kept.pair) == ["pad/ball"] and kept.node.tolist() == [1]
    np.testing.assert_array_equal(kept.weights, met.weights)
    np.testing.assert_array_equal(kept.displacement["pad"], np.full((2, 3), 2.0))


def test_every_newton_step_measures_slip_from_the_same_anchors(monkeypatch):
    # each step is handed the anchors the steps before it met, placed where the frame
    # started: a contact is never anchored anew where a later linearisation finds it
    seen = []
    solve = finite.solve_frame

    def recorded(*args, anchors=None, **kwargs):
        res = solve(*args, anchors=anchors, **kwargs)
        seen.append((anchors, res.slip_from))
        return res

    monkeypatch.setattr(finite, "solve_frame", recorded)
    bodies, pairs = _pad_and_ball(0.25, 0.5)
    start = {"pad": np.full(bodies[0].mesh.n_dofs, 1e-5)}
    out = solve_finite_frame(bodies, pairs, start=start)
    assert out.converged and len(seen) == out.steps >= 2
    for (given, _), (_, met_before) in zip(seen[1:], seen[:-1]):
        before = _by_contact(met_before)
        now = _by_contact(given)
        assert before and before.items() <= now.items()
    for given, _ in seen:
        np.testing.assert_array_equal(given.displacement["pad"], 1e-5)


def _by_contact(a: Anchors) -> dict:
    return {
        (str(p), int(n)): (tuple(f), tuple(np.round(w, 12)))
        for p, n, f, w in zip(a.pair, a.node, a.facet, a.weights, strict=True)
    }


def test_a_tangent_that_cannot_be_factored_later_stops_the_frame_not_the_run(monkeypatch):
    # from the third step on every linear frame fails to factor: the frame ends where the
    # second left it, not converged and saying why; only a first tangent that cannot be
    # factored is an error (the body unstable where it starts)
    solve = finite.solve_frame
    calls = []

    def failing(*args, **kwargs):
        calls.append(1)
        if len(calls) >= 3:
            raise fem.SolverError("PARDISO could not factor the matrix")
        return solve(*args, **kwargs)

    monkeypatch.setattr(finite, "solve_frame", failing)
    out = solve_finite_frame(*_pad_and_ball(0.25, 0.5))
    assert not out.converged and "could not be factored" in out.stop_reason
    assert out.steps >= 2 and np.abs(out.displacement["pad"]).max() > 0
    assert out.frame_result().contact_force["pad"][:, 2].sum() < 0


def test_a_frictionless_search_from_the_last_place_finds_the_same_frame():
    # a free ball pressed by a plate onto a pad: searched from where a first solve left the
    # ball, the frame takes its contacts at once and ends where the search from rest ends
    from tests.output.test_output import ball_on_pad

    bodies, pairs, planes = ball_on_pad(0.05)
    rest = solve_frame(bodies, pairs, planes)
    bodies, pairs, planes = ball_on_pad(0.05)
    placed = solve_frame(bodies, pairs, planes, search_from={"ball": rest.displacement["ball"]})
    assert rest.converged and placed.converged
    assert placed.iterations <= rest.iterations
    for name in ("ball", "pad"):
        a, b = rest.displacement[name], placed.displacement[name]
        assert np.abs(a - b).max() <= 1e-6 * np.abs(a).max()
    wrong = {"ball": np.zeros((3, 3))}  # another mesh's: ignored, the search starts at rest
    bodies, pairs, planes = ball_on_pad(0.05)
    again = solve_frame(bodies, pairs, planes, search_from=wrong)
    np.testing.assert_array_equal(again.displacement["ball"], rest.displacement["ball"])


def test_a_contact_that_flips_is_seen_and_one_that_settles_is_not():
    from contact.solver.newtonrate import Flips

    def step(*nodes):
        return {"pair": np.array(["ball/bowl"] * len(nodes), dtype=object), "node": np.array(nodes)}

    settling = Flips()  # one contact lost for good, one gained for good: no flip
    assert not any(settling.add(s) for s in (step(1, 2), step(1, 3), step(1, 3), step(1, 3)))
    taken = Flips()  # node 7 closed by one step, open in the steps on either side
    assert [taken.add(s) for s in (step(1), step(1, 7), step(1))] == [False, False, True]
    assert taken.add(step(1))  # seen once, it holds for the rest of the frame
    dropped = Flips()  # node 7 open by one step, closed on either side
    assert [dropped.add(s) for s in (step(1, 7), step(1), step(1, 7))] == [False, False, True]
