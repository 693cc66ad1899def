"""A free ball that the first linear solve slides: caught by what it slides into, or not
held. Frictionless contacts hold a free ball only where their normals enclose it."""

import functools
from pathlib import Path

import numpy as np
import pytest

import contact.solver.contactset as contactset
import contact.solver.held as held
import fem
from contact.geometry.plane import Plane
from contact.run import GraspRun
from contact.scene.read import load_scene
from contact.solver import ContactRows, ContactSettings, FrameState, solve_frame
from contact.solver.body import ElasticBody
from contact.solver.delassus import BodyState
from contact.solver.pairs import ContactPair
from tests.helpers import example

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = example("bowl", "linear")  # the linear model's first solve slides the ball


def frame(tmp_path, name, text, t=1.0):
    """The example's frame at ``t`` for a scene edited to ``text``."""
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return GraspRun(load_scene(path)).frame(t)


def check_balance(res):
    """The free ball in balance; action equals reaction between ball, hand and planes."""
    ball = res.total_contact_force("ball")
    hand = res.total_contact_force("hand")
    planes = sum(res.obstacle_forces.values())
    scale = np.linalg.norm(hand)
    assert scale > 1.0  # newtons: the fingers press the ball
    assert np.abs(ball).max() <= 1e-9 * scale
    assert np.abs(ball + hand + planes).max() <= 1e-9 * scale


def stiff_flesh_scene():
    # flesh ten times stiffer than the example's, each fingertip closed 1 mm into the
    # ball (the seed's point search: the pads go deeper): the first solve slides the
    # ball towards the wrist, out of its fingertip contacts, into the proximal wall
    text = EXAMPLE.replace("E = 5.0e4", "E = 5.0e5")
    text = text.replace("press = 0.001", "press = 0.001\nfirst_contact = false")
    assert text.count("press = 0.001\nfirst_contact = false") == 4
    return text


def test_a_ball_the_fingers_slide_is_caught_by_what_it_slides_into(tmp_path, monkeypatch):
    # the first set's near rows (NEAR) keep this ball from sliding in the first place:
    # without them, what a slide runs into must catch it
    monkeypatch.setattr(contactset, "NEAR", 0.0)
    res, *_ = frame(tmp_path, "stiff", stiff_flesh_scene())
    assert res.converged, res.stop_reason
    assert res.penetration_ratio <= 1e-3
    check_balance(res)
    # the first solve slid the ball by more than half an element (6 mm bricks)
    assert res.history[0].max_change > 3e-3
    # the proximal wall of the bowl holds it
    assert np.linalg.norm(res.obstacle_forces["cradle_proximal"]) > 1.0
    # stopped at the slide instead, the same frame is "not held", never a silent answer
    monkeypatch.setattr(held, "SLIDES", 0)
    res, *_ = frame(tmp_path, "stiff", stiff_flesh_scene())
    assert not res.converged
    assert res.stop_reason.startswith("not held: ball slid ")


def test_a_ball_whose_walls_touch_it_between_nodes_rests_in_them(tmp_path, monkeypatch):
    # a tetrahedral ball (as other tools give) whose nodes miss the bowl's tangent points,
    # each fingertip closed 1 mm into it: the walls' near nodes are open rows of the first
    # solve, which keep the ball in the bowl instead of sliding it through a wall
    centre = (0.0, 0.06, -0.058)
    mesh = fem.hex_to_tet(fem.shell_mesh(0.032, 0.035, 0.006, center=centre))
    fem.write_mesh(tmp_path / "ball.vtu", mesh)
    text = EXAMPLE.replace(
        'element = "hex"\nmesh_size = 0.005           # m\n',
        f'mesh = "{(tmp_path / "ball.vtu").as_posix()}"\n',
    ).replace("press = 0.001", "press = 0.001\nfirst_contact = false")
    assert text.count("press = 0.001\nfirst_contact = false") == 4 and "ball.vtu" in text
    res, *_ = frame(tmp_path, "tets", text)
    assert res.converged, res.stop_reason
    assert res.iterations <= 4
    assert res.penetration_ratio <= 1e-3
    check_balance(res)
    assert res.history[0].max_change < 0.012  # two 6 mm elements
    # without them the first solve slides the ball 25 mm, through the wall
    monkeypatch.setattr(contactset, "NEAR", 0.0)
    res, *_ = frame(tmp_path, "tets", text)
    assert res.history[0].max_change > 0.018


def test_rows_found_after_a_jump_are_linearised_where_the_ball_was(tmp_path, monkeypatch):
    # the fingers closed 2.8 mm into the ball's facets: the first solve, which holds only the
    # overlapping rows, throws the ball 10 mm up into the palm; the palm's rows are taken
    # where the ball was before, on the facets it was coming to, and it settles
    text = EXAMPLE.replace("press = 0.001", "press = 0.0028")
    assert text.count("press = 0.0028") == 4
    # the first set's near rows (NEAR) hold the palm from the start: without them the
    # rows found after the jump must bring the ball back
    monkeypatch.setattr(contactset, "NEAR", 0.0)
    res, extra, *_ = frame(tmp_path, "press", text)
    assert res.converged, res.stop_reason
    # each finger closed until its first skin node was 2.8 mm inside the ball
    flexed = extra["auto_flexion"]
    assert set(flexed) == {f"{f}_mcp" for f in ("index", "middle", "ring", "little")}
    for joint, out in flexed.items():
        assert out["converged"], joint
        assert out["distance"] == pytest.approx(-0.0028, abs=1e-4), joint
    assert res.history[0].max_change > 0.005
    assert res.penetration_ratio <= 1e-3
    check_balance(res)
    # taken where it landed (some nodes 12 mm inside the flesh, on whatever facet is
    # nearest there), the rows never settle
    monkeypatch.setattr(held, "JUMP", np.inf)
    res, *_ = frame(tmp_path, "press", text)
    assert not res.converged


@functools.cache
def pad_scene(walled=True, on_table=True):
    """A ball on a table (or none), pressed from above and the side by a small pad (back
    fixed), towards a wall 1 mm off (or none)."""
    r = 0.02
    ball = ElasticBody(
        "ball",
        fem.ball_mesh(r, divisions=6, layers=3, center=(0, 0, r)),
        fem.LinearElastic(1e6, 0.3),
    )
    a = np.radians(30.0)
    n = np.array([np.sin(a), 0.0, -np.cos(a)])  # pushes the ball along +x and down
    t = np.array([np.cos(a), 0.0, np.sin(a)])
    side, h = 0.008, 0.004
    box = fem.box_mesh((side, side, h), (3, 3, 2), (-side / 2, -side / 2, 0.0))
    origin = np.array([0.0, 0.0, r]) - (r - 0.003) * n  # 3 mm into the ball
    points = box.points @ np.column_stack([t, [0.0, 1.0, 0.0], -n]).T + origin
    back = np.flatnonzero(np.isclose(box.points[:, 2], h))
    pad = ElasticBody(
        "pad",
        fem.Mesh(points, box.cells),
        fem.LinearElastic(1e5, 0.3),
        prescribed=fem.node_dofs(back),
        supports={"back": back},
    )
    table = Plane([0, 0, 0], [0, 0, 1], name="table")
    wall = Plane([r + 0.001, 0, 0], [-1, 0, 0], name="wall")
    planes = [p for p, keep in ((table, on_table), (wall, walled)) if keep]
    pairs = [ContactPair(ball, p) for p in planes]
    pairs += [ContactPair(ball, pad), ContactPair(pad, ball)]
    return [ball, pad], pairs, planes


def test_a_ball_a_small_pad_pushes_into_a_wall_is_held_there():
    bodies, pairs, planes = pad_scene()
    res = solve_frame(bodies, pairs, planes, ContactSettings())
    assert res.converged, res.stop_reason
    pad = res.total_contact_force("pad")
    table, wall = res.obstacle_forces["table"], res.obstacle_forces["wall"]
    # the pad pushes the ball along +x and down (its normal, 30 degrees from -z); the
    # wall and the table take it
    assert -pad[0] > 0 and pad[2] > 0
    # (both meshes' rows push where the pad's flat face meets the faceted ball: a few
    # per cent off the face's normal)
    assert -pad[0] / pad[2] == pytest.approx(np.tan(np.radians(30.0)), rel=0.1)
    assert np.abs(pad + table + wall).max() <= 1e-9 * np.linalg.norm(pad)


def test_a_ball_a_small_pad_presses_on_a_table_is_held_under_its_edge():
    # with no wall the pad pushes the ball along +x until its lower edge presses on the
    # ball from straight above: then the pad's force on the ball is vertical, and the
    # table takes it
    bodies, pairs, planes = pad_scene(walled=False)
    res = solve_frame(bodies, pairs, planes, ContactSettings())
    assert res.converged, res.stop_reason
    pad, table = res.total_contact_force("pad"), res.obstacle_forces["table"]
    assert pad[2] > 0 and abs(pad[0]) <= 1e-9 * pad[2]
    assert np.abs(pad + table).max() <= 1e-9 * pad[2]
    assert res.displacement["ball"][:, 0].mean() > 0.002  # it moved along +x


def test_a_ball_a_small_pad_pushes_away_is_not_held():
    # with nothing else the pad pushes the ball away until its contacts open; any place
    # further along balances too, so the frame cannot say where the ball is, and says so
    # instead of "converged" with no force
    bodies, pairs, planes = pad_scene(walled=False, on_table=False)
    res = solve_frame(bodies, pairs, planes, ContactSettings())
    assert not res.converged
    assert res.stop_reason.startswith("not held: ball touches nothing (moved ")
    d = res.stop_reason.split("along (")[1].split(")")[0]
    direction = np.array([float(v) for v in d.split(",")])
    n = np.array([np.sin(np.radians(30.0)), 0.0, -np.cos(np.radians(30.0))])
    assert direction @ n > 0.9  # along the pad's normal, the way it pushes
    assert np.abs(res.total_contact_force("pad")).max() == 0.0


@pytest.mark.parametrize("name", ["table", "wall", "pad"])
def test_what_the_ball_nearly_touches_gets_open_rows_in_the_first_set(name):
    bodies, pairs, planes = pad_scene()
    frame_ = FrameState(bodies, planes, pairs, ContactSettings())
    u = {b.name: np.zeros((b.mesh.n_points, 3)) for b in bodies}
    plain, _, _ = frame_.contacts.new_rows(ContactRows(), u, touching=True)
    near, _, _ = frame_.contacts.new_rows(ContactRows(), u, touching=True, near=0.5)
    i = next(k for k, p in enumerate(pairs) if p.master.name == name)
    p = frame_.measure_pair(i, u, frame_.margin)
    local = frame_.local["ball"][p.nodes]
    within = p.nodes[(p.gap >= -frame_.tol(pairs[i], p.nodes)) & (p.gap < 0.5 * local)]
    beyond = p.nodes[p.gap >= 0.5 * local]
    mine = near.node[near.pair == i]
    assert within.size and np.isin(within, mine).all()
    assert not np.isin(beyond, mine).any()
    assert np.isin(plain.node[plain.pair == i], mine).all()
    assert (near.pair == i).sum() > (plain.pair == i).sum()


@pytest.mark.parametrize("angle", [0.05, 0.2])
def test_a_ball_turned_past_small_rotations_is_not_a_result(angle):
    # the rigid part of a free ball's displacement: a turn about z (and a shift); past
    # MAX_TURN the linearised rotation stretches the ball and the frame says so
    ball = pad_scene()[0][0]
    x = ball.mesh.points - ball.mesh.points.mean(axis=0)
    u = np.cross([0.0, 0.0, angle], x) + np.array([0.001, 0.0, 0.0])
    rigid = ball.solver.modes.T @ u.ravel()  # orthonormal modes: the amplitudes
    state = BodyState(u.ravel(), np.zeros(u.size), rigid)
    reason = held.turned([ball], {"ball": state})
    if angle < held.MAX_TURN:
        assert reason == ""
    else:
        assert reason.startswith(f"ball turned {np.degrees(angle):.3g} deg, past the 5.73 deg")
