"""The damping of free finite bodies' Newton steps: its rules, one by one."""

from types import SimpleNamespace

import pytest

from contact.solver.damping import FIRST, FOLLOW, IDLE, LEAST, MOST, REACH, Damping


def _unheld(not_carried: float, available: float = 1.0, turns: bool = False):
    slip = {"not_carried": not_carried, "available": available, "turns": turns}
    return SimpleNamespace(slip=slip)


def test_friction_that_does_not_settle_is_damped_tenfold_more_up_to_the_most() -> None:
    d = Damping()
    assert d.springs(["ball"]) is None
    seen = []
    while d.unsettled():
        seen.append(d.prox)
    assert seen == pytest.approx([FIRST, 10 * FIRST, MOST])
    assert d.springs(["ball"]) == {"ball": MOST}


def test_a_step_moved_too_far_is_damped_while_that_shortens_it() -> None:
    d = Damping()
    assert not d.too_far(1.5 * REACH)  # within twice the reach: taken, shortened
    assert d.too_far(12 * REACH) and d.prox == pytest.approx(12 * FIRST)
    assert d.too_far(3 * REACH)  # halved: again
    assert not d.too_far(2.5 * REACH)  # not halved (the contacts drive it): taken
    assert d.too_far(12 * REACH)  # the next step's first try


def test_the_springs_fall_with_the_motion_to_none() -> None:
    d = Damping(prox=0.1)
    assert d.taken(REACH, 1.0) == 0.1 and d.prox == pytest.approx(0.1)
    d.taken(0.0, 0.5)
    assert d.prox == pytest.approx(0.01)
    for r in (0.4, 0.3, 0.2):
        d.taken(0.0, r)
    assert d.prox == pytest.approx(1e-5) and d.prox >= LEAST
    d.taken(0.0, 0.1)
    assert d.prox == 0.0


def test_damped_steps_that_do_not_lower_the_residual_are_followed_by_an_undamped_one() -> None:
    # the springs may carry a load the contacts never take (a ball sliding out of a
    # pinch): the next solve without them says whether they hold it
    d = Damping(prox=0.1)
    d.taken(REACH, 0.5)
    for _ in range(IDLE - 1):
        d.taken(REACH, 0.5)
        assert d.prox == pytest.approx(0.1)
    d.taken(REACH, 0.6)
    assert d.prox == 0.0
    d = Damping(prox=0.1)
    for r in (0.5, 0.4, 0.3, 0.2):  # falling: kept
        d.taken(REACH, r)
    assert d.prox == pytest.approx(0.1)


def test_a_body_not_held_is_followed_while_the_share_left_falls() -> None:
    d = Damping()
    first = _unheld(0.2)
    assert d.unheld(first, {"ball": 1}) and d.prox == FIRST
    assert d.taken(0.5 * REACH, 1.0) == FIRST and d.prox == 0.0  # next: undamped, a verdict
    assert d.unheld(_unheld(0.1), {"ball": 2})  # it fell: followed
    d.taken(0.0, 1.0)
    assert d.unheld(_unheld(0.1, turns=True), {})  # only a moment left now: followed
    d.taken(0.0, 1.0)
    last = _unheld(0.1, turns=True)
    assert not d.unheld(last, {"ball": 3})  # no progress: stops
    assert d.verdict == (last, {"ball": 3})  # the frame's verdict: where it stopped


def test_a_load_no_motion_balances_stops_at_once_and_following_is_bounded() -> None:
    d = Damping()
    assert d.unheld(_unheld(0.3), {})
    d.taken(0.0, 1.0)
    assert not d.unheld(_unheld(0.3), {})  # a slide between parallel pads
    d = Damping()
    n = 0
    while d.unheld(_unheld(1.0 / (n + 1)), {}):
        d.taken(0.0, 1.0)
        n += 1
    assert n == FOLLOW


def test_a_damped_solve_not_held_is_damped_more() -> None:
    d = Damping(prox=FIRST)
    assert d.unheld(_unheld(0.2), {}) and d.prox == pytest.approx(10 * FIRST)
    assert d.verdict is None  # a damped solve's is not the frame's verdict


def test_a_body_that_touches_nothing_leaves_all_its_load() -> None:
    d = Damping()
    assert d.unheld(SimpleNamespace(slip=None), {})  # falls: followed once
    d.taken(0.0, 1.0)
    assert not d.unheld(SimpleNamespace(slip=None), {})  # nothing gained: stops
