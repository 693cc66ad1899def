"""``python -m contact.grasp SCENE.toml``: the command line that runs a scene.

It reads the scene, solves its frames (:class:`contact.run.GraspRun`: pose the hand, place
the ball, resolve the contact) and writes the results folder
(:class:`contact.output.ResultsWriter`), with a progress bar on a terminal and warnings as
one log line each. On stdout it reports one line a frame and a closing line
(:mod:`contact.app.report`; ``--quiet`` silences them). Exit status (:data:`EXIT_STATUS`): 0
when every frame converged with every bone under its limit, 1 when a frame did not
converge, a bone passed its limit or a free body is not held (everything is still written;
stderr names each such frame and why, unless ``--quiet``; the run stops at the first frame
not held, the frames after it reported as not solved: :mod:`contact.app.unheld`), 2 for bad
input (one line on stderr naming the file, key or element; nothing written, except where a
later frame cannot be set up where the motion brought it: the frames solved are written,
that one and those after it reported as not solved), 3 for an
internal error (one line naming the exception and a log file holding its traceback), 4 for
an I/O failure (a folder that cannot be written, a full disk, a race lost to another run),
130 and 143 when interrupted by SIGINT (Ctrl-C) and SIGTERM (one line; the staging folder
removed, the previous results untouched).

Each frame's record gets the grasp's figures (:mod:`contact.output.summary`): the grip
force, the forces, contact area and peak pressure per hand part, and the largest strain
per body, with a warning past :data:`contact.output.summary.SMALL_STRAIN`.

With friction every frame depends on the frames before it (where each contact stuck), so
``--frames`` replays the history: every frame from the first up to the last one asked for
is solved, in time order, and only those asked for are written.

``--pose-only`` poses the hand and places the ball without solving
(:mod:`contact.app.poseonly`).

``--least-grip`` then searches the least scale of the scene's force-driven grip that holds
the ball at every frame (:mod:`contact.holding.leastgrip`; the normal run is its first trial), adds
it to ``summary.json`` as ``least_grip`` and reports it in one more line; each trial gives
a progress line on stderr. It needs every frame (no ``--frames``), something force-driven,
gravity and friction: else exit status 2, nothing written. The exit status stays the
frames' own.
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import sys
import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import TextIO

import fem

from .app import unheld
from .app.cli import check_terminated, guarded
from .app.poseonly import pose_only
from .app.report import frame_line, least_grip_line, trial_line
from .errors import ContactError, OutputError, SceneError, TargetError
from .hand.fingers import node_parts
from .holding.leastgrip import Trial, judge, least_grip
from .output import BodyFrame, ResultsWriter, summary, versions
from .run import GraspRun
from .scene.read import load_scene
from .solver.body import ElasticBody
from .solver.results import FrameResult, IterationRecord

__all__ = [
    "EXIT_STATUS",
    "GraspRun",
    "main",
    "run",
]

log = logging.getLogger(__name__)

#: The exit statuses of the command line, as ``--help`` and the README list them.
EXIT_STATUS = (
    "Exit status: 0 every frame converged with every bone under its limit; 1 a frame did "
    "not converge, a bone passed its limit or a free body is not held (results are still "
    "written; stderr names the frames and why, unless --quiet; the run stops at the first "
    "frame not held, the later frames reported as not solved); 2 bad input (one line; "
    "nothing written, or, where a later frame cannot be set up, the frames before it); "
    "3 an internal error (one line and the path of a log file with its traceback); 4 an "
    "I/O failure (a folder that cannot be written, a full disk, a race lost to another "
    "run; the previous results untouched); 130 / 143 interrupted by SIGINT / SIGTERM "
    "(the previous results untouched)."
)
#: Frames named one line each on stderr when a run exits 1; past these, one line counts.
_FAILED_LINES = 5


def _version() -> str:
    try:
        from importlib.metadata import version

        return version("grasp-contact")
    except Exception:  # not installed as a distribution
        return "unknown"


def run(
    scene_path: str | Path,
    *,
    out: str | Path | None = None,
    frames: Sequence[int] | None = None,
    pictures: bool | None = None,
    quiet: bool = False,
    least: bool = False,
) -> int:
    """Run a scene and write its results folder.

    Parameters
    ----------
    scene_path : str or Path
        The scene file (TOML; see ``docs/scene.md``).
    out : str or Path, optional
        Results folder; default the scene's ``output.directory``.
    frames : sequence of int, optional
        Indices of the frames to write; default all. Without friction only these are
        solved; with friction every frame up to the last of them is solved, in order.
    pictures : bool, optional
        Render pictures; default the scene's ``output.pictures``.
    quiet : bool
        No progress bar and no report on stdout.
    least : bool
        ``--least-grip``: then search the least grip that holds and add it to the summary.

    Returns
    -------
    int
        The exit status: 0 every frame realistic, 1 not (stderr names the frames unless
        ``quiet``), 2 bad input, 4 an I/O failure (one line on stderr); see
        :data:`EXIT_STATUS`.
    """
    try:
        scene = load_scene(scene_path)
    except (ContactError, ValueError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    times = list(scene.frames)
    if least:
        try:
            if frames is not None:
                raise SceneError("--least-grip holds the ball at every frame: it takes no --frames")
            scene.grip  # noqa: B018 (refuses what it cannot scale or hold)
        except SceneError as exc:
            print(f"error: {scene.path}: {exc}", file=sys.stderr)
            return 2
    chosen = list(range(len(times))) if frames is None else list(frames)
    bad = [i for i in chosen if not 0 <= i < len(times)]
    if bad:
        print(
            f"error: --frames {bad[0]}: the scene has frames 0..{len(times) - 1}",
            file=sys.stderr,
        )
        return 2
    twice = sorted({i for i in chosen if chosen.count(i) > 1})
    if twice:
        print(f"error: --frames {twice[0]}: a frame is asked for twice", file=sys.stderr)
        return 2
    directory = Path(out) if out is not None else scene.output.directory
    show = scene.output.pictures if pictures is None else pictures
    try:
        writer = ResultsWriter(
            directory,
            pictures=show,
            gif=scene.output.gif and show,
            window_size=scene.output.window_size,
        )
    except (TargetError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 4
    solved = chosen
    if scene.frictional and frames is not None:
        # the history of stick anchors: solve from the first frame, in order
        chosen = sorted(set(chosen))
        solved = list(range(chosen[-1] + 1)) if chosen else []
    bar = _progress(len(solved), quiet)
    status = 0
    entries = []
    results: list[FrameResult] = []
    found = None
    unsolved: list[dict] = []
    failed: Exception | None = None  # why a later frame could not be set up
    try:
        run_ = GraspRun(scene)
        hand_labels: dict = {}
        if run_.hand is not None:  # the hand's cells named by part and bone in the results
            hand_labels = {
                "region_names": run_.hand.part_names,
                "cell_bone": run_.hand.cell_bone,
                "bone_names": run_.hand.skeleton.bone_names,
            }
        for k, i in enumerate(solved):
            check_terminated()
            t = times[i]
            t0 = time.perf_counter()
            bar.set_description(f"t = {t:g}")

            def tell(rec: IterationRecord) -> None:
                bar.set_postfix(
                    iteration=rec.iteration, change=f"{rec.max_change:.2e}", refresh=True
                )

            try:
                result, extra, planes, frame_bodies = run_.frame(t, tell)
            except OutputError:
                raise
            except (ContactError, fem.FemError) as exc:
                if not results:
                    raise  # the scene's own start: nothing solved to keep
                # the motion brought the run where it cannot go on: what it solved is kept
                status, failed = 2, exc
                rest = [(j, times[j]) for j in solved[k:] if j in chosen]
                unsolved = unheld.cannot_set_up(t, exc, rest)
                break
            results.append(result)
            gone = unheld.lost(result)
            if gone:  # no defined state to go on from: the run stops here (contact.app.unheld)
                status = 1
                later = [j for j in solved[k + 1 :] if j in chosen]
                unsolved = unheld.not_solved(i, t, result, [(j, times[j]) for j in later])
            if i not in chosen:
                log.info("t = %g: replayed for the friction history (not written)", t)
                bar.update(1)
                if gone:
                    break
                continue
            bodies = {
                b.name: BodyFrame(
                    b.mesh,
                    b.materials,
                    bbar=b.bbar,
                    nodal_pressure=b.nodal_pressure,
                    finite=b.finite,
                    **(hand_labels if b.name == "hand" else {}),
                )
                for b in frame_bodies
            }
            entry = writer.add_frame(
                i,
                t,
                result,
                bodies,
                planes=[(p.name, p.point + p.motion, p.normal) for p in planes],
                extra={**extra, **_figures(run_, result, frame_bodies, t)},
            )
            entries.append(entry)
            if not entry["verdict"]["realistic"]:
                status = 1
            log.info("t = %g: %s", t, entry["verdict"]["reason"])
            if not quiet:
                bar.write(frame_line(entry, time.perf_counter() - t0), file=sys.stdout)
            bar.update(1)
            if gone:
                break
        if least and failed is None:
            found = _least_grip(run_, times, results, bar, quiet)
        check_terminated()
        writer.finish(scene.echo(), versions=versions())
        if found is not None:
            summary.add_least_grip(directory / "summary.json", found)
        if unsolved:
            unheld.add_not_solved(directory / "summary.json", unsolved)
    except OutputError as exc:
        writer.abort()
        bar.close()
        print(f"error: {exc}", file=sys.stderr)
        return 4
    except (ContactError, fem.FemError) as exc:  # the scene's: a bare ValueError is a bug (3)
        writer.abort()
        bar.close()
        print(f"error: {scene.path}: {exc}", file=sys.stderr)
        return 2
    except BaseException:
        writer.abort()
        bar.close()
        raise
    bar.close()
    if failed is not None:
        print(f"error: {scene.path}: {failed}", file=sys.stderr)
    if not quiet:
        if unsolved:
            print(unheld.not_solved_line(unsolved), flush=True)
        print(unheld.closing_line(entries, directory, unsolved), flush=True)
        if found is not None:
            print(least_grip_line(found), flush=True)
    if status and not quiet:
        _tell_failed(entries, directory, unsolved)
    return status


def _tell_failed(entries: Sequence[dict], directory: Path, unsolved: Sequence[dict]) -> None:
    """On stderr: each frame not realistic and why (the first few), those not solved, the folder."""
    failed = [e for e in entries if not e["verdict"]["realistic"]]
    for e in failed[:_FAILED_LINES]:
        print(f"frame {e['index']} (t = {e['time']:g}): {e['verdict']['reason']}", file=sys.stderr)
    if len(failed) > _FAILED_LINES:
        more = len(failed) - _FAILED_LINES
        print(f"... and {more} more frames not realistic (summary.json)", file=sys.stderr)
    if unsolved:
        print(unheld.not_solved_message(unsolved), file=sys.stderr)
    print(f"results in {directory}", file=sys.stderr)


def _least_grip(
    run: GraspRun, times: list[float], results: list[FrameResult], bar, quiet: bool
) -> dict:
    """The least-grip search from the normal run (its first trial); its summary item."""
    first = dataclasses.replace(judge(1.0, results, times, run.scene), solves=0)  # reused

    def tell(n: int, tr: Trial) -> None:
        log.info("least grip: trial %d at %.4gx: %s", n, tr.scale, tr.reason)
        if not quiet:
            bar.write(trial_line(n, tr.scale, tr.holds, tr.h, tr.reason), file=sys.stderr)

    return least_grip(run, times, first=first, on_trial=tell).record()


def _figures(run: GraspRun, result: FrameResult, bodies: Sequence[ElasticBody], t: float) -> dict:
    """The grasp's figures of a frame: grip force, per hand part, largest strain per body."""
    hand = next((b for b in bodies if b.name == "hand"), None)
    out: dict = {"grip_force": summary.grip_force(result, None if hand is None else "hand")}
    out["fingers"] = None
    if hand is not None and run.hand is not None:
        names = run.hand.part_names
        out["fingers"] = summary.part_forces(
            result.contact_fields.get("hand"),
            node_parts(hand.mesh, len(names)),
            names,
            hand.node_areas,
        )
    strains = {}
    for b in bodies:
        e = summary.max_strain(
            b.mesh, result.displacement[b.name], bbar=b.bbar, nodal_pressure=b.nodal_pressure,
            finite=b.finite,
        )  # fmt: skip
        strains[b.name] = e
        if e > summary.SMALL_STRAIN and not b.finite:
            log.warning(
                "t = %g: the %s's largest strain is %.0f %%, past %.0f %%: beyond small-strain "
                "linear elasticity, its forces and stresses are an extrapolation",
                t,
                b.name,
                100 * e,
                100 * summary.SMALL_STRAIN,
            )
    out["max_strain"] = strains
    return out


def _progress(total: int, quiet: bool):
    from tqdm import tqdm

    return tqdm(
        total=total,
        unit="frame",
        disable=quiet or not sys.stderr.isatty(),
        file=sys.stderr,
        dynamic_ncols=True,
    )


def main(argv: Sequence[str] | None = None) -> int:
    """The command line; returns the exit status."""
    ap = argparse.ArgumentParser(
        prog="python -m contact.grasp",
        description="Pose a hand by keyframes and resolve its contact with a deformable "
        "ball, frame by frame; write the displacements, stresses, contact and bone forces, "
        "pictures and a summary with the verdict (is the grasp realistic?).",
        epilog=EXIT_STATUS + " The scene keys are documented in docs/scene.md.",
    )
    ap.add_argument("scene", help="the scene file (TOML; see docs/scene.md)")
    ap.add_argument(
        "--out",
        metavar="DIR",
        help="results folder (default: the scene's output.directory); an existing folder "
        "is replaced only once the new results are complete",
    )
    ap.add_argument(
        "--frames",
        metavar="I",
        type=int,
        nargs="+",
        help="write only these frames (0-based indices into the scene's frame times); "
        "without friction only they are solved, with friction every frame up to the last "
        "of them is solved in order, since each depends on those before it",
    )
    ap.add_argument(
        "--no-pictures", action="store_true", help="write no PNG frames, GIF or stress pictures"
    )
    ap.add_argument(
        "--pose-only",
        action="store_true",
        help="pose the hand and place the ball at every frame without solving any contact; "
        "write the posed hand, the ball and pose.json (each fingertip and each part's "
        "distance to the ball) into DIR (default: output.directory with _pose appended)",
    )
    ap.add_argument(
        "--least-grip",
        action="store_true",
        help="after the run, search the least scale of the scene's force-driven grip that "
        "holds the ball at every frame (to 1 %%); write it to summary.json as least_grip "
        "and print it (needs force-driven planes, gravity and friction)",
    )
    ap.add_argument(
        "--quiet",
        action="store_true",
        help="no progress bar, no report on stdout and no log messages but errors",
    )
    ap.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    args = ap.parse_args(argv)
    logging.basicConfig(
        level=logging.ERROR if args.quiet else logging.WARNING,
        format="%(levelname)s: %(message)s",
    )
    # a warning (a mesh coarser than the wall, a pressure beyond small strains) is one
    # line on stderr like the log's, not a source line and a traceback-like location
    shown = warnings.showwarning
    warnings.showwarning = _warn_line
    try:
        return guarded(lambda: _dispatch(args), "the previous results are untouched")
    finally:
        warnings.showwarning = shown


def _dispatch(args: argparse.Namespace) -> int:
    """The command the arguments ask for: a run, a pose-only run, or a refusal."""
    if args.pose_only and args.least_grip:
        print("error: --least-grip solves the scene: it takes no --pose-only", file=sys.stderr)
        return 2
    if args.pose_only:
        return pose_only(args.scene, out=args.out, frames=args.frames, quiet=args.quiet)
    return run(
        args.scene,
        out=args.out,
        frames=args.frames,
        pictures=False if args.no_pictures else None,
        quiet=args.quiet,
        least=args.least_grip,
    )


def _warn_line(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: TextIO | None = None,
    line: str | None = None,
) -> None:
    """A warning as one log line (suppressed by ``--quiet`` as the log is)."""
    log.warning("%s", message)


if __name__ == "__main__":
    sys.exit(main())
