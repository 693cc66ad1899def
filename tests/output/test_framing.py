"""The main view looks where the held body's contacts can be seen."""

import numpy as np

from contact.output.framing import clear_direction, main_view, visible


def _square(centre, normal, size):
    """Two triangles of a square of side ``size`` at ``centre`` across ``normal``."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    a = np.cross(n, [0, 0, 1.0] if abs(n[2]) < 0.9 else [1.0, 0, 0])
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    c = np.asarray(centre, float)
    p = [c + size / 2 * (s * a + t * b) for s, t in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    return np.array([[p[0], p[1], p[2]], [p[0], p[2], p[3]]])


def test_a_point_behind_a_triangle_is_hidden_and_one_before_it_is_not():
    wall = _square((0, 0, 1.0), (0, 0, 1), 2.0)
    points = np.array([[0, 0, 0.0], [0, 0, 2.0], [5, 0, 0.0]])
    # looking down -z from above: the first is behind the wall, the second before it,
    # the third beside it
    assert visible(points, (0, 0, 1.0), wall).tolist() == [False, True, True]
    assert visible(points, (0, 0, -1.0), wall).tolist() == [True, False, True]


def test_the_view_turns_from_a_finger_in_front_of_the_contacts():
    # a ball pinched along x, a finger's back (a wall) between it and the preferred eye
    theta = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    ring = np.column_stack([np.zeros_like(theta), 0.2 * np.cos(theta), 0.2 * np.sin(theta)])
    side = np.array([1.0, 0.0, 0.0])
    contacts = np.vstack([ring + side, ring - side])
    preferred = np.array([0.0, -1.0, 0.3])
    preferred /= np.linalg.norm(preferred)
    wall = _square(1.5 * preferred, preferred, 4.0)
    assert not visible(contacts, preferred, wall).any()
    d = clear_direction([contacts], [wall], preferred, 2.0)
    assert visible(contacts, d, wall).all()
    box = np.array([[-1.0, -1.0, -1.0], [1.0, 1.0, 1.0]])
    view = main_view(box, axis=np.array([0.0, 0.0, 1.0]), sight=([contacts], [wall]))
    eye = np.asarray(view.position) - np.asarray(view.focus)
    assert visible(contacts, eye, wall).all()
    # nothing in the way: the view stays where it was going to look
    assert np.allclose(clear_direction([contacts], [np.zeros((0, 3, 3))], preferred, 2.0),
                       preferred)
