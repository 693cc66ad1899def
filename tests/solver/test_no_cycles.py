"""A solved frame's bodies and factorisations go when the caller lets them go: no
reference cycle keeps them for the garbage collector (a finite frame makes a body and a
factorisation per Newton step; held by cycles, 17 of them lived at once on the README
example, 2.1 GB)."""

import gc
import weakref

import numpy as np

import fem
from contact.geometry.plane import Plane
from contact.solver import solve_frame
from contact.solver.body import ElasticBody
from contact.solver.pairs import ContactPair


def _frame(mortar):
    mesh = fem.box_mesh((0.02, 0.02, 0.01), (4, 4, 2))
    top = np.flatnonzero(np.isclose(mesh.points[:, 2], 0.01))
    body = ElasticBody("block", mesh, fem.LinearElastic(1e6, 0.3),
                       prescribed=fem.node_dofs(top, [0, 1, 2]))  # fmt: skip
    under = Plane((0, 0, 0), (0, 0, 1), motion=(0, 0, 1e-4), name="table")
    res = solve_frame([body], [ContactPair(body, under, mortar=mortar)], [under])
    assert res.converged and res.total_contact_force("block")[2] > 0  # pushed up
    return weakref.ref(body), weakref.ref(body.solver), weakref.ref(body.solver._factorization)


def test_a_solved_frame_leaves_no_cycle_holding_its_factorisations():
    gc.collect()
    gc.disable()
    try:
        for mortar in (False, True):
            refs = _frame(mortar)
            assert all(r() is None for r in refs), mortar
    finally:
        gc.enable()
