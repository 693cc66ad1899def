"""Frictional contact sets on which the semismooth Newton's active sets cycle.

Each is a contact system taken from a grasp (``tests/solver/data/hard_friction.npz``: the
Delassus operator, rigid modes, right-hand side, loads, coefficients and tangential rows):
the cube of ``examples/cube.toml`` hanging from three fingers at mu 0.3 (two contact sets
of its last frame) and at mu 0.2 (near its slip limit: a Tresca problem with
the radii of a guess cannot carry its weight, and the fixed point of Tresca problems
swings between two states), and two free bodies pressed together by the hand with
friction. A Newton method with whole steps and Hueber, Stadler and Wohlmuth's slip
derivative cycles on all four; the solve must still meet Coulomb's law to the tolerance.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from contact.solver.friction import FRICTION_TOLERANCE, SLIP, STICK, solve_friction

DATA = Path(__file__).with_name("data") / "hard_friction.npz"


def _case(name: str) -> dict:
    with np.load(DATA) as data:
        return {
            key.split("__", 1)[1]: data[key] for key in data.files if key.startswith(name + "__")
        }


@pytest.mark.parametrize("name", ["cube_a", "cube_b", "cube_limit", "two_bodies"])
def test_a_cycling_contact_set_meets_coulombs_law(name: str) -> None:
    p = _case(name)
    mu, tangent = p["mu"], p["tangent"]
    res = solve_friction(
        p["w"], p["g"], p["rhs"], p["c"], mu=mu, tangent=tangent, start=p.get("start"),
        load_scale=float(p["load_scale"]),
    )
    assert res.solved and res.residual <= FRICTION_TOLERANCE
    k = mu.size
    lam, y = res.lam, res.y
    scale = np.abs(lam).max()
    ys = np.abs(y).max()
    n, gap = lam[:k], y[:k]
    assert n.min() >= 0.0 and gap.min() >= -1e-8 * ys
    assert np.abs(n * gap).max() <= 1e-8 * scale * ys
    has = tangent[:, 0] >= 0
    t, s = lam[tangent[has]], y[tangent[has]]
    size = np.linalg.norm(t, axis=1)
    assert (size - mu[has] * n[has]).max() <= 1e-8 * scale  # the cone
    stick = res.status[has] == STICK
    assert np.abs(s[stick]).max(initial=0.0) <= 1e-8 * ys
    moving = (res.status[has] == SLIP) & (np.linalg.norm(s, axis=1) > 1e-8 * ys)
    cos = np.einsum("ij,ij->i", t[moving], s[moving]) / (
        size[moving] * np.linalg.norm(s[moving], axis=1)
    )
    assert np.allclose(cos, -1.0, atol=1e-6)  # the force opposes the slip
    assert np.abs(p["g"].T @ lam - p["c"]).max() <= 1e-9 * scale  # the bodies balance


def test_a_spring_carries_what_the_contacts_do_not() -> None:
    """Held by springs, a body the contacts hold leaves them a load that vanishes with them."""
    p = _case("cube_b")
    carried = []
    for spring in (1e-2, 1e-5):
        res = solve_friction(
            p["w"], p["g"], p["rhs"], p["c"], mu=p["mu"], tangent=p["tangent"],
            load_scale=float(p["load_scale"]), spring=spring,
        )
        assert res.solved
        unbalanced = p["g"].T @ res.lam - p["c"]
        # the balance row: what the contacts leave, the spring carries
        assert np.allclose(unbalanced, spring * _unit(p) * res.a, atol=1e-12)
        carried.append(np.abs(unbalanced).max() / np.abs(p["c"]).max())
    # held: the spring's share falls with its stiffness (a thousandth, to within 10x)
    assert carried[1] < 1e-2 * carried[0]


def _unit(p: dict) -> float:
    g, w = p["g"], p["w"]
    return float(np.mean(np.einsum("ij,ij->i", g, g))) / float(np.mean(np.diag(w)))


def test_a_step_damped_by_springs_of_its_own_is_the_sprung_problem() -> None:
    """``prox``: springs that belong to the problem (a Newton step's damping) hold the
    amplitudes they are on, and only those; on every one, the spring's solution."""
    p = _case("two_bodies")
    args = (p["w"], p["g"], p["rhs"], p["c"])
    kw = dict(mu=p["mu"], tangent=p["tangent"], load_scale=float(p["load_scale"]))
    r = p["g"].shape[1]
    sprung = solve_friction(*args, **kw, spring=1e-2)
    damped = solve_friction(*args, **kw, prox=np.full(r, 1e-2))
    assert sprung.solved and damped.solved
    scale = np.abs(sprung.lam).max()
    assert np.abs(damped.lam - sprung.lam).max() <= 1e-8 * scale
    # on the first body's modes only: the second's balance is exact, the first's sprung
    prox = np.zeros(r)
    prox[:6] = 1e-2
    one = solve_friction(*args, **kw, prox=prox)
    assert one.solved
    unbalanced = p["g"].T @ one.lam - p["c"]
    assert np.allclose(unbalanced, prox * _unit(p) * one.a, atol=1e-9 * scale)
    assert np.abs(unbalanced[:6]).max() > 1e-6 * scale
