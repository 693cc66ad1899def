"""Run ``contact.grasp`` with its stages timed: ``python benchmarks/_grasp_trace.py JSON ARGS``.

The grasp command line (``ARGS`` as for ``python -m contact.grasp``) is run in this process
with a few of its functions wrapped by timers, and the time spent in each stage written to
``JSON``. A stage's time is exclusive: the time of a wrapped function nested inside another
counts to its own stage only, so the stages add up to the wall time of the run (less the
interpreter's start, which the caller measures).

Stages: ``imports`` (``import contact.grasp``: numpy, scipy, fem, contact), ``load_mesh``
(reading the scene, making the ball's mesh, loading the hand and its rig), ``posing``
(keyframes, automatic flexion, mapping the flesh, placing the ball, the bone check),
``assemble_factor`` (every body's stiffness assembled and factored), ``contact`` (the
contact iteration of every frame), ``writing`` (the results folder: VTU files, stresses,
pictures, GIF, summary) and ``other`` (the rest of ``main``). Nothing of ``contact`` is
changed but for the timers; the exit status is that of the command line.

Kept out of the ``benchmarks`` package's imports on purpose: it is run as a script, so that
the child imports what ``python -m contact.grasp`` imports and nothing more.
"""

from __future__ import annotations

import time

_T0 = time.perf_counter()

import functools  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
from collections.abc import Callable  # noqa: E402
from typing import Any  # noqa: E402

__all__ = ["main"]

_totals: dict[str, float] = {}
_calls: dict[str, int] = {}
_stack: list[list[float]] = []  # [start, time of nested timed calls]


def _timed(stage: str, fn: Callable[..., Any]) -> Callable[..., Any]:
    """``fn`` with its exclusive time added to ``stage``."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        _stack.append([time.perf_counter(), 0.0])
        try:
            return fn(*args, **kwargs)
        finally:
            start, nested = _stack.pop()
            elapsed = time.perf_counter() - start
            _totals[stage] = _totals.get(stage, 0.0) + elapsed - nested
            _calls[stage] = _calls.get(stage, 0) + 1
            if _stack:
                _stack[-1][1] += elapsed

    return wrapper


def _wrap(owner: Any, name: str, stage: str) -> None:
    setattr(owner, name, _timed(stage, getattr(owner, name)))


def main(argv: list[str]) -> int:
    """Run the grasp command line ``argv[1:]``; write the stage times to ``argv[0]``."""
    path, args = argv[0], argv[1:]
    t0 = time.perf_counter()
    import contact.grasp
    import contact.output.writer
    import contact.run.grasprun
    import contact.scene.read
    import contact.solver.body
    import fem

    imports = time.perf_counter() - t0
    grasp = contact.grasp
    _wrap(contact.scene.read, "load_scene", "load_mesh")
    run = contact.run.grasprun
    _wrap(run.GraspRun, "__post_init__", "load_mesh")
    for name in ("angles", "ball_body", "hand_body"):
        _wrap(run.GraspRun, name, "posing")
    _wrap(run, "check_bones", "posing")
    _wrap(contact.solver.body.ElasticBody, "__init__", "assemble_factor")
    # bodies factor lazily, inside the contact iteration once their contact zone is marked
    _wrap(fem.StaticSolver, "factorize", "assemble_factor")
    _wrap(run, "solve_frame", "contact")
    _wrap(run, "solve_finite_frame", "contact")
    for name in ("__init__", "add_frame", "finish"):
        _wrap(contact.output.writer.ResultsWriter, name, "writing")
    _wrap(grasp, "main", "other")
    status = grasp.main(args)
    end = time.perf_counter()
    stages = {"imports": imports, **_totals}
    result = {
        "stages": stages,
        "calls": _calls,
        "script_s": end - _T0,
        "main_s": end - t0 - imports,
        "status": status,
    }
    with open(path, "w") as f:
        json.dump(result, f, indent=2)
    return int(status)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
