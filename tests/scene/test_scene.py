"""The strict scene loader (contact.scene): valid scenes, defaults, and bad inputs."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest

from contact import Keyframes, load_skeleton
from contact.errors import ContactError
from contact.hand.shipped import HAND_DIR
from contact.scene import (
    CONTACT_KEYS,
    AutoFlex,
    Material,
    OutputScene,
    PlaneScene,
    Scene,
    SceneError,
    SolverScene,
    load_scene,
)
from contact.solver import ContactSettings

ROOT = Path(__file__).resolve().parents[2]
#: The example scenes (a sweep file names a scene, it is not one: docs/sweep.md).
EXAMPLES = sorted(p for p in (ROOT / "examples").glob("*.toml") if not p.stem.startswith("sweep"))

BASE = """\
[scene]
name = "test"
description = "a hand, a ball, a table"

[ball]
radius = 0.03
kind = "hollow"
thickness = 0.003
pressure = 2.0e4
element = "hex"
mesh_size = 0.006
center = [0.0, 0.09, -0.06]
material = { E = 1.0e6, nu = 0.45, density = 1100.0 }

[hand]
resolution = "coarse"
flesh = { E = 5.0e4, nu = 0.45 }
bone_force_limit = 40.0
bone_force_limits = { index_distal = 20.0 }

[[hand.keyframe]]
time = 0.0
angles = { index_mcp = 0.0 }

[[hand.keyframe]]
time = 1.0
angles = { index_mcp = 45.0, index_pip = 60.0 }
tension = 0.0

[[hand.auto_flexion]]
joint = "index_pip"
point = "index"
times = [1.0]

[[plane]]
name = "table"
point = [0.0, 0.0, -0.1]
normal = [0.0, 0.0, 1.0]

[frames]
times = [0.0, 0.5, 1.0]

[solver]
tolerance = 1.0e-4
max_iterations = 50

[output]
directory = "results"
"""

NO_HAND = """\
[ball]
radius = 0.02
mesh_size = 0.005
center = [0.0, 0.0, 0.02]

[[plane]]
name = "table"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]

[frames]
count = 3
"""

PLATE = """
[[plane]]
name = "plate"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, -1.0]
offsets = [[0.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, -0.2]]
"""


def edit(text: str, old: str, new: str) -> str:
    assert text.count(old) == 1, old
    return text.replace(old, new)


@pytest.fixture
def scene_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    """Write scene text to ``tmp_path/scene.toml`` (working directory ``tmp_path``)."""
    monkeypatch.chdir(tmp_path)

    def write(text: str, name: str = "scene.toml") -> Path:
        path = tmp_path / name
        path.write_text(text)
        return path

    return write


# --------------------------------------------------------------------------- valid scenes


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
def test_examples_load(path: Path) -> None:
    scene = load_scene(path)
    assert scene.path == path.resolve()
    assert scene.frames and list(scene.frames) == sorted(scene.frames)
    echo = json.loads(json.dumps(scene.echo()))
    assert echo["scene"]["name"] == scene.name
    if scene.ball is not None:
        assert echo["ball"]["radius"] == scene.ball.radius
    assert [o["name"] for o in echo["object"]] == [o.name for o in scene.objects]
    assert scene.object_names
    assert echo["frames"]["times"] == list(scene.frames)
    if scene.hand is not None:
        sk = load_skeleton(scene.hand.rig)
        Keyframes(sk, scene.hand.keyframes)  # what the CLI builds


def test_examples_are_the_three_asked_for() -> None:
    assert {p.stem for p in EXAMPLES} >= {"grasp", "finger_press", "hertz_plates"}
    grasp = load_scene(ROOT / "examples" / "grasp.toml")
    assert grasp.ball.kind == "hollow" and grasp.ball.pressure > 0
    assert grasp.hand is not None and grasp.hand.resolution == "coarse"
    plates = load_scene(ROOT / "examples" / "hertz_plates.toml")
    assert plates.hand is None and len(plates.planes) == 2
    # the plate down 1 mm at the last frame, weighted gaps from the first press on
    assert np.allclose(plates.planes[1].offset(plates.frames[-1]), [0.0, 0.0, -0.001])
    assert plates.frames[0] > 0.0 and plates.solver.contact.gaps == "weighted"


def test_full_scene(scene_file) -> None:
    scene = load_scene(scene_file(BASE))
    assert isinstance(scene, Scene)
    assert scene.name == "test" and scene.description == "a hand, a ball, a table"
    b = scene.ball
    assert (b.radius, b.kind, b.thickness, b.element, b.mesh_size) == (
        0.03,
        "hollow",
        0.003,
        "hex",
        0.006,
    )
    assert (b.E, b.nu, b.density) == (1.0e6, 0.45, 1100.0)
    h = scene.hand
    assert h is not None
    assert h.rig == HAND_DIR / "rig.toml" and h.directory == HAND_DIR
    assert h.flesh == Material(5.0e4, 0.45, 1000.0)
    assert [k["time"] for k in h.keyframes] == [0.0, 1.0]
    assert h.keyframes[1]["angles"] == {"index_mcp": 45.0, "index_pip": 60.0}
    assert h.keyframes[1]["tension"] == 0.0 and h.keyframes[0]["bias"] == 0.0
    assert h.auto_flexion == (AutoFlex("index_pip", "index", 1e-4, 0.0, (1.0,)),)
    assert scene.frames == (0.0, 0.5, 1.0)
    assert scene.planes == (PlaneScene("table", (0.0, 0.0, -0.1), (0.0, 0.0, 1.0)),)
    assert scene.gravity is None and scene.follow is None
    assert scene.solver == SolverScene()
    assert scene.output == OutputScene(Path("results"))
    echo = scene.echo()
    json.dumps(echo)
    assert echo["hand"]["rig"] == str(HAND_DIR / "rig.toml")
    assert echo["hand"]["auto_flexion"][0]["times"] == [1.0]


def test_defaults_without_hand(scene_file) -> None:
    scene = load_scene(scene_file(NO_HAND, "plates.toml"))
    assert scene.name == "plates"  # the file's stem
    assert scene.hand is None and scene.follow is None and scene.gravity is None
    assert scene.frames == (0.0, 0.5, 1.0)  # count over [0, 1]
    assert scene.ball.kind == "solid" and scene.ball.element == "tet"
    assert scene.solver == SolverScene()
    out = scene.output
    assert (out.directory, out.pictures, out.gif, out.window_size) == (
        Path("results"),
        True,
        True,
        (1024, 768),
    )
    one = load_scene(scene_file(edit(NO_HAND, "count = 3", "count = 1")))
    assert one.frames == (0.0,)


def test_frame_count_spans_the_keyframes(scene_file) -> None:
    text = edit(BASE, "times = [0.0, 0.5, 1.0]", "count = 5")
    text = edit(text, "time = 0.0\n", "time = 0.2\n").replace("times = [1.0]", "times = [0.6]")
    scene = load_scene(scene_file(text))
    assert scene.frames == (0.2, 0.4, 0.6, 0.8, 1.0)
    one = load_scene(scene_file(edit(text, "count = 5", "count = 1").replace("[0.6]", "[0.2]")))
    assert one.frames == (0.2,)


def test_gravity_follow_and_solver(scene_file) -> None:
    text = edit(BASE, 'description = "a hand, a ball, a table"', "gravity = [0, 0, -9.81]")
    text = edit(
        text, "[hand]\n", '[ball.follow]\njoint = "index_mcp"\nstart = 0.0\nstop = 0.5\n\n[hand]\n'
    )
    text = edit(text, "tolerance = 1.0e-4", "tolerance = 1.0e-5")
    text = edit(
        text,
        "max_iterations = 50",
        'max_iterations = 20\nalgorithm = "seed"\nrelaxation = "aitken"\n'
        'relaxation_factor = 0.3\nlinear_solver = "superlu"\ngap_tolerance = 2e-3\n'
        'force_tolerance = 0.0\ngaps = "weighted"',
    )
    scene = load_scene(scene_file(text))
    assert scene.gravity == (0.0, 0.0, -9.81)
    assert scene.follow is not None and scene.follow.joint == "index_mcp"
    assert (scene.follow.start, scene.follow.stop) == (0.0, 0.5)
    s = scene.solver
    settings = s.settings(scene.hand.limits(["index_distal", "thumb_distal"]))
    assert isinstance(settings, ContactSettings)
    assert (settings.algorithm, settings.max_iterations, settings.relaxation) == (
        "seed",
        20,
        "aitken",
    )
    assert settings.relaxation_factor == 0.3 and settings.gap_tolerance == 2e-3
    assert settings.force_tolerance == 0.0 and s.linear_solver == "superlu"
    assert settings.support_limits == {"index_distal": 20.0, "thumb_distal": 40.0}
    # every contact key is read: none is left at its default
    assert [k for k in CONTACT_KEYS if getattr(settings, k) == getattr(ContactSettings(), k)] == []
    assert scene.echo()["ball"]["follow"] == {"joint": "index_mcp", "start": 0.0, "stop": 0.5}


def test_limits_without_a_global_limit(scene_file) -> None:
    scene = load_scene(scene_file(edit(BASE, "bone_force_limit = 40.0\n", "")))
    assert scene.hand.bone_force_limit is None
    assert scene.hand.limits(["index_distal", "thumb_distal"]) == {"index_distal": 20.0}


def test_plane_offsets_interpolate(scene_file) -> None:
    text = NO_HAND + PLATE.replace("[0.0, 0.0, 0.0]", "[0.0, 0.0, 0.04]").replace("-0.2", "-0.002")
    scene = load_scene(scene_file(text))
    table, plate = scene.planes
    assert np.array_equal(table.offset(0.7), np.zeros(3))
    assert np.allclose(plate.offset(-1.0), 0.0)
    assert np.allclose(plate.offset(0.25), [0.0, 0.0, -0.0005])
    assert np.allclose(plate.offset(5.0), [0.0, 0.0, -0.002])
    assert plate.normal == (0.0, 0.0, -1.0)


def test_normal_is_normalised_and_tilted_facing_planes_are_fine(scene_file) -> None:
    tilted = plate(0.05, "").replace("[0.0, 0.0, -1.0]", "[0.0, 0.3, -2.0]")
    scene = load_scene(scene_file(NO_HAND + tilted))
    n = np.array(scene.planes[1].normal)
    assert math.isclose(np.linalg.norm(n), 1.0) and n[2] < 0
    assert scene.planes[1].offsets == ()


def test_relative_paths(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "ball.vtu").write_text("not read by the loader")
    (tmp_path / "work").mkdir()
    monkeypatch.chdir(tmp_path / "work")
    text = edit(NO_HAND, "mesh_size = 0.005", 'mesh = "ball.vtu"')
    text += '\n[output]\ndirectory = "out/deeper"\n'
    path = tmp_path / "sub" / "scene.toml"
    path.write_text(text)
    scene = load_scene(path)
    assert Path(scene.ball.mesh) == (tmp_path / "sub" / "ball.vtu").resolve()
    assert scene.output.directory == Path("out/deeper")  # relative to the working directory
    # a hand rig relative to the scene file
    rig = tmp_path / "sub" / "rig.toml"
    rig.write_text((HAND_DIR / "rig.toml").read_text())
    scene = load_scene(
        _write(tmp_path / "sub" / "h.toml", BASE.replace("[hand]\n", '[hand]\nrig = "rig.toml"\n'))
    )
    assert scene.hand.rig == rig.resolve()


def test_rig_that_does_not_match_the_meshes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    rig = (HAND_DIR / "rig.toml").read_text()
    (tmp_path / "rig.toml").write_text(rig.replace("[bones.carpus]", "[bones.carpals]"))
    path = _write(tmp_path / "s.toml", BASE.replace("[hand]\n", '[hand]\nrig = "rig.toml"\n'))
    with pytest.raises(SceneError, match=r"hand\.rig = 'rig\.toml': its joints and bones differ"):
        load_scene(path)


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_auto_flexion_node_and_every_frame(scene_file) -> None:
    text = edit(
        BASE, 'point = "index"\ntimes = [1.0]', "point = 1234\npress = 0.001\nepsilon = 1e-5"
    )
    (a,) = load_scene(scene_file(text)).hand.auto_flexion
    assert a == AutoFlex("index_pip", 1234, 1e-5, 0.001, None)
    assert a.first_contact  # the default: the first skin node the joint brings there
    text = edit(BASE, "times = [1.0]", "first_contact = false")
    (b,) = load_scene(scene_file(text)).hand.auto_flexion
    assert not b.first_contact


def test_hand_nodal_pressure_key_and_echo(scene_file) -> None:
    sc = load_scene(scene_file(BASE))
    assert sc.hand.nodal_pressure is None  # absent: decided by the flesh's nu
    assert sc.echo()["hand"]["nodal_pressure"] is None
    assert sc.echo()["ball"]["nodal_pressure"] is None
    text = edit(
        BASE,
        "flesh = { E = 5.0e4, nu = 0.45 }",
        "flesh = { E = 5.0e4, nu = 0.45 }\nnodal_pressure = true",
    )
    sc = load_scene(scene_file(text))
    assert sc.hand.nodal_pressure is True and sc.echo()["hand"]["nodal_pressure"] is True


def test_error_classes() -> None:
    assert issubclass(SceneError, ContactError) and issubclass(SceneError, ValueError)


# --------------------------------------------------------------------------- bad scenes

FOLLOW_HAND = '[ball.follow]\njoint = "{joint}"\nstart = {start}\nstop = {stop}\n\n[hand]\n'

# (id, old text of BASE, new text, substrings the message must hold: the key path first)
BAD = [
    ("not-toml", "radius = 0.03", "radius = = 0.03", ["not valid TOML", "line 6"]),
    ("unknown-key", "radius = 0.03", "radus = 0.03\nradius = 0.03",
     ["ball.radus", "unknown key", "did you mean 'radius'"]),
    ("unknown-section", "[solver]", "[solvr]", ["solvr", "did you mean 'solver'"]),
    ("unknown-material-key", "density = 1100.0", "densty = 1100.0",
     ["ball.material.densty", "did you mean 'density'"]),
    ("radius-string", "radius = 0.03", 'radius = "big"', ["ball.radius = 'big'", "number"]),
    ("bool-not-number", "max_iterations = 50", "max_iterations = true",
     ["solver.max_iterations = True", "integer"]),
    ("float-iterations", "max_iterations = 50", "max_iterations = 5.5",
     ["solver.max_iterations", "integer"]),
    ("bool-tolerance", "tolerance = 1.0e-4", "tolerance = false", ["solver.tolerance", "number"]),
    ("center-length", "center = [0.0, 0.09, -0.06]", "center = [0.0, 0.09]",
     ["ball.center", "3 numbers"]),
    ("missing-radius", "radius = 0.03\n", "", ["ball.radius", "missing"]),
    ("missing-mesh", "mesh_size = 0.006\n", "", ["ball.mesh_size", "missing"]),
    ("E-zero", "E = 1.0e6", "E = 0.0", ["ball.material.E = 0.0", "positive"]),
    ("E-negative-flesh", "flesh = { E = 5.0e4", "flesh = { E = -5.0e4",
     ["hand.flesh.E = -50000.0", "positive"]),
    ("nu-half", "nu = 0.45, density", "nu = 0.5, density",
     ["ball.material.nu = 0.5", "below 0.5"]),
    ("nu-minus-one", "nu = 0.45 }", "nu = -1.0 }", ["hand.flesh.nu = -1.0", "above -1"]),
    ("radius-negative", "radius = 0.03", "radius = -0.03", ["ball.radius = -0.03", "positive"]),
    ("radius-zero", "radius = 0.03", "radius = 0", ["ball.radius = 0", "positive"]),
    ("thickness-zero", "thickness = 0.003", "thickness = 0.0",
     ["ball.thickness = 0.0", "positive"]),
    ("thickness-radius", "thickness = 0.003", "thickness = 0.03",
     ["ball.thickness = 0.03", "below the radius"]),
    ("solid-thickness", 'kind = "hollow"', 'kind = "solid"', ["ball.thickness", "hollow"]),
    ("kind", 'kind = "hollow"', 'kind = "empty"', ["ball.kind = 'empty'", "solid, hollow"]),
    ("mesh-missing", "mesh_size = 0.006", 'mesh = "nowhere.vtu"',
     ["ball.mesh = 'nowhere.vtu'", "no such file"]),
    ("mesh-and-size", "mesh_size = 0.006", 'mesh_size = 0.006\nmesh = "x.vtu"',
     ["ball.mesh", "not both"]),
    ("key-out-of-limits", "index_pip = 60.0", "index_pip = 200",
     ["hand.keyframe[1].angles.index_pip = 200", "outside its limits [0, 110]"]),
    ("key-below-limits", "index_mcp = 0.0 }", "index_mcp = -45.0 }",
     ["hand.keyframe[0].angles.index_mcp = -45.0", "limits [-20, 90]"]),
    ("unknown-joint", "index_mcp = 0.0 }", "index_mpc = 0.0 }",
     ["hand.keyframe[0].angles.index_mpc", "unknown joint angle", "did you mean 'index_mcp'"]),
    ("angle-type", "index_pip = 60.0", 'index_pip = "sixty"',
     ["hand.keyframe[1].angles.index_pip", "number"]),
    ("key-times", "time = 1.0", "time = 0.0",
     ["hand.keyframe[1].time = 0.0", "must increase"]),
    ("tension", "tension = 0.0", "tension = 1.5", ["hand.keyframe[1].tension", "[-1, 1]"]),
    ("keyframe-key", "tension = 0.0", "tenson = 0.0",
     ["hand.keyframe[1].tenson", "did you mean 'tension'"]),
    ("no-keyframes", "[[hand.keyframe]]\ntime = 0.0\nangles = { index_mcp = 0.0 }\n\n"
     "[[hand.keyframe]]\ntime = 1.0\nangles = { index_mcp = 45.0, index_pip = 60.0 }\n"
     "tension = 0.0\n", "", ["hand.keyframe", "missing"]),
    ("frames-outside", "times = [0.0, 0.5, 1.0]", "times = [0.0, 0.5, 1.5]",
     ["frames.times[2] = 1.5", "outside the keyframes' span [0, 1]"]),
    ("frames-before", "times = [0.0, 0.5, 1.0]", "times = [-0.1, 0.5, 1.0]",
     ["frames.times[0] = -0.1", "span"]),
    ("frames-order", "times = [0.0, 0.5, 1.0]", "times = [0.0, 1.0, 0.5]",
     ["frames.times[2] = 0.5", "increase"]),
    ("frames-count-zero", "times = [0.0, 0.5, 1.0]", "count = 0",
     ["frames.count = 0", "at least 1"]),
    ("frames-count-negative", "times = [0.0, 0.5, 1.0]", "count = -3",
     ["frames.count = -3", "at least 1"]),
    ("frames-both", "times = [0.0, 0.5, 1.0]", "times = [0.0]\ncount = 2",
     ["frames", "exactly one"]),
    ("frames-missing", "[frames]\ntimes = [0.0, 0.5, 1.0]\n", "", ["frames", "missing"]),
    ("tolerance-zero", "tolerance = 1.0e-4", "tolerance = 0.0",
     ["solver.tolerance = 0.0", "positive"]),
    ("tolerance-negative", "tolerance = 1.0e-4", "tolerance = -1e-4",
     ["solver.tolerance = -0.0001", "positive"]),
    ("gap-tolerance-zero", "tolerance = 1.0e-4", "gap_tolerance = 0",
     ["solver.gap_tolerance = 0", "positive"]),
    ("force-tolerance", "tolerance = 1.0e-4", "force_tolerance = -1.0",
     ["solver.force_tolerance = -1.0", ">= 0"]),
    ("iterations-zero", "max_iterations = 50", "max_iterations = 0",
     ["solver.max_iterations = 0", ">= 1"]),
    ("iterations-negative", "max_iterations = 50", "max_iterations = -5",
     ["solver.max_iterations = -5", ">= 1"]),
    ("algorithm", "max_iterations = 50", 'algorithm = "newton"',
     ["solver.algorithm = 'newton'", "contact-space, seed"]),
    ("relaxation", "max_iterations = 50", 'relaxation = "strong"',
     ["solver.relaxation = 'strong'", "none, fixed, aitken"]),
    ("relaxation-factor", "max_iterations = 50", "relaxation_factor = 0.0",
     ["solver.relaxation_factor = 0.0", "(0, 1]"]),
    ("gaps", "max_iterations = 50", 'gaps = "mortar"',
     ["solver.gaps = 'mortar'", "nodal, weighted"]),
    ("linear-solver", "max_iterations = 50", 'linear_solver = "mumps"',
     ["solver.linear_solver = 'mumps'", "auto"]),
    ("unknown-bone", "{ index_distal = 20.0 }", "{ index_distl = 20.0 }",
     ["hand.bone_force_limits.index_distl", "unknown bone", "did you mean 'index_distal'"]),
    ("bone-limit-negative", "{ index_distal = 20.0 }", "{ index_distal = -1.0 }",
     ["hand.bone_force_limits.index_distal = -1.0", "positive"]),
    ("global-limit-zero", "bone_force_limit = 40.0", "bone_force_limit = 0.0",
     ["hand.bone_force_limit = 0.0", "positive"]),
    ("resolution", 'resolution = "coarse"', 'resolution = "medium"',
     ["hand.resolution = 'medium'", "coarse, fine"]),
    ("rig-missing", 'resolution = "coarse"', 'rig = "no_rig.toml"',
     ["hand.rig = 'no_rig.toml'", "no such file"]),
    ("directory-missing", 'resolution = "coarse"', 'directory = "no_hand"',
     ["hand.directory = 'no_hand'", "no such folder"]),
    ("normal-zero", "normal = [0.0, 0.0, 1.0]", "normal = [0.0, 0.0, 0.0]",
     ["plane[0].normal", "non-zero"]),
    ("plane-name-reserved", 'name = "table"', 'name = "ball"',
     ["plane[0].name = 'ball'", "reserved"]),
    ("plane-key", "normal = [0.0, 0.0, 1.0]", "normal = [0.0, 0.0, 1.0]\nnormals = 1",
     ["plane[0].normals", "did you mean 'normal'"]),
    ("plane-not-array", "[[plane]]", "[plane]", ["plane", "array of tables"]),
    ("ball-behind-plane", "point = [0.0, 0.0, -0.1]", "point = [0.0, 0.0, 0.0]",
     ["plane[0].point", "behind the plane 'table'"]),
    ("auto-flex-joint", 'joint = "index_pip"', 'joint = "index_pap"',
     ["hand.auto_flexion[0].joint = 'index_pap'", "did you mean 'index_pip'"]),
    ("auto-flex-point", 'point = "index"', 'point = "pinky"',
     ["hand.auto_flexion[0].point = 'pinky'", "thumb, index"]),
    ("auto-flex-node", 'point = "index"', "point = -1",
     ["hand.auto_flexion[0].point = -1", "at least 0"]),
    ("auto-flex-time", "times = [1.0]", "times = [0.75]",
     ["hand.auto_flexion[0].times[0] = 0.75", "frame times"]),
    ("auto-flex-press", "times = [1.0]", "press = -0.001",
     ["hand.auto_flexion[0].press = -0.001", "negative"]),
    ("auto-flex-first", "times = [1.0]", 'first_contact = "yes"',
     ["hand.auto_flexion[0].first_contact = 'yes'", "true or false"]),
    ("hand-nodal", "flesh = { E = 5.0e4, nu = 0.45 }",
     'flesh = { E = 5.0e4, nu = 0.45 }\nnodal_pressure = "yes"',
     ["hand.nodal_pressure = 'yes'", "true or false"]),
    ("auto-flex-epsilon", "times = [1.0]", "epsilon = 0.0",
     ["hand.auto_flexion[0].epsilon = 0.0", "positive"]),
    ("gravity", 'description = "a hand, a ball, a table"', "gravity = [0.0, -9.81]",
     ["scene.gravity", "3 numbers"]),
    ("scene-name", 'name = "test"', "name = 3", ["scene.name = 3", "string"]),
    ("follow-joint", "[hand]\n", FOLLOW_HAND.format(joint="elbow", start=0.0, stop=1.0),
     ["ball.follow.joint = 'elbow'", "unknown joint"]),
    ("follow-times", "[hand]\n", FOLLOW_HAND.format(joint="wrist", start=1.0, stop=0.0),
     ["ball.follow.stop = 0.0", "start"]),
    ("output-pictures", 'directory = "results"', "pictures = 1",
     ["output.pictures = 1", "true or false"]),
    ("output-window", 'directory = "results"', "window_size = [800]",
     ["output.window_size", "width, height"]),
    ("output-key", 'directory = "results"', 'dir = "results"',
     ["output.dir", "did you mean 'directory'"]),
]  # fmt: skip


@pytest.mark.parametrize(("old", "new", "expected"), [c[1:] for c in BAD], ids=[c[0] for c in BAD])
def test_bad_scene(scene_file, old: str, new: str, expected: list[str]) -> None:
    path = scene_file(edit(BASE, old, new))
    with pytest.raises(SceneError) as info:
        load_scene(path)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(f"{path}: ")
    for part in expected:
        assert part in message, message


# Bad scenes without a hand (id, text, substrings).
BALL = "[ball]\nradius = 0.02\nmesh_size = 0.005\ncenter = [0.0, 0.0, 0.02]\n"
MOVING = "offsets = [[0.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, -0.2]]"
FOLLOW = '[ball.follow]\njoint = "wrist"\nstart = 0.0\nstop = 1.0\n\n[[plane]]'


def plate(z: float, offsets: str = MOVING, name: str = "plate") -> str:
    """A plate at height ``z`` facing down, with ``offsets``."""
    text = PLATE.replace("[0.0, 0.0, 0.0]", f"[0.0, 0.0, {z}]", 1).replace(MOVING, offsets)
    return text.replace('"plate"', f'"{name}"')


BAD_NO_HAND = [
    ("no-ball", NO_HAND.replace(BALL, ""), ["ball", "missing", "[ball]"]),
    ("plate-through-table", NO_HAND + plate(0.1),
     ["plane[1].offsets", "frame 2 (t = 1)", "'plate' and 'table' have passed through"]),
    ("plate-below-ball-centre", NO_HAND + plate(0.1, MOVING.replace("-0.2", "-0.09")),
     ["plane[1].offsets", "frame 2 (t = 1)", "behind the plane 'plate'", "moved past it"]),
    ("ball-behind-fixed-plate", NO_HAND + plate(0.01, ""),
     ["plane[1].point", "behind the plane 'plate'", "normal must point toward the ball"]),
    ("duplicate-plane", NO_HAND + plate(1.0, name="table"),
     ["plane[1].name = 'table'", "another plane"]),
    ("offset-times", NO_HAND + plate(1.0, MOVING.replace("[1.0, 0.0, 0.0, -0.2]", "[0, 0, 0, 1]")),
     ["plane[1].offsets[1]", "increase"]),
    ("offset-length", NO_HAND + plate(1.0, MOVING.replace("[1.0, 0.0, 0.0, -0.2]", "[1, -0.2]")),
     ["plane[1].offsets[1]", "4 numbers"]),
    ("follow-without-hand", NO_HAND.replace("[[plane]]", FOLLOW, 1),
     ["ball.follow.joint = 'wrist'", "[hand]"]),
    ("output-is-a-file", NO_HAND + '\n[output]\ndirectory = "scene.toml"\n',
     ["output.directory = 'scene.toml'", "not a folder"]),
    ("output-under-a-file", NO_HAND + '\n[output]\ndirectory = "scene.toml/out"\n',
     ["output.directory = 'scene.toml/out'", "not a folder"]),
]  # fmt: skip


@pytest.mark.parametrize(
    ("text", "expected"), [c[1:] for c in BAD_NO_HAND], ids=[c[0] for c in BAD_NO_HAND]
)
def test_bad_scene_without_hand(scene_file, text: str, expected: list[str]) -> None:
    path = scene_file(text)
    with pytest.raises(SceneError) as info:
        load_scene(path)
    message = str(info.value)
    assert "\n" not in message and message.startswith(f"{path}: ")
    for part in expected:
        assert part in message, message


def test_missing_scene_file(tmp_path: Path) -> None:
    path = tmp_path / "nowhere.toml"
    with pytest.raises(SceneError, match=r"nowhere\.toml: no such scene file"):
        load_scene(path)


def test_not_toml_names_line_and_column(scene_file) -> None:
    path = scene_file("[ball]\nradius = 0.03\ncenter = = 1\n")
    with pytest.raises(SceneError, match=r"scene\.toml: not valid TOML: .*line 3, column"):
        load_scene(path)


def test_mesh_not_a_file(scene_file, tmp_path: Path) -> None:
    (tmp_path / "adir.vtu").mkdir()
    path = scene_file(edit(NO_HAND, "mesh_size = 0.005", 'mesh = "adir.vtu"'))
    with pytest.raises(SceneError, match=r"ball\.mesh = 'adir\.vtu': not a file"):
        load_scene(path)


def test_mesh_unreadable(scene_file, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    target = tmp_path / "locked.vtu"
    target.write_text("x")
    path = scene_file(edit(NO_HAND, "mesh_size = 0.005", 'mesh = "locked.vtu"'))
    real_open = open

    def guarded(file, *args, **kwargs):
        if Path(file) == target.resolve():
            raise PermissionError(13, "Permission denied", str(file))
        return real_open(file, *args, **kwargs)

    monkeypatch.setattr("builtins.open", guarded)
    with pytest.raises(SceneError, match=r"ball\.mesh = 'locked\.vtu': cannot be read"):
        load_scene(path)


def test_output_parent_not_writable(
    scene_file, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "locked").mkdir()
    path = scene_file(NO_HAND + '\n[output]\ndirectory = "locked/results"\n')
    real_access = os.access

    def access(p, mode, *args, **kwargs):  # as a user without write permission sees it
        if Path(p) == tmp_path / "locked" and mode & os.W_OK:
            return False
        return real_access(p, mode, *args, **kwargs)

    monkeypatch.setattr(os, "access", access)
    with pytest.raises(
        SceneError, match=r"output\.directory = 'locked/results': cannot create it: .* not writable"
    ):
        load_scene(path)


def test_existing_output_directory_is_fine(scene_file, tmp_path: Path) -> None:
    (tmp_path / "results").mkdir()
    scene = load_scene(scene_file(NO_HAND + '\n[output]\ndirectory = "results"\ngif = false\n'))
    assert scene.output.directory == Path("results") and scene.output.gif is False


def test_bad_cases_cover_the_issue() -> None:
    assert len(BAD) + len(BAD_NO_HAND) >= 30


def test_docs_full_example_loads(scene_file) -> None:
    doc = (ROOT / "docs" / "scene.md").read_text()
    text = doc.split("```toml\n", 1)[1].split("```", 1)[0]
    text = text.replace('"../meshes/hand', f'"{HAND_DIR}')
    scene = load_scene(scene_file(text))
    assert scene.gravity == (0.0, 0.0, -9.81)
    assert scene.follow is not None and scene.hand.auto_flexion[0].press == 0.001
    assert scene.hand.limits(["index_distal", "ring_distal"]) == {
        "index_distal": 20.0,
        "ring_distal": 40.0,
    }
    echo = scene.echo()
    for section in ("scene", "ball", "hand", "plane", "frames", "solver", "output"):
        assert echo[section], section
