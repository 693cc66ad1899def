"""The contact zone marked before factoring: the first set and a ring around it."""

import numpy as np

from contact.solver.zone import APPROACH, RING, master_zone, slave_zone


def grid(h=1.0, n=21):
    """Nodes on a square grid in the plane z = 0, spacing ``h``, centred."""
    s = (np.arange(n) - n // 2) * h
    x, y = np.meshgrid(s, s, indexing="ij")
    return np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])


def test_an_overlap_zone_is_the_first_set_and_a_ring():
    pts = grid()
    nodes = np.arange(len(pts))
    r = np.linalg.norm(pts[:, :2], axis=1)
    gap = r**2 / 40.0 - 1.0  # a sphere of radius 20 pressed 1 deep: overlap radius 6.3
    local = np.ones(len(pts))
    first = gap <= -0.5  # half the deepest overlap: r <= 4.47
    zone = slave_zone(pts, nodes, gap, first, local)
    assert zone[first].all()
    # the ring: every node within RING elements of the first set, none further
    d = np.min(np.linalg.norm(pts[:, None, :] - pts[first][None], axis=2), axis=1)
    assert np.array_equal(zone, d <= RING)
    assert zone.sum() < (r < 6.3).sum()  # tighter than the whole overlap


def test_without_overlap_the_zone_is_around_the_closest_approach():
    pts = grid()
    nodes = np.arange(len(pts))
    r = np.linalg.norm(pts[:, :2], axis=1)
    gap = 0.5 + r**2 / 40.0  # half an element apart at the closest
    zone = slave_zone(pts, nodes, gap, np.zeros(len(pts), bool), np.ones(len(pts)))
    core = gap <= 0.5 + APPROACH  # within APPROACH elements of the closest approach
    assert 0 < core.sum() < len(pts)
    d = np.min(np.linalg.norm(pts[:, None, :] - pts[core][None], axis=2), axis=1)
    assert np.array_equal(zone, d <= RING)
    assert zone[np.argmin(r)] and not zone[np.argmax(r)]
    assert not slave_zone(pts[:0], nodes[:0], gap[:0], gap[:0] < 0, gap[:0]).size


def test_master_nodes_within_an_element_plus_the_overlap():
    slave = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0]])
    gap = np.array([-2.0, 0.5])
    local = np.array([1.0, 1.0])
    master = np.array([[0.0, 0.0, 2.9], [0.0, 0.0, 3.1], [10.0, 0.0, 0.9], [10.0, 0.0, 1.1]])
    ok, near = master_zone(slave, gap, local, master)
    # reach 1 + 2 around the overlapping node, 1 around the other
    assert ok.tolist() == [True, False, True, False]
    assert np.allclose(near[ok], [2.9 - 2.0, 0.9 + 0.5])
    assert np.isinf(near[~ok]).all()
