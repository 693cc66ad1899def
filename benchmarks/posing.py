"""Posing the hand: time per frame and tetrahedron quality over the range of motion.

For each shipped resolution of the hand, :class:`contact.HandPoser` is built once (the JLD
localisation) and then times a frame: the JLD mapping of every flesh node, the bone
transforms and the signed volumes of every tetrahedron. The goal is at most
:data:`GOAL_S` seconds a frame on the fine mesh.

The range of motion is sampled at fractions of every joint's limits: each angle alone at
that fraction of each of its limits, and random poses with every angle uniform within that
fraction of its limits. For each fraction the table gives the poses that invert a
tetrahedron (and of those, the ones where only tetrahedra whose four nodes are fixed to
bones invert: no mapping of the free flesh can save those), the joints blamed, and the
smallest tetrahedron quality ``6 sqrt(2) V / l_rms^3`` of the poses that do not invert.

The diagnostic columns say why poses would invert without the relaxer: the poses where
the JLD mapping alone inverts a tetrahedron, the joints whose areas hold those tetrahedra
(the zone joint of most of their nodes) and what kind they are: on the skin (a node on
the outer skin), on a bone (a node fixed to a bone, none on the skin) or inner.

The random poses above are independent. An animation poses a keyframed sequence, frame
after frame: the sequence study (``posing_sequences.csv``) animates from rest through
random keys at the same fractions of the limits (Kochanek-Bartels, one key a second,
:data:`SEQ_FPS` frames a second) and poses every frame twice: on its own (cold), and
warm-started from the previous frame (``HandPoser.pose(..., start=previous)``).
"""

from __future__ import annotations

import time
import warnings
from collections import Counter
from pathlib import Path

import numpy as np

from contact.hand.keyframes import Keyframes
from contact.hand.posing import HandPoser
from contact.hand.quality import tet_quality, tet_volumes
from contact.hand.shipped import load_hand
from contact.hand.skeleton import Skeleton

from ._common import (
    load_average,
    machine_info,
    measure,
    results_dir,
    write_csv,
)
from .posing_report import LEFT_COLUMNS, SEQ_FPS, SEQ_KEYS, SEQ_KEYS_CSV, _plot, _write_report

__all__ = [
    "FRACTIONS",
    "GOAL_S",
    "SEQ_FPS",
    "run",
    "sample_range",
    "sample_sequences",
    "sequence_keys",
    "sequence_poses",
]

#: Goal: seconds to pose one frame of the fine hand.
GOAL_S = 0.2
#: Fractions of the joint limits sampled: full run and ``--quick``.
FRACTIONS = {False: (0.25, 0.5, 0.75, 1.0), True: (0.25, 0.5)}
#: Random poses per fraction: full run and ``--quick``.
N_RANDOM = {False: 40, True: 4}
#: Resolutions: full run and ``--quick``.
RESOLUTIONS = {False: ("coarse", "fine", "fingertips"), True: ("coarse",)}
#: Sequences per fraction: full run and ``--quick``.
N_SEQUENCES = {False: 2, True: 1}

CSV_KEYS = [
    "resolution",
    "nodes",
    "tets",
    "fraction",
    "poses",
    "inverted_poses",
    "bone_only_poses",
    "min_quality",
    "mean_s",
    "max_s",
    "rest_quality",
    "blamed",
    "jld_inverted_poses",
    "jld_where",
    "jld_kinds",
]


def sample_range(poser: HandPoser, fraction: float, n_random: int, seed: int = 0) -> dict:
    """Pose the hand over a fraction of its range of motion and summarise the quality.

    Parameters
    ----------
    poser : HandPoser
    fraction : float
        Fraction of every joint's limits.
    n_random : int
        Random poses on top of the single-angle ones.
    seed : int

    Returns
    -------
    dict
        ``poses``, ``inverted_poses``, ``bone_only_poses``, ``min_quality`` (over the
        poses that invert nothing), ``blamed`` (joint: count) and ``unmended`` (per pose
        left inverted: the pose, the joint blamed, the first inverted element, how many are
        inverted, the element's nodes fixed to a bone and its quality).
    """
    hand = poser.hand
    limits = hand.skeleton.limits
    tets = hand.flesh.cells["tetra"]
    bone_only = (hand.bone_id[tets] >= 0).all(axis=1)
    poses = [
        {name: fraction * lim}
        for name, (lo, hi) in limits.items()
        for lim in (lo, hi)
        if lim != 0.0
    ]
    rng = np.random.default_rng(seed)
    poses += [
        {n: rng.uniform(fraction * lo, fraction * hi) for n, (lo, hi) in limits.items()}
        for _ in range(n_random)
    ]
    inverted = bone = jld_bad = 0
    worst = np.inf
    blamed: Counter[str] = Counter()
    unmended: list[dict] = []
    where: Counter[str] = Counter()
    kinds: Counter[str] = Counter()
    skin = np.zeros(hand.flesh.n_points, dtype=bool)
    skin[np.unique(hand.skin_faces.faces["triangle"])] = True
    zone = poser.flesh_map.zone_joint
    joints = hand.skeleton.joint_names
    times = []
    for angles in poses:
        jld = hand.flesh.points + poser.flesh_map.displacement(angles)
        bad = np.flatnonzero(tet_volumes(jld, tets) <= 0.0)
        if len(bad):
            jld_bad += 1
            for t in tets[bad]:
                z = zone[t][zone[t] >= 0]
                where[joints[np.bincount(z).argmax()] if len(z) else "buffer"] += 1
                on_bone = (hand.bone_id[t] >= 0).any()
                kinds["skin" if skin[t].any() else "bone" if on_bone else "inner"] += 1
        t0 = time.perf_counter()
        pose = poser.pose(angles, check=False)
        times.append(time.perf_counter() - t0)
        if len(pose.inverted):
            inverted += 1
            bone += bool(bone_only[pose.inverted].all())
            first = int(pose.inverted[0])
            joint = poser.culprit(pose.angles, first)
            blamed[joint] += 1
            unmended.append(
                {
                    "pose": _describe(angles),
                    "joint": joint,
                    "element": first,
                    "inverted": len(pose.inverted),
                    "bone_nodes": int((hand.bone_id[tets[first]] >= 0).sum()),
                    "quality": float(pose.quality[first]),
                }
            )
        else:
            worst = min(worst, pose.min_quality)
    return {
        "poses": len(poses),
        "inverted_poses": inverted,
        "bone_only_poses": bone,
        "min_quality": float(worst) if np.isfinite(worst) else None,
        "mean_s": float(np.mean(times)),
        "max_s": float(np.max(times)),
        "blamed": ", ".join(f"{j} {c}" for j, c in blamed.most_common(4)),
        "unmended": unmended,
        "jld_inverted_poses": jld_bad,
        "jld_where": ", ".join(
            f"{j} {c / max(where.total(), 1):.0%}" for j, c in where.most_common(4)
        ),
        "jld_kinds": " / ".join(
            f"{kinds[k] / max(kinds.total(), 1):.0%}" for k in ("skin", "bone", "inner")
        ),
    }


def sequence_keys(
    limits: dict[str, tuple[float, float]], fraction: float, rng: np.random.Generator
) -> list[dict]:
    """The keys of one sequence: rest at time 0, then :data:`SEQ_KEYS` random keys.

    Every angle is keyed at 0 (rest) at the start: a key that leaves an angle out does
    not key it, and before its first key an angle holds that key's value (an empty first
    key would start the sequence at the first random pose, posed cold, and hold it for a
    second).
    """
    keys = [{"time": 0.0, "angles": dict.fromkeys(limits, 0.0)}]
    for k in range(SEQ_KEYS):
        angles = {
            n: float(rng.uniform(fraction * lo, fraction * hi)) for n, (lo, hi) in limits.items()
        }
        keys.append({"time": float(k + 1), "angles": angles})
    return keys


def sequence_poses(
    skeleton: Skeleton, fraction: float, rng: np.random.Generator
) -> list[dict[str, float]]:
    """One sequence's joint angles, frame by frame.

    :func:`sequence_keys` sampled at :data:`SEQ_FPS` frames a second, the spline's
    overshoots clamped silently. The sequences of :func:`sample_sequences` and of
    :mod:`benchmarks.posing_replay`.
    """
    frames = Keyframes(skeleton, sequence_keys(skeleton.limits, fraction, rng))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return [frames.pose(t) for t in np.arange(SEQ_KEYS * SEQ_FPS + 1) / SEQ_FPS]


def sample_sequences(poser: HandPoser, fraction: float, n_sequences: int, seed: int = 0) -> dict:
    """Pose keyframed sequences frame by frame, cold and warm-started.

    Each sequence starts at rest and goes through :data:`SEQ_KEYS` random keys (every
    angle uniform within ``fraction`` of its limits), one a second, sampled at
    :data:`SEQ_FPS` frames a second. Every frame is posed on its own (cold) and from the
    previous frame's pose (warm, :meth:`HandPoser.pose` with ``start``).

    Returns
    -------
    dict
        ``frames``; per mode (``cold_``, ``warm_``): ``mean_s``, ``max_s``, ``steps``
        (the relaxer's Newton steps, all frames), ``min_quality`` and ``inverted`` (frames
        left with an inverted tetrahedron).
    """
    hand = poser.hand
    rng = np.random.default_rng(seed)
    out: dict = {"sequences": n_sequences, "frames": 0}
    stats = {
        m: {"times": [], "steps": 0, "quality": np.inf, "inverted": 0} for m in ("cold", "warm")
    }
    for _ in range(n_sequences):
        poses = sequence_poses(hand.skeleton, fraction, rng)
        out["frames"] += len(poses)
        previous = None
        for angles in poses:  # cold and warm frame by frame: the same machine state
            for mode, st in stats.items():
                t0 = time.perf_counter()
                pose = poser.pose(angles, check=False, start=previous if mode == "warm" else None)
                st["times"].append(time.perf_counter() - t0)
                assert poser.relaxer is not None
                st["steps"] += poser.relaxer.stats["iterations"]
                st["quality"] = min(st["quality"], pose.min_quality)
                st["inverted"] += bool(len(pose.inverted))
                if mode == "warm":
                    previous = pose
    for mode, st in stats.items():
        out[f"{mode}_mean_s"] = float(np.mean(st["times"]))
        out[f"{mode}_max_s"] = float(np.max(st["times"]))
        out[f"{mode}_steps"] = st["steps"]
        out[f"{mode}_min_quality"] = float(st["quality"])
        out[f"{mode}_inverted"] = st["inverted"]
    return out


def _describe(angles: dict[str, float], top: int = 3) -> str:
    """A pose in a few words: its largest angles (degrees)."""
    big = sorted(angles.items(), key=lambda kv: -abs(kv[1]))[:top]
    more = len([v for v in angles.values() if v != 0.0]) - len(big)
    return ", ".join(f"{k} {v:.0f}" for k, v in big) + (f" (+{more})" if more > 0 else "")


def run(quick: bool = False, out: str | Path | None = None) -> list[dict]:
    """Run the posing benchmark and write ``posing.{csv,md,png}``.

    Parameters
    ----------
    quick : bool
        The coarse hand and two fractions only: seconds.
    out : path, optional
        Results folder; ``benchmarks/results`` (``.../quick`` for quick runs) by default.

    Returns
    -------
    list of dict
        One row per resolution and fraction.
    """
    folder = results_dir(out, quick)
    info = machine_info()
    rows: list[dict] = []
    timing: list[dict] = []
    sequences: list[dict] = []
    for res in RESOLUTIONS[quick]:
        hand = load_hand(res)
        t0 = time.perf_counter()
        poser = HandPoser(hand)
        setup = time.perf_counter() - t0
        angles = {"index_mcp": 15.0, "index_pip": 20.0, "middle_mcp": 10.0, "thumb_cmc": 10.0}
        frame = measure(lambda p=poser, a=angles: p.pose(a, check=False), repeat=7, budget=5.0)
        poser.skin_points(angles)  # localise the skin once
        skin = measure(lambda p=poser, a=angles: p.skin_points(a), repeat=5, budget=2.0)
        nodes, ntets = hand.flesh.n_points, len(hand.flesh.cells["tetra"])
        timing.append(
            {
                "resolution": res,
                "nodes": nodes,
                "tets": ntets,
                "setup_s": setup,
                "pose_s": frame.best,
                "skin_s": skin.best,
                "goal": (
                    f"<= {GOAL_S} s: {'met' if frame.best <= GOAL_S else 'MISSED'}"
                    if res == "fine"
                    else ""
                ),
            }
        )
        print(
            f"[posing] {res}: set-up {setup:.2f} s, a frame {frame.best * 1e3:.1f} ms", flush=True
        )
        rest_q = float(tet_quality(hand.flesh.points, hand.flesh.cells["tetra"]).min())
        for f in FRACTIONS[quick]:
            row = {"resolution": res, "nodes": nodes, "tets": ntets, "fraction": f}
            row.update(sample_range(poser, f, N_RANDOM[quick]))
            row["rest_quality"] = rest_q
            rows.append(row)
            print(
                f"[posing] {res} {f:.2f} of limits: {row['inverted_poses']}/{row['poses']} "
                f"poses invert a tet, min quality {row['min_quality']}",
                flush=True,
            )
            seq = {"resolution": res, "fraction": f}
            seq.update(sample_sequences(poser, f, N_SEQUENCES[quick]))
            sequences.append(seq)
            print(
                f"[posing] {res} {f:.2f} of limits, {seq['frames']} frames of sequences: "
                f"cold {seq['cold_mean_s']:.3f} s a frame, warm {seq['warm_mean_s']:.3f} s",
                flush=True,
            )
    info["load average at end"] = load_average()
    write_csv(folder / "posing.csv", [{**r} for r in rows], CSV_KEYS)
    left = [
        {"resolution": r["resolution"], "fraction": r["fraction"], **u}
        for r in rows
        for u in r["unmended"]
    ]
    write_csv(folder / "posing_inverted.csv", left, [c.key for c in LEFT_COLUMNS])
    write_csv(folder / "posing_sequences.csv", sequences, SEQ_KEYS_CSV)
    _write_report(folder, info, rows, timing, quick, left, sequences)
    _plot(folder / "posing.png", rows)
    return rows
