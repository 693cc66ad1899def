"""Rebuild the shipped hand: ``python -m meshes.build [--resolution coarse fine]``.

From ``meshes/hand/rig.toml`` it builds, for each resolution, the skin (metaballs), the bone
surfaces and the flesh tetrahedra, checks them, writes ``skin_<res>.vtp``,
``bones_<res>.vtp`` and ``flesh_<res>.vtu``, merges the key numbers and mesh quality into
``quality.json`` and renders ``rest.png`` and ``fist.png``. fTetWild is not deterministic:
a rebuild gives a different (equally valid) mesh.
"""

from __future__ import annotations

import argparse
import json
import logging
import time
from pathlib import Path

from contact.errors import RigError
from contact.hand.bones import joint_clearance
from contact.hand.build import COARSE, FINE, FINGERTIPS, build_hand, hand_report, write_hand
from contact.hand.checks import finger_widths
from contact.hand.flesh import joint_pairs, open_joints
from contact.hand.jointgap import split_joint_gaps
from contact.hand.metaballs import skin_surface
from contact.hand.plot import SIDE_VIEW, render_hand
from contact.hand.shipped import HAND_DIR, RESOLUTIONS, load_hand
from contact.hand.skeleton import Skeleton, load_skeleton

log = logging.getLogger("meshes.build")

#: The fist of ``fist.png`` (degrees).
FIST = {
    **{f"{f}_mcp": 85.0 for f in ("index", "middle", "ring", "little")},
    **{f"{f}_pip": 100.0 for f in ("index", "middle", "ring", "little")},
    **{f"{f}_dip": 60.0 for f in ("index", "middle", "ring", "little")},
    "ring_cmc": 8.0,
    "little_cmc": 15.0,
    "thumb_cmc": 30.0,
    "thumb_mcp": 40.0,
    "thumb_ip": 50.0,
}


def _rig_numbers(directory: Path) -> dict:
    """Hand length, finger widths and volume of the rig's skin at 1 mm."""
    skeleton = load_skeleton(directory / "rig.toml")
    skin = skin_surface(skeleton, resolution=0.001)
    lo, hi = skin.bounds[2], skin.bounds[3]
    return {
        "wrist_crease_to_middle_tip_cm": round(hi * 100, 2),
        "wrist_stub_cm": round(-lo * 100, 2),
        "finger_widths_mm": {
            k: round(v * 1e3, 1) for k, v in finger_widths(skeleton, skin).items()
        },
        "skin_volume_cm3": round(skin.volume * 1e6, 1),
        "bone_lengths_mm": {k: round(v * 1e3, 1) for k, v in skeleton.bone_lengths().items()},
    }


def check_clearance(skeleton: Skeleton) -> dict[str, float]:
    """Smallest bone gap of every joint over its range of motion (mm).

    Raises :class:`RigError` below the rig's ``flesh.gap`` (see
    :func:`contact.hand.bones.joint_clearance`).
    """
    out = {}
    gap = skeleton.spec.gap
    for joint in skeleton.joint_names:
        clearance, at = joint_clearance(skeleton, joint, steps=7, edge=0.0008)
        out[joint] = round(clearance * 1e3, 2)
        if clearance < 0.98 * gap:
            raise RigError(
                f"joint {joint}: its bones come {clearance * 1e3:.2f} mm apart at {at}, the "
                f"rig asks for {gap * 1e3:.2f} mm over the whole range of motion"
            )
    return out


def pictures(directory: Path) -> None:
    """Render ``rest.png`` (fine skin and bones) and ``fist.png`` (bones posed by FK)."""
    hand = load_hand("fine" if (directory / "flesh_fine.vtu").is_file() else "coarse", directory)
    render_hand(
        directory / "rest.png", hand.bones, hand.skin, title="rest: skin (35 % opaque) and bones"
    )
    angles = FIST
    skin = skin_surface(hand.skeleton, angles, resolution=0.0015)
    render_hand(
        directory / "fist.png",
        hand.bones,
        skin,
        hand.skeleton.forward_kinematics(angles),
        camera=SIDE_VIEW,
        title="fist: bones by forward kinematics, metaballs posed with them",
    )


def reopen(resolution: str, directory: Path) -> dict:
    """Open the joints and split the joint gaps of a shipped flesh file (no re-meshing).

    For files meshed before :func:`contact.hand.flesh.open_joints` dropped every
    tetrahedron tied to both bones of a joint, or before
    :func:`contact.hand.jointgap.split_joint_gaps` left two layers of free nodes in every gap
    between bones; rewrites the file and returns its new report.
    """
    import dataclasses

    hand = load_hand(resolution, directory)
    flesh, bone_id, cell_bone = open_joints(
        hand.flesh, hand.bone_id, hand.cell_bone, joint_pairs(hand.skeleton)
    )
    flesh, bone_id, cell_bone = split_joint_gaps(flesh, bone_id, cell_bone)
    write_hand(
        dataclasses.replace(hand, flesh=flesh, bone_id=bone_id, cell_bone=cell_bone), directory
    )
    return hand_report(load_hand(resolution, directory))


def main(argv: list[str] | None = None) -> None:
    """Command-line entry point."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolution", nargs="+", choices=RESOLUTIONS, default=list(RESOLUTIONS))
    parser.add_argument("--dir", type=Path, default=HAND_DIR, help="folder with rig.toml")
    parser.add_argument("--no-pictures", action="store_true")
    parser.add_argument(
        "--reopen",
        action="store_true",
        help="only open the joints and split the joint gaps of the shipped flesh files",
    )
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s: %(message)s")
    if args.reopen:
        report_path = args.dir / "quality.json"
        report = json.loads(report_path.read_text())
        for res in args.resolution:
            entry = reopen(res, args.dir)
            report[res].update({k: entry[k] for k in ("bones", "flesh")})
            log.info("%s reopened: %s", res, json.dumps(entry["flesh"]))
        report_path.write_text(json.dumps(report, indent=2) + "\n")
        return
    skeleton = load_skeleton(args.dir / "rig.toml")
    report_path = args.dir / "quality.json"
    report = json.loads(report_path.read_text()) if report_path.is_file() else {}
    report["rig"] = _rig_numbers(args.dir)
    report["rig"]["joint_clearance_mm"] = check_clearance(skeleton)
    for res in (r for r in (COARSE, FINE, FINGERTIPS) if r.name in args.resolution):
        t0 = time.perf_counter()
        hand, timings = build_hand(skeleton, res)
        write_hand(hand, args.dir)
        entry = hand_report(load_hand(res.name, args.dir))  # what was written
        entry["seconds"] = {k: round(v, 1) for k, v in timings.items()}
        entry["seconds"]["total"] = round(time.perf_counter() - t0, 1)
        entry["settings"] = {
            "skin_grid_m": res.skin_grid,
            "skin_reduction": res.skin_reduction,
            "bone_edge_m": res.bone_edge,
            "tet_edge_m": res.tet_edge,
            "tetwild": res.tetwild,
            "tip_edge_m": res.tip_edge,
        }
        report[res.name] = entry
        report_path.write_text(json.dumps(report, indent=2) + "\n")
        log.info("%s: %s", res.name, json.dumps(entry["flesh"]))
    if not args.no_pictures:
        pictures(args.dir)


if __name__ == "__main__":
    main()
