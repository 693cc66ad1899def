"""The held body's contact pressure picture: the pressure it draws and where it looks from."""

from __future__ import annotations

import numpy as np
import pytest

import fem
from contact.output.pressure import COVER, PressureScale, contact_pressure, pressure_views


def test_contact_pressure_is_force_over_tributary_area() -> None:
    # a 2 x 2 x 1 block of unit bricks: a top corner node carries a quarter of one face,
    # a top edge node two quarters, the top centre four
    mesh = fem.box_mesh((2.0, 2.0, 1.0), (2, 2, 1))
    x = mesh.points
    top = np.isclose(x[:, 2], 1.0)
    corner = np.flatnonzero(top & np.isclose(x[:, 0], 0) & np.isclose(x[:, 1], 0))[0]
    centre = np.flatnonzero(top & np.isclose(x[:, 0], 1) & np.isclose(x[:, 1], 1))[0]
    fn = np.zeros(mesh.n_points)
    fn[[corner, centre]] = 3.0
    p = contact_pressure(mesh, x, fn)
    # the corner also lies on two side faces: 1/4 of each
    assert p[corner] == pytest.approx(3.0 / 0.75)
    assert p[centre] == pytest.approx(3.0 / 1.0)
    assert np.count_nonzero(p) == 2
    # measured where the body is: stretched twice in x and y, a quarter of the pressure
    p2 = contact_pressure(mesh, x * [2.0, 2.0, 1.0], fn)
    assert p2[centre] == pytest.approx(3.0 / 4.0)


def _sphere(n: int = 400) -> np.ndarray:
    i = np.arange(n) + 0.5
    polar = np.arccos(1 - 2 * i / n)
    turn = np.pi * (1 + 5**0.5) * i
    return np.column_stack([np.cos(turn) * np.sin(polar), np.sin(turn) * np.sin(polar),
                            np.cos(polar)])  # fmt: skip


def test_views_see_every_contact_from_outside_the_largest_first() -> None:
    ball = 0.02 * _sphere() + [0.1, 0.0, 0.0]
    d = (ball - [0.1, 0.0, 0.0]) / 0.02
    # a thumb at -y (the largest force), two fingers around +y, a table below
    patches = [
        (d @ [0, -1, 0] > 0.95, 2.0),
        (d @ np.array([0.3, 1, 0]) / np.hypot(0.3, 1) > 0.97, 0.5),
        (d @ np.array([-0.3, 1, 0]) / np.hypot(0.3, 1) > 0.97, 0.5),
        (d @ [0, 0, -1] > 0.97, 0.3),
    ]
    pts = np.concatenate([ball[m] for m, _ in patches])
    w = np.concatenate([np.full(m.sum(), f / m.sum()) for m, f in patches])
    views = pressure_views([(pts, w)], [ball])
    assert 1 <= len(views) <= 3
    axes = [np.subtract(v.position, v.focus) / np.linalg.norm(np.subtract(v.position, v.focus))
            for v in views]  # fmt: skip
    # the first looks at the thumb: its push is the largest
    assert axes[0] @ [0, -1, 0] > 0.99
    # every contact faces some camera within the cover
    facing = np.max([d_ @ np.array(axes).T for d_ in (pts - [0.1, 0, 0]) / 0.02], axis=1)
    assert (facing >= np.cos(COVER) - 1e-12).all()
    for v in views:
        np.testing.assert_allclose(v.focus, [0.1, 0.0, 0.0], atol=1e-3)


def test_no_contact_no_view_and_the_scale_s_unit() -> None:
    ball = 0.02 * _sphere()
    assert pressure_views([(np.zeros((0, 3)), np.zeros(0))], [ball]) == []
    assert PressureScale.of("ball", 4e4).title == "ball: contact pressure (kPa)"
    assert PressureScale.of("ball", 2e6).scale == 1e-6
