"""The ball: radius, volume, cavity, pressure load, validation, mesh files, Lame."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import fem
from contact.errors import ContactError
from contact.objects.ball import Ball, BallError, BallSpec, make_ball
from contact.solver.body import ElasticBody

R, T, P = 0.035, 0.012, 2.0e4
CENTER = (0.01, 0.02, 0.03)


def spec(kind: str = "solid", element: str = "hex", **kw) -> BallSpec:
    extra = {"thickness": T, "pressure": P} if kind == "hollow" else {}
    args = {"kind": kind, "element": element, "mesh_size": 0.006, "center": CENTER}
    return BallSpec(R, **{**args, **extra, **kw})


def longest_edge(ball: Ball) -> float:
    """Longest edge of the boundary faces: the surface discretisation length."""
    h = 0.0
    for f in ball.mesh.boundary.faces.values():
        x = ball.mesh.points[f]
        h = max(h, float(np.linalg.norm(x - np.roll(x, 1, axis=1), axis=2).max()))
    return h


def radii(ball: Ball, nodes) -> np.ndarray:
    return np.linalg.norm(ball.mesh.points[nodes] - np.asarray(CENTER), axis=1)


@pytest.fixture(
    scope="module",
    params=[("solid", "hex"), ("solid", "tet"), ("hollow", "hex"), ("hollow", "tet")],
    ids=lambda p: "-".join(p),
)
def ball(request: pytest.FixtureRequest) -> Ball:
    return make_ball(spec(*request.param))


def test_outer_surface_on_the_requested_sphere(ball):
    h = longest_edge(ball)
    tol = 1e-9 * R if ball.spec.element == "hex" else h**2 / (2 * R)  # facet sagitta
    assert np.abs(radii(ball, ball.outer_nodes) - R).max() <= tol
    b = ball.mesh.boundary
    assert ball.inner.n_faces + ball.outer.n_faces == b.n_faces
    assert len(ball.loads) == ball.mesh.n_dofs


def test_volume_within_the_discretisation_error(ball):
    a = ball.spec.inner_radius
    exact = 4 / 3 * math.pi * (R**3 - a**3)
    # faceting error of a sphere of radius s with edges h: about h^2 s / 4 times 4 pi / 3
    bound = 0.6 * longest_edge(ball) ** 2 * 4 / 3 * math.pi * (R + a)
    assert abs(ball.mesh.volume - exact) <= bound
    assert abs(ball.mesh.volume - exact) <= 0.05 * exact


def test_cavity_and_pressure_load(ball):
    if ball.spec.kind == "solid":
        assert ball.inner.n_faces == 0
        assert not ball.loads.any()
        return
    a = R - T
    h = longest_edge(ball)
    tol = 1e-9 * R if ball.spec.element == "hex" else h**2 / (2 * a)
    assert np.abs(radii(ball, ball.inner.nodes) - a).max() <= tol
    assert not np.isin(ball.inner.nodes, ball.outer_nodes).any()
    fem.check_balance(ball.loads, ball.mesh.points)
    f = ball.loads.reshape(-1, 3)
    x = ball.mesh.points - np.asarray(CENTER)
    assert (np.einsum("ij,ij->i", f, x)[ball.inner.nodes] > 0).all()  # pushes outward
    upper = x[:, 2] > 0
    assert f[upper, 2].sum() == pytest.approx(P * math.pi * a**2, rel=0.03)


@pytest.mark.filterwarnings("ignore:ball.pressure")  # a 2 mm wall at 2e4 Pa: 10 % strain
def test_hollow_hex_has_two_elements_through_a_thin_wall():
    b = make_ball(spec("hollow", thickness=0.002, mesh_size=0.01))
    levels = np.unique(np.round(radii(b, np.arange(b.mesh.n_points)) / R, 9))
    assert len(levels) == 3  # inner, middle, outer sphere


@pytest.mark.parametrize(
    ("kw", "message"),
    [
        ({"radius": -1.0}, "ball.radius = -1.0: must be positive"),
        ({"radius": "big"}, "ball.radius = 'big': must be a number"),
        ({"kind": "foam"}, "ball.kind = 'foam'"),
        ({"element": "quad"}, "ball.element = 'quad'"),
        ({"kind": "hollow", "thickness": 0.05}, "ball.thickness = 0.05: must be below the radius"),
        ({"kind": "hollow"}, "ball.thickness: a hollow ball needs"),
        ({"thickness": 0.003}, "ball.thickness = 0.003: only a hollow ball"),
        ({"pressure": 1.0e4}, "ball.pressure = 10000.0: only a hollow ball"),
        ({"kind": "hollow", "thickness": 0.01, "pressure": math.nan}, "ball.pressure = nan"),
        ({"mesh_size": 0.1}, "ball.mesh_size = 0.1: must be positive and at most"),
        ({"mesh_size": None}, "give exactly one"),
        ({"mesh": "b.vtu"}, "give exactly one"),
        ({"center": (0.0, 0.0)}, "ball.center = (0.0, 0.0): must be 3 numbers"),
        ({"nu": 0.5}, "ball.material.nu = 0.5: must be above -1 and below 0.5"),
        ({"E": 0.0}, "ball.material.E = 0.0: must be positive"),
    ],
)
def test_validation_names_the_field(kw, message):
    args = {"radius": R, "mesh_size": 0.006, **kw}
    with pytest.raises(BallError) as info:
        BallSpec(**args)
    assert message in str(info.value)
    assert isinstance(info.value, ContactError) and isinstance(info.value, ValueError)


def test_exact_thickness_message():
    with pytest.raises(
        BallError, match=r"^ball\.thickness = 0\.05: must be below the radius 0\.035$"
    ):
        BallSpec(0.035, "hollow", thickness=0.05, mesh_size=0.004)


def test_mesh_file_round_trip(tmp_path):
    made = make_ball(spec("hollow"))
    path = tmp_path / "ball.vtu"
    fem.write_mesh(path, made.mesh)
    read = make_ball(spec("hollow", mesh_size=None, mesh=path))
    assert read.mesh.n_points == made.mesh.n_points
    assert read.inner.n_faces == made.inner.n_faces
    np.testing.assert_array_equal(read.outer_nodes, made.outer_nodes)
    np.testing.assert_allclose(read.loads, made.loads, atol=1e-12 * np.abs(made.loads).max())


def test_surface_file_is_filled_with_tetrahedra(tmp_path):
    import pyvista as pv

    surface = pv.Icosphere(radius=R, center=CENTER, nsub=2)  # 320 triangles
    path = tmp_path / "ball.stl"
    surface.save(path)
    ball = make_ball(spec("solid", mesh_size=None, mesh=path))
    assert set(ball.mesh.cells) == {"tetra"}
    r = radii(ball, ball.outer_nodes)
    assert np.abs(r - R).max() < 0.02 * R
    volume = sum(float(v.sum()) for v in ball.mesh.volumes.values())
    assert volume == pytest.approx(surface.volume, rel=0.01)  # the faceted sphere's own
    x = surface.points[surface.regular_faces]
    h = float(np.linalg.norm(x - np.roll(x, 1, axis=1), axis=2).mean())
    assert 0.5 * h < longest_edge(ball) < 2.0 * h  # at the surface's size
    not_closed = tmp_path / "open.stl"
    surface.clip("z", origin=CENTER).save(not_closed)
    with pytest.raises(BallError, match=r"open\.stl' is a surface that cannot be filled"):
        make_ball(spec("solid", mesh_size=None, mesh=not_closed))


def test_mesh_file_not_this_ball_is_refused(tmp_path):
    path = tmp_path / "solid.vtu"
    fem.write_mesh(path, make_ball(spec("solid")).mesh)
    with pytest.raises(BallError, match=r"solid\.vtu.*radius 0\.03 .*range from 0\.035 to 0\.035"):
        make_ball(BallSpec(0.03, mesh=path, center=CENTER))
    with pytest.raises(BallError, match=r"solid\.vtu.*no inner surface"):
        make_ball(spec("hollow", mesh_size=None, mesh=path))
    hollow = tmp_path / "hollow.vtu"
    fem.write_mesh(hollow, make_ball(spec("hollow")).mesh)
    with pytest.raises(BallError, match=r"hollow\.vtu': not a solid ball.*from 0\.023 to"):
        make_ball(spec("solid", mesh_size=None, mesh=hollow))


def test_a_pressure_beyond_small_strains_warns():
    E, nu, a, b = 1.0e6, 0.3, R - T, R
    s = spec("hollow", E=E, nu=nu, mesh_size=0.0035)
    exact = P * a**3 / (b**3 - a**3) * ((1 - 2 * nu) / E + (1 + nu) * b**3 / (2 * E * a**3))
    assert s.pressure_strain == pytest.approx(exact, rel=1e-12)
    assert spec("solid", mesh_size=0.0035).pressure_strain == 0.0
    soft = spec("hollow", E=P / 0.5, nu=nu, mesh_size=0.0035)  # p / E = 0.5
    assert soft.pressure_strain > 0.05
    with pytest.warns(UserWarning, match=r"strains the wall by .* beyond the small strains"):
        make_ball(soft)


def test_tetrahedra_near_incompressible_take_nodal_pressures(monkeypatch):
    import contact.objects.ball as ball_module

    # the mesh itself does not matter here: a small hex_to_tet ball stands for pytetwild's
    monkeypatch.setattr(
        ball_module, "_generate", lambda s: fem.hex_to_tet(fem.ball_mesh(R, R, divisions=2))
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert make_ball(spec("solid", element="tet", nu=0.49, mesh_size=0.01)).nodal_pressure
        assert not make_ball(spec("solid", element="tet", nu=0.45, mesh_size=0.01)).nodal_pressure
        forced = spec("solid", element="tet", nu=0.3, mesh_size=0.01, nodal_pressure=True)
        assert make_ball(forced).nodal_pressure
    plain = spec("solid", element="tet", nu=0.49, mesh_size=0.01, nodal_pressure=False)
    with pytest.warns(UserWarning, match=r"nu = 0.49 on linear tetrahedra with ball.nodal"):
        assert not make_ball(plain).nodal_pressure
    monkeypatch.undo()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        brick = make_ball(spec("solid", element="hex", nu=0.49, mesh_size=0.01))
        assert not brick.nodal_pressure  # B-bar bricks
    with pytest.raises(BallError, match=r"ball.nodal_pressure = 'yes'"):
        spec("solid", nodal_pressure="yes")


def test_hollow_hex_expands_as_lames_thick_sphere():
    E, nu, a, b = 1.0e6, 0.3, R - T, R
    ball = make_ball(spec("hollow", E=E, nu=nu, mesh_size=0.0035))  # 1.5 % off
    body = ElasticBody("ball", ball.mesh, ball.material, loads=ball.loads)
    u = body.solver.solve(ball.loads).u.reshape(-1, 3)
    x = ball.mesh.points - np.asarray(CENTER)
    r = np.linalg.norm(x, axis=1)
    ur = np.einsum("ij,ij->i", u, x) / r
    exact = P * a**3 / (b**3 - a**3) * ((1 - 2 * nu) * r / E + (1 + nu) * b**3 / (2 * E * r**2))
    assert np.abs(ur - exact).max() <= 0.03 * exact.max()


def test_hollow_tet_surface_has_an_inward_cavity(monkeypatch):
    """What goes to pytetwild: both spheres closed, the inner one flipped (a hole)."""
    seen = {}

    def fake(surface, edge_length):
        seen["surface"], seen["h"] = surface, edge_length
        raise RuntimeError("stop before meshing")

    monkeypatch.setattr(fem, "tetrahedralize", fake)
    with pytest.warns(UserWarning, match=r"ball\.mesh_size = 0\.006 exceeds half the wall"):
        with pytest.raises(RuntimeError, match="stop"):
            make_ball(spec("hollow", "tet", thickness=0.01))
    pts, tri = seen["surface"]
    fem.check_surface(pts, tri)
    x = pts[tri] - np.asarray(CENTER)
    vol = np.einsum("ij,ij->i", x[:, 0], np.cross(x[:, 1], x[:, 2])).sum() / 6
    exact = 4 / 3 * math.pi * (R**3 - (R - 0.01) ** 3)
    assert vol == pytest.approx(exact, rel=0.02) and seen["h"] == 0.006
