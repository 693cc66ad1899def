"""Which modes a frictional Newton step leaves undetermined (contact.solver.reducedstep)."""

import numpy as np

from contact.solver.reducedstep import OWN, _unseen


def _jacobian(own: np.ndarray) -> tuple[np.ndarray, int]:
    """One closed contact row moving mode 0 alone (stiffness 1e3), three modes, ``own``."""
    m, r = 1, 3
    j = np.zeros((m + r, m + r))
    j[0, 0], j[0, m] = 1.0, 1e3
    j[m:, :m] = 1e3 * np.eye(r)[:, :1]
    j[m:, m:] = own
    return j, m


def test_a_mode_held_only_by_a_small_stiffness_of_its_own_is_undetermined():
    # a ball on one stuck node: its turn about the node held by its weight's arm alone
    for scale, seen in ((0.1 * OWN, False), (10 * OWN, True)):
        own = np.diag([0.0, -scale * 1e3, 0.0])
        j, m = _jacobian(own)
        v0 = _unseen(j, np.array([True]), m, np.zeros(3), None)
        along = np.abs(v0.T @ np.eye(3)[1]).max(initial=0.0)
        assert (along < 1e-12) == seen
        assert np.abs(v0.T @ np.eye(3)[2]).max() == 1.0  # mode 2: nothing holds it


def test_a_borders_auxiliaries_are_held_by_their_own_rows():
    own = np.zeros((3, 3))
    own[2, 2] = -1e-2  # below OWN of the contact's, but the auxiliary's own equation
    j, m = _jacobian(own)
    aux = np.array([False, False, True])
    v0 = _unseen(j, np.array([True]), m, np.zeros(3), aux)
    assert v0.shape == (3, 1) and abs(abs(v0[1, 0]) - 1.0) < 1e-12


def test_a_loaded_unseen_mode_stays_in_the_step():
    j, m = _jacobian(np.zeros((3, 3)))
    v0 = _unseen(j, np.array([True]), m, np.array([0.0, 1.0, 0.0]), None)
    assert v0.shape == (3, 1) and abs(abs(v0[2, 0]) - 1.0) < 1e-12
