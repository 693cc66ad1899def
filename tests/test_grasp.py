"""The command line ``python -m contact.grasp``: exit codes, results, bad input."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from contact.grasp import main
from tests.helpers import plates_scene

ROOT = Path(__file__).resolve().parents[1]



def write(tmp_path, iterations=30, name="scene.toml"):
    out = tmp_path / "results"
    path = tmp_path / name
    return plates_scene(path, out, mesh_size=0.003, iterations=iterations), out


def test_plates_scene_runs_and_writes_every_result(tmp_path):
    scene, out = write(tmp_path)
    assert main([str(scene), "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["all_converged"] and summary["all_realistic"]
    frames = summary["frames"]
    assert [f["time"] for f in frames] == [0.5, 1.0]
    f1, f2 = (f["obstacle_forces"]["plate"]["magnitude"] for f in frames)
    # Hertz: the force grows like the approach to the power 3/2 (2^1.5 = 2.83)
    assert 2.3 < f2 / f1 < 3.4
    assert (out / "ball.pvd").is_file()
    assert (out / "ball_0000.vtu").is_file() and (out / "ball_0001.vtu").is_file()
    assert (out / "convergence.png").stat().st_size > 1000
    assert summary["scene"]["solver"]["algorithm"] == "contact-space"


def test_frames_option_and_out_option(tmp_path):
    scene, _ = write(tmp_path)
    other = tmp_path / "other"
    assert main([str(scene), "--quiet", "--frames", "1", "--out", str(other)]) == 0
    summary = json.loads((other / "summary.json").read_text())
    assert [f["time"] for f in summary["frames"]] == [1.0]


def test_a_warning_is_one_log_line(tmp_path, capsys, caplog):
    scene, out = write(tmp_path)
    text = scene.read_text().replace(
        'kind = "solid"', 'kind = "hollow"\nthickness = 0.004\npressure = 2.0e5'
    )
    scene.write_text(text)
    assert main([str(scene), "--frames", "0"]) == 0
    # through the log (one "WARNING: ..." line on stderr), not Python's warning display
    (rec,) = [r for r in caplog.records if "ball.pressure" in r.getMessage()]
    assert rec.levelname == "WARNING" and rec.name == "contact.grasp"
    assert rec.getMessage().startswith("ball.pressure = 200000 Pa strains the wall by ")
    assert "UserWarning" not in capsys.readouterr().err
    assert (out / "summary.json").is_file()


def test_nearly_incompressible_flesh_takes_nodal_pressures_or_warns_of_locking(tmp_path):
    """Flesh above nu 0.45 takes averaged nodal pressures (as a tet ball does); kept plain
    by ``hand.nodal_pressure = false``, it warns that its tetrahedra lock."""
    import warnings

    from contact.run import GraspRun
    from contact.scene.read import load_scene

    text = HAND.format(out=(tmp_path / "out").as_posix()).replace(
        'resolution = "coarse"', 'resolution = "coarse"\nflesh = { E = 5.0e4, nu = 0.49 }'
    )
    text = text.replace("center = [-0.007, 0.06, 0.0]", "center = [0.0, 0.06, -0.1]")
    (tmp_path / "s.toml").write_text(text)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        run = GraspRun(load_scene(tmp_path / "s.toml"))
    hand = run.hand_body(run.angles(0.0))
    assert run.nodal_pressure and hand.nodal_pressure
    nodal = hand.solver.factored_matrix.nnz
    plain_text = text.replace(
        'resolution = "coarse"', 'resolution = "coarse"\nnodal_pressure = false'
    )
    (tmp_path / "p.toml").write_text(plain_text)
    with pytest.warns(UserWarning, match=r"hand.flesh.nu = 0.49 on linear tet"):
        plain = GraspRun(load_scene(tmp_path / "p.toml"))
    body = plain.hand_body(plain.angles(0.0))
    assert not body.nodal_pressure
    assert nodal > 2 * body.solver.factored_matrix.nnz  # the volumetric coupling's fill


def test_not_converged_exits_1_and_still_writes(tmp_path, monkeypatch):
    # without the plate's near nodes in the first set its patch takes two updates
    import contact.solver.contactset

    monkeypatch.setattr(contact.solver.contactset, "NEAR", 0.0)
    scene, out = write(tmp_path, iterations=1)
    assert main([str(scene), "--quiet"]) == 1
    summary = json.loads((out / "summary.json").read_text())
    assert not summary["all_converged"]
    assert summary["frames"][-1]["verdict"]["realistic"] is False


@pytest.mark.parametrize(
    ("edit", "words"),
    [
        (lambda s: s.replace("radius = 0.02", "radius = -0.02"), "ball.radius"),
        (lambda s: s.replace("nu = 0.3", "nu = 0.5"), "nu"),
        (lambda s: s.replace("[frames]", "[frames]\nbogus = 1"), "frames.bogus"),
        (lambda s: s.replace("max_iterations = 30", "max_iterations = 0"), "max_iterations"),
        (lambda s: s + "\n[oops", "not valid TOML"),
    ],
)
def test_bad_input_exits_2_with_one_line_and_writes_nothing(tmp_path, capsys, edit, words):
    scene, out = write(tmp_path)
    scene.write_text(edit(scene.read_text()))
    assert main([str(scene), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and "\n" not in err and "Traceback" not in err
    assert words in err
    assert not out.exists()


def test_missing_scene_and_bad_frame_index(tmp_path, capsys):
    assert main([str(tmp_path / "none.toml"), "--quiet"]) == 2
    assert "none.toml" in capsys.readouterr().err
    scene, out = write(tmp_path)
    assert main([str(scene), "--quiet", "--frames", "7"]) == 2
    assert "--frames 7" in capsys.readouterr().err
    assert not out.exists()


def test_an_old_results_folder_is_kept_when_the_new_run_fails(tmp_path):
    scene, out = write(tmp_path)
    assert main([str(scene), "--quiet"]) == 0
    before = (out / "summary.json").read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(scene.read_text().replace("radius = 0.02", "radius = 0.02\nkind = 3"))
    assert main([str(bad), "--quiet"]) == 2
    assert (out / "summary.json").read_text() == before


def test_help_and_version_from_a_subprocess():
    run = subprocess.run(
        [sys.executable, "-m", "contact.grasp", "--help"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        check=False,
    )
    assert run.returncode == 0
    for option in ("--out", "--frames", "--no-pictures", "--pose-only", "--quiet", "--version"):
        assert option in run.stdout
    assert "Exit status" in run.stdout
    run = subprocess.run(
        [sys.executable, "-m", "contact.grasp", "--version"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        check=False,
    )
    assert run.returncode == 0 and "0.1" in run.stdout


HAND = """
[ball]
radius = 0.01
kind = "solid"
element = "hex"
mesh_size = 0.004
center = [-0.007, 0.06, 0.0]
material = {{ E = 1.0e6, nu = 0.3 }}

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


def test_a_ball_inside_a_bone_is_bad_input(tmp_path, capsys):
    out = tmp_path / "results"
    scene = tmp_path / "bone.toml"
    scene.write_text(HAND.format(out=out.as_posix()))
    assert main([str(scene), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "inside bone middle_metacarpal" in err and "Traceback" not in err
    assert not out.exists()


def test_a_ball_mesh_file_with_nan_coordinates_is_bad_input(tmp_path, capsys):
    import numpy as np

    import fem

    mesh = fem.ball_mesh(0.02, divisions=2, layers=1)
    pts = mesh.points.copy()
    pts[3, 1] = np.nan
    bad = tmp_path / "ball.vtu"
    import meshio

    meshio.write(bad, meshio.Mesh(pts, [("hexahedron", mesh.cells["hexahedron"])]))
    scene, out = write(tmp_path)
    text = scene.read_text().replace("mesh_size = 0.003", f'mesh = "{bad.as_posix()}"')
    scene.write_text(text)
    assert main([str(scene), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "ball.vtu" in err and "\n" not in err.strip() and "Traceback" not in err
    assert not out.exists()


def test_pose_only_writes_the_posed_hand_the_ball_and_where_each_finger_is(tmp_path, capsys):
    """The index of finger_press is flexed 0.5 mm, then 1 mm, into the ball: its nearest
    skin node is inside by about that (the ball's facets lie inside the sphere); the
    other parts stay centimetres away; nothing is solved."""
    from contact.app.report import parse_line

    out = tmp_path / "pose"
    scene = ROOT / "examples" / "finger_press.toml"
    assert main([str(scene), "--pose-only", "--out", str(out)]) == 0
    names = sorted(p.name for p in out.iterdir() if p.name != ".grasp-contact.json")
    assert names == [
        "ball.pvd", "ball_0000.vtu", "ball_0001.vtu", "ball_0002.vtu",
        "hand.pvd", "hand_0000.vtu", "hand_0001.vtu", "hand_0002.vtu", "pose.json",
    ]  # fmt: skip
    doc = json.loads((out / "pose.json").read_text())
    frames = doc["frames"]
    assert [f["time"] for f in frames] == [0.0, 0.5, 1.0]
    index = [f["parts"]["index"]["nearest"]["distance"] for f in frames]
    assert index[0] > 0.01  # not yet flexed
    assert -0.0006 < index[1] < -0.0003 and -0.0011 < index[2] < -0.0008
    for f in frames:
        parts = f["parts"]
        assert set(parts) == {"palm", "thumb", "index", "middle", "ring", "little"}
        assert "tip" not in parts["palm"]
        for name, rec in parts.items():
            if name != "index":
                assert rec["nearest"]["distance"] > 0.01
            if "tip" in rec:
                assert len(rec["tip"]["position"]) == 3
                assert rec["tip"]["distance"] >= rec["nearest"]["distance"]
    assert "index_mcp" in frames[1]["auto_flexion"]
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 4
    rec = parse_line(lines[2])
    near = dict(p.split(":") for p in rec["nearest_mm"].split(","))
    assert float(near["I"]) == pytest.approx(1e3 * index[2], abs=1e-3 * abs(1e3 * index[2]))
    assert list(dict(p.split(":") for p in rec["tip_mm"].split(","))) == list("TIMRL")
    assert parse_line(lines[-1]) == {"frames": "3", "results": str(out)}
    # a second run replaces the pose folder; a folder of other files is refused
    assert main([str(scene), "--pose-only", "--out", str(out), "--frames", "1", "--quiet"]) == 0
    assert [f["index"] for f in json.loads((out / "pose.json").read_text())["frames"]] == [1]
    assert capsys.readouterr().out == ""
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    assert main([str(scene), "--pose-only", "--out", str(other), "--quiet"]) == 2
    assert "not a pose folder" in capsys.readouterr().err
    assert sorted(p.name for p in other.iterdir()) == ["notes.txt"]


def test_pose_only_needs_a_hand(tmp_path, capsys):
    scene, out = write(tmp_path)
    assert main([str(scene), "--pose-only"]) == 2
    err = capsys.readouterr().err
    assert "--pose-only needs a [hand]" in err and "\n" not in err.strip()
    assert not Path(f"{out}_pose").exists()
