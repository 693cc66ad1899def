"""``[ball] load``: an external force and moment on the ball, and whether friction holds it.

A free solid ball squeezed between two force-driven frictional pads (normals +-x, a known
normal force ``N`` each, mu = 0.5), gravity and the load along z: held while the load
along the pads is below ``2 mu N``, not held above; a moment about the pads' axis is
resisted by the pads' torsional friction ``mu sum N_i rho_i``. Also: the nodal loads'
resultant, the factorisation shared when only the load changes, and bad input.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import fem
from contact.grasp import main
from contact.objects.ball import MAX_LOAD_FORCE, BallSpec
from contact.run import GraspRun
from contact.scene import SceneError, load_scene
from contact.scene import model as scene_model

MU, N, RHO, G = 0.5, 2.0, 1100.0, 9.81

#: The pads' scene; ``{load}`` is the ball's load keys, ``{table}`` extra planes.
PADS = """\
[scene]
gravity = [0.0, 0.0, -{g}]

[ball]
radius = 0.02
element = "hex"
mesh_size = 0.006
material = {{ E = 1.0e6, nu = 0.3, density = {rho} }}
load = {load}

[[plane]]
name = "left"
point = [-0.0205, 0.0, 0.0]
normal = [1.0, 0.0, 0.0]
force = [[0.0, {n}]]
friction = {mu}

[[plane]]
name = "right"
point = [0.0205, 0.0, 0.0]
normal = [-1.0, 0.0, 0.0]
force = [[0.0, {n}]]
friction = {mu}

[frames]
times = [0.0, 1.0]

[solver]
algorithm = "contact-space"
max_iterations = 40

[output]
directory = "{out}"
pictures = false
"""

#: A frictionless ball on a table, pushed down by a load that changes between frames.
TABLE = """\
[scene]
gravity = [0.0, 0.0, -9.81]

[ball]
radius = 0.02
element = "hex"
mesh_size = 0.006
center = [0.0, 0.0, 0.0195]
load = [[0.0, 0.0, 0.0, -0.5, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, -2.0, 0.0, 0.0, 0.0]]

[[plane]]
name = "table"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]

[frames]
times = [0.0, 0.5, 1.0]

[output]
directory = "{out}"
pictures = false
"""


def keys(*frame1: float) -> str:
    """Load keys: nothing at t = 0, ``frame1`` (fx, fy, fz, mx, my, mz) at t = 1."""
    return f"[[0.0, 0, 0, 0, 0, 0, 0], [1.0, {', '.join(map(str, frame1))}]]"


def pads(tmp_path: Path, load: str, name: str = "pads.toml") -> Path:
    path = tmp_path / name
    out = (tmp_path / "results").as_posix()
    path.write_text(PADS.format(g=G, rho=RHO, n=N, mu=MU, load=load, out=out))
    return path


def solve(path: Path, times: tuple[float, ...] = (0.0, 1.0)):
    run = GraspRun(load_scene(path))
    for t in times:
        result, _, _, bodies = run.frame(t)
    return run, result, bodies[0]


def weight(ball) -> float:
    return ball.mesh.volume * RHO * G


def slip_way(reason: str) -> list[float]:
    """The unit direction in ``"not held: ball slips along (x, y, z): ..."``."""
    return [float(v) for v in reason.split("(", 1)[1].split(")", 1)[0].split(",")]


# --- (a) a load along the pads: held below 2 mu N, slips above ----------------------


@pytest.mark.parametrize(("fraction", "held"), [(0.97, True), (1.03, False)])
def test_a_load_along_the_pads_is_held_below_two_mu_n(
    tmp_path: Path, fraction: float, held: bool
) -> None:
    run = GraspRun(load_scene(pads(tmp_path, "[]", "probe.toml")))
    w = weight(run.ball_body(0.0))
    fz = -(fraction * 2 * MU * N - w)  # the load adds to the weight along -z
    _, result, ball = solve(pads(tmp_path, keys(0, 0, fz, 0, 0, 0)))
    assert ball.loads.reshape(-1, 3).sum(axis=0)[2] == pytest.approx(fz - w, rel=1e-12)
    assert result.held is held, result.stop_reason
    if held:
        assert result.converged
        assert np.allclose(result.plane_positions["left"][1:], 0.0)
    else:
        assert result.stop_reason.startswith("not held: ball slips along (")
        assert slip_way(result.stop_reason)[2] < -0.99  # the way the load pulls: -z
        assert result.slip["available"] == pytest.approx(2 * MU * N, rel=1e-6)


def test_an_upward_load_beyond_the_weight_slips_up(tmp_path: Path) -> None:
    _, result, _ = solve(pads(tmp_path, keys(0, 0, 1.1 * 2 * MU * N + 0.4, 0, 0, 0)))
    assert result.stop_reason.startswith("not held: ball slips along (")
    assert slip_way(result.stop_reason)[2] > 0.99


# --- (b) a moment about the pads' axis: torsional friction ------------------------


def torsion_capacity(result, ball) -> float:
    """``mu sum N_i rho_i``: the pads' friction's largest moment about x (N m)."""
    nf = result.contact_fields["ball"]["normal_force"]
    x = ball.mesh.points
    return MU * float(nf @ np.hypot(x[:, 1], x[:, 2]))


def test_a_moment_about_the_pads_axis(tmp_path: Path) -> None:
    _, first, ball = solve(pads(tmp_path, keys(0, 0, 0, 1e-4, 0, 0), "small.toml"))
    capacity = torsion_capacity(first, ball)
    assert 5e-4 < capacity < 5e-3  # mu N times a contact patch's few mm, for two pads
    assert first.held is True and first.converged
    _, small, _ = solve(pads(tmp_path, keys(0, 0, 0, 0.3 * capacity, 0, 0), "third.toml"))
    assert small.held is True and small.converged
    _, big, _ = solve(pads(tmp_path, keys(0, 0, 0, 10 * capacity, 0, 0), "ten.toml"))
    # no balance: it turns about the pads' axis, the way the moment points
    assert big.held is False and not big.converged
    assert big.stop_reason.startswith("not held: ball turns about (1.000, ")
    assert big.slip["turns"] and big.slip["direction"][0] > 0.999
    # the moment not carried is about what passes the capacity
    assert big.slip["not_carried"] == pytest.approx(9 * capacity, rel=0.3)


# --- (c) the nodal loads' resultant -----------------------------------------------


def test_the_ball_s_loads_add_up_to_its_weight_and_the_load(tmp_path: Path) -> None:
    f1, m1 = np.array([0.3, -0.2, 0.5]), np.array([1e-3, 2e-3, -3e-3])
    run = GraspRun(load_scene(pads(tmp_path, keys(*f1, *m1))))
    for t, scale in ((0.25, 0.25), (1.0, 1.0)):
        ball = run.ball_body(t)
        f = ball.loads.reshape(-1, 3)
        total = np.array([0.0, 0.0, -weight(ball)]) + scale * f1
        assert np.abs(f.sum(axis=0) - total).max() < 1e-12 * np.abs(f).sum()
        moment = np.cross(ball.mesh.points, f).sum(axis=0)  # about the centre (0, 0, 0)
        assert np.abs(moment - scale * m1).max() < 1e-12 * np.abs(f).sum() * 0.02


def test_the_moment_is_about_the_placed_centre(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A ball that follows a joint: its load's moment is about where its centre went."""
    f1, m1 = np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 0.01])
    run = GraspRun(load_scene(pads(tmp_path, keys(*f1, *m1))))
    c, s = np.cos(0.4), np.sin(0.4)
    tf = np.eye(4)
    tf[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    tf[:3, 3] = [0.05, -0.02, 0.1]
    monkeypatch.setattr(run, "placement", lambda obj, t: tf)
    ball = run.ball_body(1.0)
    f = ball.loads.reshape(-1, 3)
    total = f1 + np.array([0.0, 0.0, -weight(ball)])
    assert np.abs(f.sum(axis=0) - total).max() < 1e-12 * np.abs(f).sum()
    moment = np.cross(ball.mesh.points - tf[:3, 3], f).sum(axis=0)
    assert np.abs(moment - m1).max() < 1e-12 * np.abs(f).sum() * 0.2


def test_no_load_leaves_the_ball_as_it_was(tmp_path: Path) -> None:
    run = GraspRun(load_scene(pads(tmp_path, "[]")))
    ball = run.ball_body(1.0)
    assert ball is run.objects[0]._body
    gravity = fem.gravity_load(ball.mesh, run.ball.material, (0.0, 0.0, -G))
    assert np.array_equal(ball.loads, gravity)


# --- the factorisation shared when the load changes ----------------------------


def test_a_changed_load_reuses_the_factorisation_frictionless(tmp_path: Path) -> None:
    path = tmp_path / "table.toml"
    path.write_text(TABLE.format(out=(tmp_path / "results").as_posix()))
    scene = load_scene(path)
    run = GraspRun(scene)
    for t in scene.frames:
        result, _, _, bodies = run.frame(t)
        fresh, _, _, _ = GraspRun(scene).frame(t)
        assert result.converged and fresh.converged
        u, v = result.displacement["ball"], fresh.displacement["ball"]
        assert np.abs(u - v).max() < 1e-9 * np.abs(v).max()
        total = fresh.total_contact_force("ball")
        assert np.allclose(result.total_contact_force("ball"), total, rtol=1e-9, atol=1e-12)
        assert total[2] == pytest.approx(weight(bodies[0]) + 0.5 + 1.5 * t)
    assert bodies[0].solver is run.objects[0]._body.solver
    assert run.objects[0]._body.solver.n_factorizations == 1


def test_a_changed_load_reuses_the_factorisation_with_friction(tmp_path: Path) -> None:
    """The frame after a restart (no history) is the frame of a fresh run."""
    scene = load_scene(pads(tmp_path, keys(0.0, 0.0, -0.8, 3e-4, 0.0, 0.0)))
    run = GraspRun(scene)
    run.frame(0.0)
    solver = run.objects[0]._body.solver
    again, _, _, bodies = run.restart(scene).frame(1.0)
    fresh, _, _, _ = GraspRun(scene).frame(1.0)
    assert bodies[0].solver is solver and solver.n_factorizations == 1
    assert again.held and fresh.held
    u, v = again.displacement["ball"], fresh.displacement["ball"]
    assert np.abs(u - v).max() < 1e-8 * np.abs(v).max()


# --- (d) bad input --------------------------------------------------------------


@pytest.mark.parametrize(
    ("load", "why"),
    [
        ("[[0.0, 1, 2, 3]]", "ball.load[0] = [0.0, 1, 2, 3]: must be 7 numbers"),
        (
            "[[0.0, 0, 0, 0, 0, 0, 0], [1.0, 1, 2, 3, 4, 5, true]]",
            "ball.load[1] = [1.0, 1, 2, 3, 4, 5, True]: must be 7 numbers",
        ),
        ('[[0.0, 0, 0, "1", 0, 0, 0]]', "ball.load[0] = [0.0, 0, 0, '1', 0, 0, 0]: must be 7"),
        ("[[0.0, 0, 0, nan, 0, 0, 0]]", "ball.load[0] = [0.0, 0, 0, nan, 0, 0, 0]: must be finite"),
        (
            "[[1.0, 0, 0, 0, 0, 0, 0], [1.0, 0, 0, 1, 0, 0, 0]]",
            "ball.load[1] = [1.0, 0, 0, 1, 0, 0, 0]: times must increase (previous 1)",
        ),
        (
            "[[0.0, 0, 0, 0, 0, 0, 0], [1.0, 0, 8.0e3, 8.0e3, 0, 0, 0]]",
            "ball.load[1] = [1.0, 0, 8000.0, 8000.0, 0, 0, 0]: the force must be at most 10000 N",
        ),
        (
            "[[0.0, 0, 0, 0, 0, -2.0e3, 0]]",
            "ball.load[0] = [0.0, 0, 0, 0, 0, -2000.0, 0]: the moment must be at most 1000 N m",
        ),
        ("[0.0, 0, 0, 0, 0, 0, 0]", "ball.load[0] = 0.0: must be 7 numbers"),
        ("3.0", "ball.load = 3.0: must be a list of [t, fx, fy, fz, mx, my, mz]"),
    ],
)
def test_bad_load_one_line_naming_the_key(tmp_path: Path, load: str, why: str) -> None:
    path = pads(tmp_path, load)
    with pytest.raises(SceneError) as err:
        load_scene(path)
    text = str(err.value)
    assert text.startswith(f"{path}: {why}"), text
    assert "\n" not in text


def test_bad_load_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    path = pads(tmp_path, "[[0.0, 0, 0, 1]]")
    assert main([str(path), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "ball.load[0]" in err and "\n" not in err
    assert not (tmp_path / "results").exists()


def test_the_spec_checks_on_its_own_and_the_bound_is_the_scene_s() -> None:
    assert MAX_LOAD_FORCE == scene_model.MAX_FORCE
    assert BallSpec(0.02, mesh_size=0.01).load == ()
    spec = BallSpec(0.02, mesh_size=0.01, load=[[0, 1, 0, 0, 0, 0, 0], [2, 3, 0, 0, 0, 0, 4]])
    force, moment = spec.load_at(1.0)
    assert force.tolist() == [2.0, 0.0, 0.0] and moment.tolist() == [0.0, 0.0, 2.0]
    assert spec.load_at(-1.0)[0][0] == 1.0 and spec.load_at(5.0)[1][2] == 4.0
    with pytest.raises(Exception, match=r"^ball\.load\[0\] = \(0, 1\): must be 7 numbers"):
        BallSpec(0.02, mesh_size=0.01, load=[(0, 1)])


def test_a_restart_takes_its_scene_s_load(tmp_path: Path) -> None:
    scene = load_scene(pads(tmp_path, keys(0.0, 0.0, -0.5, 0.0, 0.0, 0.0)))
    run = GraspRun(scene)
    first = run.ball_body(1.0).loads.reshape(-1, 3).sum(axis=0)
    other = replace(scene, ball=replace(scene.ball, load=((0.0, 0.0, 0.0, -0.9, 0, 0, 0),)))
    again = run.restart(other).ball_body(1.0)
    assert again.loads.reshape(-1, 3).sum(axis=0)[2] == pytest.approx(first[2] - 0.4, rel=1e-12)
    assert again.solver is run.objects[0]._body.solver
