"""``--pose-only``'s errors: one line that names the scene's file once."""

from pathlib import Path

from contact.grasp import main


def test_a_bad_scene_names_its_file_once(tmp_path: Path, capsys) -> None:
    scene = tmp_path / "s.toml"
    scene.write_text('[scene]\nname = "x"\n\n[hand]\nrig = "nope.toml"\n')
    for argv in ([str(scene), "--pose-only"], [str(scene)]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.count(str(scene)) == 1, err
