"""Paired replay of warm-started posing frames: compare two versions of the relaxer fairly.

A keyframed sequence poses each frame from the previous one (``HandPoser.pose(start=...)``).
Such a chain amplifies round-off: a change of the relaxer that moves one node by 1e-15
sends every later frame on another path, so two versions of the code never pose the same
frames, and the slowest frames of one run are not those of the other. Measured on 1,176
frames at the full limits: the same code's chains agree, but a change that only
reorders floating-point sums moves the worst frame from 0.73 to 0.50 s and the count of
frames below quality 0.005 by a fifth.

This tool takes the chain out of the comparison. ``record`` poses the sequences once and
stores every frame's start: the previous pose's bone transforms and its relaxer
correction (its nonzero rows). ``replay`` poses every frame again from its stored start
with the code at hand, so that two versions face exactly the same problems: the Newton
steps and qualities of one version are reproduced to the bit, and the difference of two
versions is the difference of their relaxers alone, frame by frame. ``compare`` pairs
two replays: time (taken in the same way, on the same frames), steps, and the frames
where the worst quality dropped or rose.

Usage::

    python -m benchmarks.posing_replay record DIR [--fraction 1.0] [--seeds 12]
    python -m benchmarks.posing_replay replay DIR --csv new.csv [--against old.csv]

Replay the old code (a ``git worktree`` on ``PYTHONPATH``) and the new one alternately on
a quiet machine: absolute times drift by several per cent over minutes.
"""

from __future__ import annotations

import argparse
import csv
import time
import types
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from contact.hand.posing import HandPoser
from contact.hand.shipped import load_hand

from .posing import sequence_poses

__all__ = ["KEYS", "compare", "main", "record", "replay", "summary"]

#: The columns of a replay's CSV.
KEYS = ["seed", "sequence", "frame", "seconds", "newton_steps", "min_quality", "inverted"]


def record(
    folder: str | Path,
    fraction: float = 1.0,
    seeds: Iterable[int] = range(12),
    sequences: int = 2,
    resolution: str = "fine",
) -> list[Path]:
    """Pose warm-started sequences and store every frame's start, one file a seed.

    Parameters
    ----------
    folder : path
        Created if needed; ``seed_<n>.npz`` files are written into it.
    fraction : float
        Of every joint's limits, as the posing study's sequences.
    seeds : iterable of int
        Random seeds, a file each.
    sequences : int
        Sequences a seed.
    resolution : str
        The hand mesh.

    Returns
    -------
    list of Path
        The files written. Each holds the frames' ids, angles, the start's bone
        transforms and correction (``has_start`` false for a sequence's first frame),
        and what the chain itself gave (``newton_steps``, ``min_quality``): a replay of
        the same code reproduces them.
    """
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    hand = load_hand(resolution)
    poser = HandPoser(hand)
    poser.pose({})  # the relaxer's set-up, outside the timings
    names = sorted(hand.skeleton.limits)
    bones = sorted(hand.skeleton.forward_kinematics())
    files = []
    for seed in seeds:
        rng = np.random.default_rng(seed)
        rows: dict[str, list] = {k: [] for k in ("ids", "angles", "has", "tf", "steps", "q")}
        idx: list[np.ndarray] = []
        val: list[np.ndarray] = []
        for s in range(sequences):
            previous = None
            for i, angles in enumerate(sequence_poses(hand.skeleton, fraction, rng)):
                rows["ids"].append((seed, s, i))
                rows["angles"].append([angles.get(n, 0.0) for n in names])
                has = previous is not None and previous.correction is not None
                rows["has"].append(has)
                if has:
                    rows["tf"].append(np.stack([previous.transforms[b] for b in bones]))
                    moved = np.flatnonzero(np.abs(previous.correction).sum(axis=1) > 0.0)
                    idx.append(moved)
                    val.append(previous.correction[moved])
                else:
                    rows["tf"].append(np.zeros((len(bones), 4, 4)))
                    idx.append(np.zeros(0, dtype=np.int64))
                    val.append(np.zeros((0, 3)))
                previous = poser.pose(angles, check=False, start=previous)
                assert poser.relaxer is not None
                rows["steps"].append(poser.relaxer.stats["iterations"])
                rows["q"].append(previous.min_quality)
        path = out / f"seed_{seed}.npz"
        np.savez_compressed(
            path,
            resolution=resolution,
            names=np.array(names),
            bones=np.array(bones),
            ids=np.array(rows["ids"], dtype=np.int64),
            angles=np.array(rows["angles"]),
            has_start=np.array(rows["has"]),
            transforms=np.array(rows["tf"]),
            offsets=np.cumsum([0] + [len(i) for i in idx]),
            nodes=np.concatenate(idx).astype(np.int64),
            correction=np.concatenate(val),
            newton_steps=np.array(rows["steps"], dtype=np.int64),
            min_quality=np.array(rows["q"]),
        )
        files.append(path)
        print(f"[posing_replay] recorded {len(rows['ids'])} frames of seed {seed} in {path}")
    return files


def replay(files: Sequence[str | Path]) -> list[dict]:
    """Pose every recorded frame again from its stored start (see :func:`record`).

    Parameters
    ----------
    files : sequence of path
        Recorded ``seed_<n>.npz`` files of one hand resolution.

    Returns
    -------
    list of dict
        One row a frame (:data:`KEYS`): its time, the relaxer's Newton steps, the worst
        tetrahedron quality and the tetrahedra left inverted.
    """
    if not files:
        raise ValueError("replay: no recorded files given")
    data = [np.load(f) for f in files]
    resolution = str(data[0]["resolution"])
    hand = load_hand(resolution)
    poser = HandPoser(hand)
    poser.pose({})
    n = len(hand.flesh.points)
    rows = []
    for d, f in zip(data, files, strict=True):
        if str(d["resolution"]) != resolution:
            raise ValueError(f"{f}: a {d['resolution']} hand; the first file's is {resolution}")
        names, bones, off = list(d["names"]), list(d["bones"]), d["offsets"]
        for k, (seed, s, i) in enumerate(d["ids"]):
            start = None
            if d["has_start"][k]:
                corr = np.zeros((n, 3))
                corr[d["nodes"][off[k] : off[k + 1]]] = d["correction"][off[k] : off[k + 1]]
                tf = dict(zip(bones, d["transforms"][k], strict=True))
                # pose() reads a start's correction and bone transforms alone
                start = types.SimpleNamespace(correction=corr, transforms=tf)
            angles = dict(zip(names, d["angles"][k].tolist(), strict=True))
            t0 = time.perf_counter()
            pose = poser.pose(angles, check=False, start=start)  # type: ignore[arg-type]
            seconds = time.perf_counter() - t0
            assert poser.relaxer is not None
            rows.append(
                {
                    "seed": int(seed),
                    "sequence": int(s),
                    "frame": int(i),
                    "seconds": seconds,
                    "newton_steps": int(poser.relaxer.stats["iterations"]),
                    "min_quality": float(pose.min_quality),
                    "inverted": len(pose.inverted),
                }
            )
    return rows


def summary(rows: Sequence[dict], goal: float = 0.2) -> str:
    """One line: mean, 95th and 99th percentile and worst time, steps and qualities."""
    t = np.array([r["seconds"] for r in rows])
    q = np.array([r["min_quality"] for r in rows])
    steps = sum(r["newton_steps"] for r in rows)
    inverted = sum(r["inverted"] > 0 for r in rows)
    return (
        f"{len(t)} frames: mean {t.mean():.4f} s, p95 {np.percentile(t, 95):.3f}, "
        f"p99 {np.percentile(t, 99):.3f}, max {t.max():.3f}, {(t > goal).sum()} above "
        f"{goal:g} s; {steps} Newton steps; worst quality {q.min():.4f}, "
        f"{(q < 0.002).sum()} frames below 0.002, {(q < 0.005).sum()} below 0.005; "
        f"{inverted} frames inverted"
    )


def compare(new: Sequence[dict], old: Sequence[dict], tol: float = 1e-4) -> str:
    """Pair two replays of the same frames: time, steps, and where the quality moved.

    Parameters
    ----------
    new, old : sequence of dict
        Rows of :func:`replay` (or read back from its CSV), the same frames.
    tol : float
        A worst quality moved by more than this counts as worse or better.

    Returns
    -------
    str
        One line.
    """
    key = ("seed", "sequence", "frame")
    by = {tuple(int(r[k]) for k in key): r for r in old}
    pairs = [(r, by.get(tuple(int(r[k]) for k in key))) for r in new]
    if any(o is None for _, o in pairs) or len(by) != len(new):
        raise ValueError("compare: the two replays are not of the same frames")
    t_new = sum(float(r["seconds"]) for r, _ in pairs)
    t_old = sum(float(o["seconds"]) for _, o in pairs)  # type: ignore[index]
    s_new = sum(int(r["newton_steps"]) for r, _ in pairs)
    s_old = sum(int(o["newton_steps"]) for _, o in pairs)  # type: ignore[index]
    dq = np.array([float(r["min_quality"]) - float(o["min_quality"]) for r, o in pairs])  # type: ignore[index]
    return (
        f"paired: {t_new:.2f} s against {t_old:.2f} s ({t_new / t_old:.3f}), Newton steps "
        f"{s_new} against {s_old}; worst quality lower on {(dq < -tol).sum()} frames, "
        f"higher on {(dq > tol).sum()}, largest drop {dq.min():.4f}"
    )


def _read(path: str | Path) -> list[dict]:
    with Path(path).open(newline="") as f:
        return list(csv.DictReader(f))


def main(argv: list[str] | None = None) -> None:
    """The command line (see the module)."""
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.posing_replay",
        description="Record warm-started posing sequences, then replay every frame from its "
        "recorded start: two versions of the relaxer on exactly the same frames.",
    )
    sub = ap.add_subparsers(dest="command", required=True)
    rec = sub.add_parser("record", help="pose sequences and store every frame's start")
    rec.add_argument("folder")
    rec.add_argument("--fraction", type=float, default=1.0, help="of the joint limits")
    rec.add_argument("--seeds", type=int, default=12, help="seeds 0 .. N-1, a file each")
    rec.add_argument("--sequences", type=int, default=2, help="sequences a seed")
    rec.add_argument("--resolution", default="fine", help="the hand mesh")
    rep = sub.add_parser("replay", help="pose every recorded frame from its start")
    rep.add_argument("folder")
    rep.add_argument("--csv", help="write the rows here")
    rep.add_argument("--against", help="a replay CSV of the same frames to pair with")
    args = ap.parse_args(argv)
    if args.command == "record":
        record(args.folder, args.fraction, range(args.seeds), args.sequences, args.resolution)
        return
    files = sorted(Path(args.folder).glob("seed_*.npz"))
    if not files:
        ap.error(f"{args.folder}: no recorded seed_*.npz files")
    rows = replay(files)
    print(summary(rows))
    if args.csv:
        with Path(args.csv).open("w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=KEYS)
            w.writeheader()
            w.writerows(rows)
    if args.against:
        print(compare(rows, _read(args.against)))


if __name__ == "__main__":
    main()
