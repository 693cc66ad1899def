"""Objects in a run: balance and action-reaction with the hand, fixed objects, bad meshes.

The blocks are volume meshes (structured bricks written as VTU), used as they are: no
fTetWild fill, the same mesh every run.
"""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np
import pytest

import fem
from contact.grasp import main
from contact.run import GraspRun
from contact.scene import load_scene
from meshes.objects.make import cube_surface

E_BLOCK = 1.0e6


def block(tmp_path: Path, edge: float = 0.02, n: int = 4, name: str = "block") -> Path:
    """A cube of bricks centred at its origin, as a VTU file."""
    mesh = fem.box_mesh((edge,) * 3, (n,) * 3, origin=(-edge / 2,) * 3)
    path = tmp_path / f"{name}.vtu"
    fem.write_mesh(path, mesh)
    return path


TWO = """\
[scene]
name = "two"

[ball]
radius = 0.035
kind = "hollow"
thickness = 0.003
pressure = 2.0e4
element = "hex"
mesh_size = 0.005
center = [0.0, 0.06, -0.058]
material = {{ E = 1.5e6, nu = 0.45, density = 1100.0 }}
friction = 0.5

[[object]]
mesh = "{block}"
center = [0.0, 0.06, -0.1030]
material = {{ E = 1.0e6, nu = 0.3, density = 1000.0 }}
friction = 0.5

[hand]
resolution = "coarse"

[[hand.keyframe]]
time = 0.0
angles = {{}}

[[plane]]
name = "table"
point = [0.0, 0.0, -0.1130]
normal = [0.0, 0.0, 1.0]
offsets = [[0.0, 0.0, 0.0, 0.0015]]

[frames]
times = [0.0]

[output]
directory = "{out}"
pictures = false
"""


@pytest.mark.parametrize("gaps", ["nodal", "weighted"])
def test_two_objects_and_the_hand_balance_and_act_and_react(tmp_path: Path, gaps: str) -> None:
    # the table lifts a block into the ball and the ball into the palm: ball/hand,
    # ball/block and block/table contacts in one frame, with friction; by weighted gaps
    # the objects, and the hand and the ball, meet in one frictional mortar pair each and
    # the table by weighted rows
    path = tmp_path / "two.toml"
    text = TWO.format(block=block(tmp_path).as_posix(), out=(tmp_path / "r").as_posix())
    path.write_text(text + f'\n[solver]\ngaps = "{gaps}"\n')
    run = GraspRun(load_scene(path))
    res, _, _, bodies = run.frame(0.0)
    assert res.converged and res.held, res.stop_reason
    pairs = set(res.contacts["pair"])
    if gaps == "weighted":
        assert "block/ball" not in pairs and ("ball/hand" in pairs) != ("hand/ball" in pairs)
    assert {"ball/hand", "ball/block", "block/table"} <= pairs | {"hand/ball", "block/ball"}
    assert any(p in pairs for p in ("ball/hand", "hand/ball"))
    assert any(p in pairs for p in ("ball/block", "block/ball"))
    scale = sum(np.abs(res.contact_force[b.name]).sum() for b in bodies)
    for b in bodies[:2]:  # the free objects: in balance in force and moment
        f = res.contact_force[b.name] + b.loads.reshape(-1, 3)
        assert np.abs(res.contact_force[b.name]).sum() > 0.05 * scale
        assert np.abs(f.sum(axis=0)).max() <= 1e-10 * scale
        c = b.mesh.points.mean(axis=0)
        size = np.ptp(b.mesh.points, axis=0).max()
        assert np.abs(np.cross(b.mesh.points - c, f).sum(axis=0)).max() <= 1e-10 * scale * size
    # action and reaction: every body and the plane together carry nothing
    total = sum(res.contact_force[b.name].sum(axis=0) for b in bodies)
    total = total + sum(res.obstacle_forces.values())
    assert np.abs(total).max() <= 1e-10 * scale


PLATES = """\
[[object]]
name = "block"
mesh = "{block}"
material = {{ E = {E}, nu = 0.3, density = 1000.0 }}
{fixed}

[[object]]
name = "top"
mesh = "{top}"
center = [0.0, 0.0, 0.02]
material = {{ E = {E}, nu = 0.3, density = 1000.0 }}

[[plane]]
name = "press"
point = [0.0, 0.0, 0.03]
normal = [0.0, 0.0, -1.0]
offsets = [[0.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, -0.0002]]

{bottom}

[frames]
times = [1.0]

[output]
directory = "{out}"
pictures = false
"""

BOTTOM = """\
[[plane]]
name = "bottom"
point = [0.0, 0.0, -0.01]
normal = [0.0, 0.0, 1.0]
"""


@pytest.mark.parametrize("fixed", [False, True])
def test_a_stack_of_blocks_is_pressed_as_its_springs_in_series(tmp_path: Path, fixed: bool) -> None:
    # two 20 mm blocks stacked between plates (or the lower one fixed, no plate under it):
    # frictionless, uniform stress, F = E A d / (2 H) for the pressed stack, or E A d / H
    # for the upper block on a rigid fixed one: linear bricks and the blocks' mortar rows
    # (the contact patch test) are exact
    path = tmp_path / "stack.toml"
    path.write_text(
        PLATES.format(
            block=block(tmp_path).as_posix(), top=block(tmp_path, name="top").as_posix(),
            E=E_BLOCK, fixed="fixed = true" if fixed else "", bottom="" if fixed else BOTTOM,
            out=(tmp_path / "r").as_posix(),
        )
    )  # fmt: skip
    run = GraspRun(load_scene(path))
    res, _, _, _ = run.frame(1.0)
    assert res.converged, res.stop_reason
    a, h, d = 0.02**2, 0.02, 0.0002
    expected = E_BLOCK * a * d / (h if fixed else 2 * h)
    press = res.obstacle_forces["press"]
    assert press[2] == pytest.approx(expected, rel=1e-8)
    top = res.contact_force["top"].sum(axis=0)
    low = res.contact_force["block"].sum(axis=0)
    assert np.abs(top).max() <= 1e-9 * expected  # the free upper block in balance
    if fixed:  # the fixed block's reaction is the press's force
        assert low[2] == pytest.approx(-expected, rel=1e-8)
        assert np.abs(res.displacement["block"]).max() == 0.0
    else:
        assert res.obstacle_forces["bottom"][2] == pytest.approx(-expected, rel=1e-8)


def _bad(kind: str) -> tuple[np.ndarray, np.ndarray]:
    """A 40 mm cube surface made bad in one way."""
    p, t = cube_surface(0.04, 0.04)
    if kind == "open":
        return p, t[2:]
    if kind == "non-manifold":
        q, u = cube_surface(0.04, 0.04)
        return np.vstack([p, q + 0.04 * np.array([1.0, 1.0, 0.0])]), np.vstack([t, u + len(p)])
    if kind == "wound":
        t = t.copy()
        t[5] = t[5, ::-1]
        return p, t
    if kind == "self-intersecting":
        return np.vstack([p, p + 0.01]), np.vstack([t, t + len(p)])
    if kind == "degenerate":
        a, b, c = t[0]
        p = np.vstack([p, 0.5 * (p[a] + p[b])])
        m = len(p) - 1
        return p, np.vstack([t[1:], [[a, m, c], [m, b, c], [a, b, m]]])
    return 1000.0 * p, t  # millimetres


@pytest.mark.parametrize(
    ("kind", "why"),
    [
        ("open", "the surface is open"),
        ("non-manifold", "the surface is not manifold"),
        ("wound", "the surface is inconsistently oriented"),
        ("self-intersecting", "the surface intersects itself"),
        ("degenerate", "degenerate triangle(s)"),
        ("millimetres", "in millimetres? the scene is in metres; scale it by 0.001"),
    ],
)
def test_a_bad_object_mesh_exits_2_with_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture, kind: str, why: str
) -> None:
    stl = tmp_path / "thing.ply"
    points, triangles = _bad(kind)
    meshio.write_points_cells(stl, points, [("triangle", triangles.astype(np.int32))])
    path = tmp_path / "scene.toml"
    path.write_text(
        f'[[object]]\nmesh = "{stl.as_posix()}"\n\n[frames]\ntimes = [0.0]\n\n'
        f'[output]\ndirectory = "{(tmp_path / "r").as_posix()}"\npictures = false\n'
    )
    assert main([str(path), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert f"object[0].mesh = '{stl}'" in err and why in err
    assert "\n" not in err and "Traceback" not in err
    assert not (tmp_path / "r").exists()


BONE = """\
[[object]]
name = "peg"
mesh = "{block}"
center = [-0.007, 0.06, 0.0]

[hand]
resolution = "coarse"

[[hand.keyframe]]
time = 0.0
angles = {{}}

[frames]
count = 1

[output]
directory = "{out}"
pictures = false
"""


def test_an_object_inside_a_bone_is_bad_input(tmp_path: Path, capsys: pytest.CaptureFixture):
    out = tmp_path / "results"
    scene = tmp_path / "bone.toml"
    scene.write_text(BONE.format(block=block(tmp_path, 0.006, 2).as_posix(), out=out.as_posix()))
    assert main([str(scene), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "object 'peg' starts inside bone middle_metacarpal" in err
    assert "\n" not in err and "Traceback" not in err
    assert not out.exists()


RESTING = """\
[scene]
gravity = [{gx}, 0.0, {gz}]

[[object]]
name = "block"
mesh = "{block}"
rotation = [0.0, 2.0, 0.0]
material = {{ E = 1.0e6, nu = 0.3, density = 1000.0 }}
friction = 0.5

[[plane]]
name = "table"
point = [{px}, 0.0, {pz}]
normal = [{nx}, 0.0, {nz}]

[frames]
times = [0.0]

[output]
directory = "{out}"
pictures = false
"""


@pytest.mark.parametrize("gap", [-2e-5, 0.0, 2e-5])
def test_a_block_resting_on_its_face_microns_from_a_table_is_held(tmp_path: Path, gap: float):
    # a flat face parallel to the table, every node a few microns off it (or in it), the
    # weight along the table's normal: friction holds the block from any such start
    import math

    a = math.radians(2.0)
    n = np.array([math.sin(a), 0.0, math.cos(a)])  # the block's bottom face's inward normal
    half = 0.01
    point = -(half + gap) * n
    g = -9.81 * n
    path = tmp_path / "rest.toml"
    path.write_text(RESTING.format(
        gx=g[0], gz=g[2], block=block(tmp_path).as_posix(), px=point[0], pz=point[2],
        nx=n[0], nz=n[2], out=(tmp_path / "r").as_posix(),
    ))  # fmt: skip
    run = GraspRun(load_scene(path))
    res, _, _, bodies = run.frame(0.0)
    assert res.converged and res.held, res.stop_reason
    weight = bodies[0].loads.reshape(-1, 3).sum(axis=0)
    assert np.allclose(res.obstacle_forces["table"], weight, rtol=1e-9, atol=1e-12)


FOLLOW = """\
[[object]]
name = "peg"
mesh = "{block}"
center = [0.0, 0.1, -0.06]
follow = {{ joint = "index_mcp", start = 0.0, stop = 1.0 }}

[hand]
resolution = "coarse"

[[hand.keyframe]]
time = 0.0
angles = {{ index_mcp = 0.0 }}

[[hand.keyframe]]
time = 1.0
angles = {{ index_mcp = 30.0 }}

[frames]
times = [0.0, 1.0]
"""


def test_an_object_follows_its_joint_as_the_ball_does(tmp_path: Path) -> None:
    from contact.hand.objects import ObjectAssociation

    path = tmp_path / "follow.toml"
    path.write_text(FOLLOW.format(block=block(tmp_path, 0.006, 2).as_posix()))
    run = GraspRun(load_scene(path))
    (peg,) = run.objects
    assert not peg.rolls and peg.follow is not None
    assert peg.faces is peg.mesh.boundary  # every boundary face of an object can touch
    assert np.allclose(run.placement(peg, 0.0), np.eye(4))
    moved = run.placement(peg, 1.0)
    assoc = ObjectAssociation("peg", "index_mcp", 0.0, 1.0)
    assert np.allclose(moved, assoc.transform(run.hand.skeleton, run.keyframes.pose, 1.0))
    assert not np.allclose(moved, np.eye(4))
    body = run.object_body(peg, 1.0)
    assert np.allclose(body.mesh.points, peg.points(moved))
