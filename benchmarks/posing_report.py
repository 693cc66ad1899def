"""The posing study's report: its tables' columns, the markdown and the plot."""

from __future__ import annotations

from pathlib import Path

from ._common import Column, markdown_table, write_markdown

__all__ = [
    "COLUMNS",
    "DIAG_COLUMNS",
    "LEFT_COLUMNS",
    "SEQ_COLUMNS",
    "SEQ_FPS",
    "SEQ_KEYS",
    "SEQ_KEYS_CSV",
    "TIME_COLUMNS",
]


#: Frames a second of the keyframed sequences (keys one second apart).
SEQ_FPS = 24
#: Random keys after the rest pose in each sequence.
SEQ_KEYS = 2


COLUMNS = (
    Column("resolution", "mesh"),
    Column("fraction", "fraction of limits", ".2f"),
    Column("poses", "poses"),
    Column("inverted_poses", "poses inverting a tet"),
    Column("bone_only_poses", "of which only bone-bone tets"),
    Column("min_quality", "min quality (valid poses)", ".4f"),
    Column("mean_s", "pose a frame, mean (s)", ".3f"),
    Column("max_s", "pose a frame, max (s)", ".3f"),
    Column("blamed", "joints blamed"),
)
DIAG_COLUMNS = (
    Column("resolution", "mesh"),
    Column("fraction", "fraction of limits", ".2f"),
    Column("jld_inverted_poses", "poses the JLD mapping alone inverts"),
    Column("jld_where", "their inverted tets by joint area (share)"),
    Column("jld_kinds", "skin / bone / inner tets"),
)
LEFT_COLUMNS = (
    Column("resolution", "mesh"),
    Column("fraction", "fraction of limits", ".2f"),
    Column("pose", "pose (largest angles, deg)"),
    Column("joint", "joint"),
    Column("element", "element"),
    Column("bone_nodes", "its nodes on a bone"),
    Column("quality", "its quality", ".4f"),
    Column("inverted", "tets inverted"),
)
SEQ_COLUMNS = (
    Column("resolution", "mesh"),
    Column("fraction", "fraction of limits", ".2f"),
    Column("frames", "frames"),
    Column("cold_mean_s", "cold: mean (s)", ".3f"),
    Column("cold_max_s", "cold: max (s)", ".3f"),
    Column("warm_mean_s", "warm: mean (s)", ".3f"),
    Column("warm_max_s", "warm: max (s)", ".3f"),
    Column("cold_steps", "Newton steps cold"),
    Column("warm_steps", "Newton steps warm"),
    Column("cold_min_quality", "min quality cold", ".4f"),
    Column("warm_min_quality", "min quality warm", ".4f"),
    Column("cold_inverted", "frames inverting a tet, cold"),
    Column("warm_inverted", "frames inverting a tet, warm"),
)
#: The sequence study's CSV: the table's columns and the sequences counted.
SEQ_KEYS_CSV = [
    *(c.key for c in SEQ_COLUMNS[:2]),
    "sequences",
    *(c.key for c in SEQ_COLUMNS[2:]),
]
TIME_COLUMNS = (
    Column("resolution", "mesh"),
    Column("nodes", "nodes", ","),
    Column("tets", "tets", ","),
    Column("setup_s", "set-up (s)", ".3f"),
    Column("pose_s", "pose a frame (s)", ".4f"),
    Column("skin_s", "map the skin (s)", ".4f"),
    Column("goal", "goal"),
)


def _write_report(
    folder: Path, info: dict, rows: list, timing: list, quick: bool, left: list, sequences: list
) -> None:
    rest = {r["resolution"]: r["rest_quality"] for r in rows}
    sections = [
        (
            "Time per frame" + (" (quick)" if quick else ""),
            markdown_table(timing, TIME_COLUMNS)
            + "\n\nA frame: the JLD mapping of every flesh node, the bone transforms and the "
            "signed volume of every tetrahedron (best of several). The set-up localises "
            "the nodes once per hand.",
        ),
        (
            "Range of motion",
            markdown_table(rows, COLUMNS)
            + "\n\nEach fraction: every angle alone at that fraction of each of its limits, "
            "and random poses with every angle within that fraction of its limits. Rest "
            "quality: "
            + ", ".join(f"{k} {v:.4f}" for k, v in rest.items())
            + ". A frame: the JLD mapping, then the relaxation of the free nodes around "
            "the tetrahedra it degrades (contact.hand.relax.FleshRelaxer, a projected Newton "
            "method on an untangling energy; each connected part of the patch starts from "
            "the lower-energy of the mapping and the harmonic fill of its folds); the time "
            "grows with the degraded region (deep flexions); it stops when its energy "
            "stalls, and a tetrahedron it leaves "
            "inverted restarts its neighbourhood from a nearby bone's rigid motion "
            "(untangled on its volumes first). The joints are open (no "
            "tetrahedron tied to both bones of a joint), every joint keeps its bones at "
            "least 1 mm apart over its range (contact.hand.bones.joint_clearance) and, on a "
            "mesh built or reopened since contact.hand.jointgap.split_joint_gaps (the fine "
            "one), no free node is tied by its edges to two bones.",
        ),
        (
            "Keyframed sequences: cold and warm-started frames",
            markdown_table(sequences, SEQ_COLUMNS)
            + f"\n\nSequences from rest through {SEQ_KEYS} random keys (every angle within "
            f"the fraction of its limits, one key a second, Kochanek-Bartels), "
            f"{SEQ_FPS} frames a second. Cold: each frame posed on its own, as above. "
            "Warm: from the previous frame's pose (HandPoser.pose with start): its "
            "relaxer correction, turned with each node's segment, added to the new "
            "mapping is one more start of each "
            "degraded part, competing on energy with the mapping and its fill; where it "
            "is the lowest, it is mended by Newton's method around its degraded "
            "tetrahedra alone (two rings; from a fresh harmonic fill there too where "
            "that leaves one below half the stop floor), and a part left inverted goes "
            "to the next pass, wider around what is still inverted "
            "(FleshRelaxer._mend_locally).",
        ),
        (
            "Why poses would invert: the JLD mapping alone",
            markdown_table(rows, DIAG_COLUMNS)
            + "\n\nThe same poses mapped by the JLD mapping alone (no relaxation). A "
            "tetrahedron's joint area: the zone joint of most of its nodes (the joint "
            "whose proximal or distal area holds them; buffer: rigid with a segment). "
            "Kinds: with a node on the outer skin; else with a node fixed to a bone; "
            "else inner.",
        ),
        (
            "Poses left inverted",
            (markdown_table(left, LEFT_COLUMNS) if left else "None.")
            + "\n\nEvery pose the relaxer could not mend (posing it with the default "
            "check raises contact.PoseError naming the same joint and element): its "
            "largest angles, the joint blamed (contact.HandPoser.culprit), the first "
            "inverted tetrahedron, its nodes fixed to a bone and its quality, and how many "
            "tetrahedra are inverted. Also in posing_inverted.csv.",
        ),
    ]
    write_markdown(folder / "posing.md", "Posing the hand: time and quality", info, sections)


def _plot(path: Path, rows: list[dict]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    for res in dict.fromkeys(r["resolution"] for r in rows):
        rr = [r for r in rows if r["resolution"] == res]
        f = [r["fraction"] for r in rr]
        a1.plot(f, [r["inverted_poses"] / r["poses"] for r in rr], "o-", label=res)
        q = [(r["fraction"], r["min_quality"]) for r in rr if r["min_quality"] is not None]
        if q:
            a2.plot(*zip(*q), "o-", label=res)
    a1.set_xlabel("fraction of the joint limits")
    a1.set_ylabel("share of poses inverting a tet")
    a2.set_xlabel("fraction of the joint limits")
    a2.set_ylabel("min tet quality (valid poses)")
    for a in (a1, a2):
        a.grid(True, alpha=0.3)
        a.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
