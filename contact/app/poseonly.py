"""``python -m contact.grasp SCENE.toml --pose-only``: pose the hand and place the ball, no solve.

For every frame the hand is posed as a grasp run poses it (keyframes, then automatic
flexion, the flesh mapped by JLD and relaxed; :class:`contact.run.GraspRun`'s pieces) and
the ball placed, and no contact is resolved: a user places a ball or aims a pinch from
where each finger is. The folder (default ``<output.directory>_pose``) holds::

    pose.json              per frame: angles, automatic flexions, each part's nearest skin
                           node and each fingertip, with positions and distances to the ball
    hand_NNNN.vtu          the posed hand (point data part, bone_id; cell data region)
    ball_NNNN.vtu          the placed ball
    hand.pvd, ball.pvd     the series

Distances are signed, to the ball's meshed outer surface (m, negative inside the ball).
A fingertip is a skin node: the boundary node farthest along the finger's distal bone
(:func:`contact.hand.fingers.fingertips`); since a finger meets a ball with its pad, a
part's ``nearest`` node is what says whether it touches. The folder is written through a
staging folder (:mod:`contact.output.staging`) and replaces only an empty folder or an
earlier pose folder whose marker lists every file in it.
"""

from __future__ import annotations

import json
import logging
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

import fem

from ..errors import ContactError, InputError, OutputError, TargetError
from ..hand.fingers import fingertips, node_parts
from ..hand.posing import Pose
from ..output.plainjson import jsonable
from ..output.staging import make_staging, write_atomic
from ..output.vtufields import write_pvd
from ..run import GraspRun
from ..scene.read import load_scene
from .report import pose_line

__all__ = ["pose_frame", "pose_only"]

log = logging.getLogger(__name__)


def pose_frame(run: GraspRun, t: float, start: Pose | None = None) -> tuple[Pose, fem.Mesh, dict]:
    """The hand posed and the ball placed at ``t``, and where each part is from the ball.

    Parameters
    ----------
    run : GraspRun
        The scene's run (with a hand).
    t : float
        Frame time.
    start : Pose, optional
        The previous frame's pose (warm start of the flesh's relaxation).

    Returns
    -------
    pose : Pose
        The posed hand.
    objects : dict of str to fem.Mesh
        Each placed object (the ball, the ``[[object]]`` meshes), by name.
    record : dict
        ``angles``, ``auto_flexion`` (as a grasp run records it), ``min_tet_quality``,
        ``parts``: part name -> ``nearest`` ``{node, position, distance}`` (the part's
        skin node nearest any object) and, for a finger, ``tip`` likewise.
    """
    hand = run.hand
    assert hand is not None and run.poser is not None
    angles = run.angles(t)
    pose = run.poser.pose(angles, start=start)
    objects = {}
    for o in run.objects:
        x = o.points(run.placement(o, t))
        objects[o.name] = fem.Mesh(x, o.mesh.cells, o.mesh.regions)
    surface = run.object_surfaces(t)
    names = hand.part_names
    parts = node_parts(hand.flesh, len(names))
    skin = hand.skin_faces.nodes
    tips = fingertips(hand)
    tip_nodes = np.array(list(tips.values()), dtype=np.int64)
    d_skin = surface.signed_distance(pose.points[skin])
    d_tip = surface.signed_distance(pose.points[tip_nodes])

    def point(node: int, distance: float) -> dict[str, Any]:
        return {"node": int(node), "position": pose.points[node], "distance": float(distance)}

    record: dict[str, Any] = {"angles": angles}
    if run.auto_flexed:
        record["auto_flexion"] = run.auto_flexed
    record["min_tet_quality"] = float(pose.min_quality)
    out: dict[str, dict[str, Any]] = {}
    for i, name in enumerate(names):
        own = np.flatnonzero(parts[skin] == i)
        out[name] = {}
        if own.size:
            k = own[np.argmin(d_skin[own])]
            out[name]["nearest"] = point(skin[k], d_skin[k])
    for (finger, node), d in zip(tips.items(), d_tip, strict=True):
        out.setdefault(finger, {})["tip"] = point(node, d)
    record["parts"] = out
    return pose, objects, jsonable(record)


def pose_only(
    scene_path: str | Path,
    *,
    out: str | Path | None = None,
    frames: Sequence[int] | None = None,
    quiet: bool = False,
) -> int:
    """Pose every frame of a scene and write the pose folder; no contact is solved.

    Parameters
    ----------
    scene_path : str or Path
        The scene file (with a ``[hand]``).
    out : str or Path, optional
        The folder; default the scene's ``output.directory`` with ``_pose`` appended.
    frames : sequence of int, optional
        Indices of the frames to pose; default all.
    quiet : bool
        No line on stdout.

    Returns
    -------
    int
        0; 2 on bad input, 4 when the folder cannot be written (one line on stderr,
        nothing written).
    """
    try:
        scene = load_scene(scene_path)
        if scene.hand is None:
            raise InputError("--pose-only needs a [hand]: the scene has none")
        times = list(scene.frames)
        asked = list(range(len(times)) if frames is None else frames)
        bad = [i for i in asked if not 0 <= i < len(times)]
        if bad:
            raise InputError(f"--frames {bad[0]}: the scene has frames 0..{len(times) - 1}")
        twice = sorted({i for i in asked if asked.count(i) > 1})
        if twice:
            raise InputError(f"--frames {twice[0]}: a frame is asked for twice")
        chosen = sorted(asked)
        default = scene.output.directory
        directory = Path(os.path.abspath(out if out is not None else f"{default}_pose"))
        stage = make_staging(directory, "pose")
    except OutputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2 if isinstance(exc, TargetError) else 4
    except (ContactError, ValueError, OSError) as exc:  # the scene's errors name its file
        print(f"error: {exc}", file=sys.stderr)
        return 2
    staging = stage.path
    try:
        records = _write_frames(GraspRun(scene), times, chosen, staging, quiet)
        doc = {"scene": str(scene.path), "units": "m", "frames": records}
        write_atomic(staging / "pose.json", (json.dumps(doc, indent=2) + "\n").encode())
        for body in records[0]["files"] if records else ():
            write_pvd(staging / f"{body}.pvd", [(r["time"], r["files"][body]) for r in records])
        stage.swap()
    except (OutputError, OSError) as exc:
        stage.discard()
        print(f"error: {scene.path}: {exc}", file=sys.stderr)
        return 4
    except (ContactError, ValueError, fem.FemError) as exc:
        stage.discard()
        print(f"error: {scene.path}: {exc}", file=sys.stderr)
        return 2
    except BaseException:
        stage.discard()
        raise
    if not quiet:
        print(f"frames={len(records)} results={directory}")
    return 0


def _write_frames(
    run: GraspRun, times: list[float], chosen: list[int], staging: Path, quiet: bool
) -> list[dict[str, Any]]:
    """Pose the chosen frames in time order; write their VTU files; their records."""
    assert run.hand is not None
    records = []
    pose = None
    n_parts = len(run.hand.part_names)
    for i in chosen:
        t = times[i]
        pose, objects, rec = pose_frame(run, t, start=pose)
        mesh = pose.mesh()
        files = {"hand": f"hand_{i:04d}.vtu"}
        files.update({name: f"{name}_{i:04d}.vtu" for name in objects})
        data = {"part": node_parts(mesh, n_parts), "bone_id": run.hand.bone_id}
        fem.write_mesh(staging / files["hand"], mesh, point_data=data)
        for name, m in objects.items():
            fem.write_mesh(staging / files[name], m)
        records.append({"index": i, "time": t, **rec, "files": files})
        if not quiet:
            near = {k: v["nearest"]["distance"] for k, v in rec["parts"].items() if "nearest" in v}
            tips = {k: v["tip"]["distance"] for k, v in rec["parts"].items() if "tip" in v}
            print(pose_line(i, t, near, tips), flush=True)
    return records
