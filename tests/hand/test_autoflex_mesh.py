"""Automatic flexion measured against the ball's meshed contact surface, not its sphere."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import fem
from contact.geometry.surfacequery import TriangleSurface, surface_of_mesh
from contact.hand.autoflex import mesh_distance, sphere_distance
from contact.objects.ball import BallSpec, make_ball
from contact.run import GraspRun
from contact.scene import load_scene

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "finger_press.toml"
PRESS = 0.0005  # m, the example's first press


def _surface(radius: float, size: float, element: str) -> TriangleSurface:
    """A fine ball's outer facets: a hex ball's, or the icosphere a tet ball is meshed in."""
    if element == "tet":
        return TriangleSurface(*fem.sphere_surface(radius, (0.0, 0.0, 0.0), 4))
    ball = make_ball(BallSpec(radius=radius, mesh_size=size, element=element))
    return TriangleSurface(ball.mesh.points, surface_of_mesh(ball.mesh, ball.outer)[1])


@pytest.mark.parametrize("element", ["hex", "tet"])
def test_mesh_distance_is_the_sphere_within_the_chord_error(element):
    radius, size = 0.02, 0.002
    surf = _surface(radius, size, element)
    rng = np.random.default_rng(0)
    d = rng.normal(size=(200, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    x = d * rng.uniform(0.5 * radius, 1.5 * radius, size=(200, 1))
    mesh, sphere = mesh_distance(surf)(x), sphere_distance(np.zeros(3), radius)(x)
    edge = float(np.linalg.norm(np.diff(surf.points[surf.triangles], axis=1), axis=2).max())
    chord = edge**2 / (8.0 * radius)  # sagitta of the longest edge: the facets' sag
    assert np.all(np.sign(mesh) == np.sign(sphere))
    assert np.abs(mesh - sphere).max() <= 2.0 * chord
    # the facets lie inside the sphere: never further out than it
    assert np.all(mesh >= sphere - 1e-12)


@pytest.fixture(scope="module")
def coarse_press(tmp_path_factory):
    """The finger_press example on a 6 mm ball, its first frame only (a 0.5 mm press)."""
    text = EXAMPLE.read_text()
    text = text.replace("mesh_size = 0.004 ", "mesh_size = 0.006 ")
    cut = text.index("[[hand.auto_flexion]]       # then 1 mm")
    text = text[:cut] + text[text.index("[[plane]]") :]
    text = text.replace("times = [0.0, 0.5, 1.0]", "times = [0.5]")
    path = tmp_path_factory.mktemp("coarse") / "press.toml"
    path.write_text(text)
    return GraspRun(load_scene(path))


def test_a_coarse_ball_is_pressed_as_deep_as_asked(coarse_press):
    run = coarse_press
    angles = run.angles(0.5)
    flex = run.auto_flexed["index_mcp"]
    assert flex["converged"]
    x = run.hand_body(angles).mesh.points[[flex["node"]]]
    mesh = float(mesh_distance(run.object_surfaces(0.5))(x)[0])
    sphere = float(sphere_distance(run.scene.ball.center, run.scene.ball.radius)(x)[0])
    # the press into the meshed facets the contact search meets; deeper into the sphere
    assert mesh == pytest.approx(-PRESS, abs=2e-5)
    assert sphere < mesh - 1e-5


def test_a_coarse_ball_pressed_half_a_millimetre_touches_the_finger(coarse_press):
    run = coarse_press
    result, _, _, _ = run.frame(0.5)
    assert result.converged, result.stop_reason
    pairs = np.asarray(result.contacts["pair"]).astype(str)
    assert np.count_nonzero(pairs == "hand/ball") + np.count_nonzero(pairs == "ball/hand") > 0
    index = run._parts() == run.hand.part_names.index("index")
    force = result.contact_fields["hand"]["normal_force"]
    assert float(force[index].sum()) > 0.0
