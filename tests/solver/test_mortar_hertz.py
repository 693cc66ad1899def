"""Weighted gaps between bodies on their smoothed surfaces: a coarse ball pressed onto a
(stiff) block by a plate meets Hertz as against a plane, whichever body is the slave, where
the flat facets' weighted gaps close late (contact.solver.mortar, smoothing)."""

import pytest

from benchmarks import plates
from contact.geometry.plane import Plane
from contact.solver import mortar, rows, solve_frame
from contact.solver.kept import Kept
from contact.solver.pairs import ContactPair

R = 0.02


def _force(size, press, ball_slave):
    ball, block = plates.ball("hex", size), plates.block(size)
    plate = Plane((0, 0, 2 * R), (0, 0, -1), motion=(0, 0, -press), name="plate")
    pair = ContactPair(ball, block, mortar=True)
    if not ball_slave:
        pair = ContactPair(block, ball, mortar=True)
    res = solve_frame([ball, block], [pair, ContactPair(ball, plate, mortar=True)], [plate])
    assert res.converged, res.stop_reason
    f = res.obstacle_forces["plate"][2]
    # the block carries what the plate gives: action and reaction
    assert res.contact_force["block"].sum(axis=0)[2] == pytest.approx(-f, rel=1e-9)
    return f / plates.hertz(press) - 1


@pytest.mark.parametrize("ball_slave", [True, False])
@pytest.mark.parametrize(("size", "press", "within"), [
    (0.003, 0.6e-3, 0.07), (0.003, 1.0e-3, 0.05), (0.006, 1.0e-3, 0.15),
])  # fmt: skip
def test_a_coarse_ball_on_a_block_meets_hertz_on_the_smoothed_surfaces(
    size, press, within, ball_slave
):
    assert abs(_force(size, press, ball_slave)) < within  # measured 0.7 .. 6.7 %


def test_the_flat_facets_close_late(monkeypatch):
    flat = mortar.mortar_coupling

    def unsmoothed(*args, **kwargs):
        return flat(*args, **{**kwargs, "smooth": False})

    monkeypatch.setattr(rows, "mortar_coupling", unsmoothed)
    monkeypatch.setattr(rows, "_KEPT", Kept(rows.KEEP))  # not the smoothed ones kept
    assert _force(0.006, 1.0e-3, True) < -0.3  # measured -37 %
    assert _force(0.003, 1.0e-3, True) < -0.07  # measured -9.3 %
