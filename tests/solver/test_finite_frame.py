"""Finite-strain frames: Newton's method around the contact-space solve, against the same
problem solved by finite-strain Newton with the contact written as prescribed values."""

import numpy as np
import pytest

import fem
from contact.errors import ContactError
from contact.geometry.plane import Plane
from contact.solver import ContactSettings, solve_frame
from contact.solver.body import ElasticBody
from contact.solver.finite import FiniteBody, solve_finite_frame
from contact.solver.pairs import ContactPair

E, NU, H = 1.0e6, 0.45, 0.01
MAT = fem.LinearElastic(E, NU)


def _bonded(kind):
    mesh = fem.box_mesh((H, H, H), (3, 3, 3))
    if kind == "tetra":
        mesh = fem.hex_to_tet(mesh)
    bottom = np.flatnonzero(np.isclose(mesh.points[:, 2], 0.0))
    return mesh, (3 * bottom[:, None] + np.arange(3)).ravel()


def _plate(press):
    return Plane((0, 0, H), (0, 0, -1), motion=(0, 0, -press * H), name="plate")


@pytest.mark.parametrize(("kind", "strain"), [("hexahedron", 0.2), ("tetra", 0.15)])
def test_a_bonded_block_pressed_by_a_frictionless_plate(kind, strain):
    # the plate is frictionless: its contact is the top's u_z prescribed, u_x and u_y free
    mesh, base = _bonded(kind)
    body = FiniteBody("block", mesh, MAT, prescribed=base)
    start = None
    for press in np.linspace(0.05, strain, round(strain / 0.05)):
        plate = _plate(press)
        out = solve_finite_frame([body], [ContactPair(body, plate)], [plate], start=start)
        assert out.converged and out.steps <= 6, out.stop_reason
        start = {"block": out.displacement["block"]}
    top = np.flatnonzero(np.isclose(mesh.points[:, 2], H))
    ref = fem.solve_finite_strain(
        mesh, MAT, prescribed=np.concatenate([base, 3 * top + 2]),
        values=np.concatenate([np.zeros(base.size), np.full(top.size, -strain * H)]),
        increments=round(strain / 0.05),
    )  # fmt: skip
    assert ref.converged
    assert np.abs(out.displacement["block"] - ref.u).max() <= 1e-9 * H
    force = out.result.obstacle_forces["plate"][2]
    assert force == pytest.approx(-ref.reactions[3 * top + 2].sum(), rel=1e-9)
    assert out.residual <= 1e-8


def test_at_small_strain_it_is_the_linear_frame():
    mesh, base = _bonded("hexahedron")
    press = 1e-6
    plate = _plate(press)
    fin = FiniteBody("block", mesh, MAT, prescribed=base)
    out = solve_finite_frame([fin], [ContactPair(fin, plate)], [plate])
    lin = ElasticBody("block", mesh, MAT, prescribed=base)
    ref = solve_frame([lin], [ContactPair(lin, plate)], [plate], ContactSettings())
    u = ref.displacement["block"]
    assert np.abs(out.displacement["block"] - u).max() <= 1e-5 * np.abs(u).max()


def test_what_it_does_not_take_yet_is_refused():
    mesh, base = _bonded("hexahedron")
    plate = _plate(0.05)
    free = FiniteBody("block", mesh, MAT)
    with pytest.raises(ContactError, match="needs supports"):
        solve_finite_frame([free], [ContactPair(free, plate)], [plate])
    held = FiniteBody("block", mesh, MAT, prescribed=base)
    with pytest.raises(ContactError, match="frictionless"):
        solve_finite_frame([held], [ContactPair(held, plate, friction=0.3)], [plate])
