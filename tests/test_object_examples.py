"""The shipped object examples: the hand lifts an object off a table and holds it by friction."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from contact.grasp import main

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
@pytest.mark.parametrize("name", ["cube", "can"])
def test_the_example_holds_its_object_at_every_frame(tmp_path: Path, name: str) -> None:
    out = tmp_path / name
    assert main([str(ROOT / "examples" / f"{name}.toml"), "--quiet", "--no-pictures",
                 "--out", str(out)]) == 0  # fmt: skip
    summary = json.loads((out / "summary.json").read_text())
    frames = summary["frames"]
    assert all(f["converged"] and f["held"] for f in frames)
    assert all(f["verdict"]["realistic"] for f in frames)
    # at the end the table is gone: the fingers carry the whole weight
    last = frames[-1]
    (support,) = last["obstacle_forces"].values()  # the table (the can's stand)
    assert np.linalg.norm(support["force"]) == 0.0 and last["grip_force"] > 0
    assert (out / f"{name}.pvd").is_file()


@pytest.mark.slow
def test_the_cube_near_its_slip_limit_ends_every_frame_with_a_verdict(tmp_path: Path) -> None:
    """At mu 0.3 on the pads (the example has 0.8) every frame settles to a verdict.

    Held, not held, or turned past the small rotations the linear model describes; never
    "friction did not settle".
    """
    text = (ROOT / "examples" / "cube.toml").read_text()
    text = text.replace('"../meshes/', f'"{ROOT.as_posix()}/meshes/')
    assert "friction = 0.8 " in text
    scene = tmp_path / "cube.toml"
    scene.write_text(text.replace("friction = 0.8 ", "friction = 0.3 ", 1))
    out = tmp_path / "out"
    main([str(scene), "--quiet", "--no-pictures", "--out", str(out)])
    frames = json.loads((out / "summary.json").read_text())["frames"]
    assert len(frames) == 4
    for f in frames:
        # converged, or a verdict: not held, or turned past what the linear model describes
        stop = f["stop_reason"]
        assert f["converged"] or stop.startswith(("not held", "cube turned")), stop
        assert f["friction"]["residual"] <= f["friction"]["tolerance"] or not f["converged"]
