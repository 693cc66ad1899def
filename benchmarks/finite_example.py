"""The README example's closing frame at finite strain against the same frame linear.

``examples/grasp.toml`` linear (flesh and ball ``model = "linear"``), as shipped (its
flesh neo-Hookean) and with the ball neo-Hookean too, each run by
:class:`contact.run.GraspRun` through the frames before ``t = 1`` (the open hand, the
ball on the table) and then the frame at ``t = 1``, where the hand closes on the ball:
its wall-clock time in each model, its
Newton steps, where the finite one's time goes, and the verdict and grip of each.
Goal (the finite-strain issue): the finite frame at most 3x the linear one.
"""

from __future__ import annotations

import re
import tempfile
import time
from pathlib import Path

from contact.errors import ContactError
from contact.output import summary
from contact.run import GraspRun
from contact.scene import load_scene

from ._common import Column

__all__ = ["COLUMNS", "EXAMPLE", "FRAME", "GOAL", "example_rows", "example_section"]

#: The scene and the frame measured (the closing one), after the frames before it.
EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "grasp.toml"
FRAME = 1.0
#: The finite frame's time over the linear one's.
GOAL = 3.0

COLUMNS = (
    Column("model", "model"),
    Column("frame_s", "frame t = 1 (s)", ".2f"),
    Column("newton_steps", "Newton steps"),
    Column("converged", "converged"),
    Column("held", "held"),
    Column("grip_n", "grip (N)", ".3f"),
    Column("linearise_s", "linearising (s)", ".2f"),
    Column("linear_frames_s", "linear frames (s)", ".2f"),
    Column("checks_s", "checks (s)", ".2f"),
)


def _models(text: str, ball: str, flesh: str) -> str:
    """The scene with its ball's (``material``) and flesh's ``model`` set (inline tables)."""
    for key, model in (("material", ball), ("flesh", flesh)):
        text, n = re.subn(
            rf'^({key} = \{{[^}}\n]*?)(,\s*model = "[^"]*")?\s*\}}',
            rf'\1, model = "{model}" }}', text, count=1, flags=re.M,
        )  # fmt: skip
        if n != 1:
            raise RuntimeError(f"{EXAMPLE}: its {key} table was not found")
    return text


def _closing_frame(text: str, folder: Path, name: str) -> dict:
    """Run the scene ``text`` to its closing frame; that frame's figures."""
    path = folder / f"{name}.toml"
    path.write_text(text.replace('directory = "results/grasp"', f'directory = "{folder}"'))
    scene = load_scene(path)
    run = GraspRun(scene)
    try:
        for t in scene.frames:
            if t < FRAME:
                run.frame(t)
        t0 = time.perf_counter()
        res, extra, _, _ = run.frame(FRAME)
    except ContactError as exc:  # a frame the run could not set up: said, not timed
        return {"model": name, "frame_s": None, "newton_steps": "-", "converged": False,
                "held": None, "grip_n": None, "error": str(exc)}  # fmt: skip
    seconds = time.perf_counter() - t0
    newton = extra.get("newton", {})
    grip = summary.grip_force(res, "hand")
    timings = res.timings
    return {
        "model": name, "frame_s": seconds, "newton_steps": newton.get("steps", "-"),
        "converged": res.converged, "held": res.held, "grip_n": grip,
        "linearise_s": timings.get("linearise", 0.0),
        "linear_frames_s": timings.get("linear frames", 0.0),
        "checks_s": timings.get("checks", 0.0),
    }  # fmt: skip


def example_rows() -> list[dict]:
    """The closing frame: linear, the flesh neo-Hookean, the flesh and the ball."""
    text = EXAMPLE.read_text()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        return [
            _closing_frame(_models(text, "linear", "linear"), folder, "linear"),
            _closing_frame(
                _models(text, "linear", "neo-hookean"), folder, "neo-hookean flesh"
            ),
            _closing_frame(
                _models(text, "neo-hookean", "neo-hookean"), folder, "neo-hookean flesh and ball"
            ),
        ]


def example_section(rows: list[dict]) -> str:
    """The goal lines under the table."""
    lines = []
    for row in rows[1:]:
        if row["frame_s"] is None or rows[0]["frame_s"] is None:
            lines.append(f"{row['model']}: not run to t = 1 ({row.get('error', '')})")
            continue
        ratio = row["frame_s"] / rows[0]["frame_s"]
        verdict = "met" if ratio <= GOAL else "MISSED"
        lines.append(f"{row['model']} / linear {ratio:.1f}x: {verdict}")
    return (
        "The README example's closing frame (t = 1, the hand closing on the ball), after "
        f"the frames before it, against the goal of {GOAL:g}x: {'; '.join(lines)}. The "
        "linear frame factors each body once; each Newton step assembles and factors the "
        "tangent anew and solves a whole linear frame. The free neo-Hookean ball is solved "
        "with its turn stiffness (fem.TurningInverse), free to roll: where the frames "
        "before t = 1 roll it from its pole onto a facet, the keyframes may close a bone "
        "through where it went, and that frame cannot be set up."
    )
