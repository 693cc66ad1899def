"""What ``summary.json`` says: a frame's verdict and record, the whole file's JSON.

A frame's record (:func:`frame_entry`) holds its time, verdict, forces (contact, obstacle,
bone), contacts per pair, whether its free bodies are held, its Coulomb friction figures
(:func:`friction_entry`), largest von Mises stress per body, the iteration history, its
files and its timings. The grasp's own figures are computed here and passed in as the
record's extra items by the caller, which knows the bodies: the grip force
(:func:`grip_force`), the forces, contact area and peak pressure per hand part
(:func:`part_forces`) and the largest strain per body (:func:`max_strain`, against
:data:`SMALL_STRAIN`). With ``--least-grip`` the search's outcome is added at the top
level under ``"least_grip"`` (:func:`add_least_grip`). Everything but the ``"timings"``
keys and ``least_grip.seconds`` (seconds) and the versions is a function of the input, so
that two runs of one scene give equal summaries.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

import fem

from ..errors import OutputError
from ..solver.results import FrameResult, FrictionReport
from .plainjson import jsonable
from .staging import write_atomic

__all__ = [
    "SMALL_STRAIN",
    "add_least_grip",
    "frame_entry",
    "friction_entry",
    "grip_force",
    "max_strain",
    "part_forces",
    "pressure_over_area",
    "summary_text",
    "update_summary",
    "verdict",
]

#: The largest principal strain that small-strain linear elasticity describes well: beyond
#: it the model's forces and stresses are an extrapolation, and the run warns.
SMALL_STRAIN = 0.10


def verdict(result: FrameResult) -> dict[str, Any]:
    """The verdict of a frame: realistic when converged and no bone is over its limit.

    Parameters
    ----------
    result : FrameResult

    Returns
    -------
    dict
        ``{"realistic": bool, "reason": str}``; the reason names every bone over its
        limit with its force and limit, else the stop reason of a solve that did not
        converge, else ``"converged; every bone under its limit"`` (with ``"held"`` where a
        free body is held; without the bones where the scene has none).
    """
    if result.over_limit:
        parts = [
            f"bone {name} carries {float(f):.4g} N > its limit {float(lim):.4g} N"
            for name, (f, lim) in sorted(result.over_limit.items())
        ]
        return {"realistic": False, "reason": "; ".join(parts)}
    if not result.converged:
        return {"realistic": False, "reason": f"not converged: {result.stop_reason}"}
    parts = ["converged"] + (["held"] if result.held else [])
    if any(result.support_forces.values()):
        parts.append("every bone under its limit")
    return {"realistic": True, "reason": "; ".join(parts)}


def grip_force(result: FrameResult, hand: str | None) -> float:
    """The total grip force: the sum of the normal contact forces on the objects (N).

    Parameters
    ----------
    result : FrameResult
    hand : str or None
        The hand's body name: the contacts of the pairs it is in count. None (no hand):
        the contacts against the planes count.

    Returns
    -------
    float
        With a hand, the sum of its skin nodes' normal forces (``contact_fields``): the
        sum of the forces per part, so that the grip and the fingers are one sum (the
        rows' own forces, counted both ways across the skin, add up to about 1 % more
        where a node meets the ball as a slave and as a master's corner). Without, the
        sum of the magnitudes of the planes' contacts' normal forces (>= 0); for a ball
        squeezed between two plates, twice the squeeze.
    """
    fields = result.contact_fields.get(hand) if hand is not None else None
    if fields is not None and "normal_force" in fields:
        return float(np.sum(fields["normal_force"]))
    c = result.contacts
    if not c or not len(c.get("pair", ())):
        return 0.0
    pair = np.asarray(c["pair"]).astype(str)
    slave, _, master = np.char.partition(pair, "/").T
    if hand is not None:
        mine = (slave == hand) | (master == hand)
    else:
        mine = np.isin(master, list(result.obstacle_forces))
    return float(np.abs(np.asarray(c["force"], dtype=np.float64)[mine]).sum())


def pressure_over_area(normal_force: ArrayLike, areas: ArrayLike) -> NDArray[np.float64]:
    """Each node's normal contact force over its tributary area (Pa), 0 off contact."""
    fn, a = np.asarray(normal_force, dtype=np.float64), np.asarray(areas, dtype=np.float64)
    out = np.zeros(len(fn))
    touch = (fn > 0.0) & (a > 0.0)
    out[touch] = fn[touch] / a[touch]
    return out


def part_forces(
    fields: Mapping[str, ArrayLike] | None,
    parts: NDArray[np.int64],
    names: Sequence[str],
    areas: ArrayLike,
) -> dict[str, dict[str, float]]:
    """Normal and tangential totals, contact area and peak pressure per hand part.

    Parameters
    ----------
    fields : mapping or None
        The hand's nodal contact fields (:attr:`FrameResult.contact_fields`):
        ``normal_force`` ``(N,)`` and ``tangential_force`` ``(N, 3)``; None: no contact.
    parts : ndarray of int, shape (N,)
        The part of every node (:func:`contact.hand.fingers.node_parts`).
    names : sequence of str
        Part names by id (palm, thumb, index, middle, ring, little).
    areas : array_like, shape (N,)
        Tributary boundary area of every node (m^2).

    Returns
    -------
    dict of str to dict of str to float
        Part name -> ``normal`` (sum of the nodal normal force magnitudes, N),
        ``tangential`` (sum of the nodal tangential force magnitudes, N),
        ``contact_area`` (sum of the tributary areas of the nodes with a normal force,
        m^2), ``peak_pressure`` (largest :func:`pressure_over_area`, Pa) and
        ``max_cone_use`` (largest ``|t| / (mu n)`` of its contacts, 0 without friction).
    """
    n = len(parts)
    a = np.asarray(areas, dtype=np.float64)
    fn = np.zeros(n)
    ft = np.zeros(n)
    cone = np.zeros(n)
    if fields is not None:
        fn = np.asarray(fields["normal_force"], dtype=np.float64)
        ft = np.linalg.norm(np.asarray(fields["tangential_force"], dtype=np.float64), axis=1)
        if "cone_use" in fields:
            cone = np.asarray(fields["cone_use"], dtype=np.float64)
    touch = (fn > 0.0) & (a > 0.0)
    pressure = pressure_over_area(fn, a)
    out = {}
    for i, name in enumerate(names):
        own = parts == i
        out[str(name)] = {
            "normal": float(fn[own].sum()),
            "tangential": float(ft[own].sum()),
            "contact_area": float(a[own & touch].sum()),
            "peak_pressure": float(pressure[own].max(initial=0.0)),
            "max_cone_use": float(cone[own].max(initial=0.0)),
        }
    return out


def max_strain(
    mesh: fem.Mesh,
    u: ArrayLike,
    *,
    bbar: bool = True,
    nodal_pressure: bool = False,
    finite: bool = False,
) -> float:
    """The largest principal strain of a body, in magnitude, at any Gauss point.

    A ``finite`` (neo-Hookean) body's is its largest principal logarithmic strain
    ``|ln lambda|`` (:func:`fem.log_strain`), 0 for a rigid turn of any angle.

    Parameters
    ----------
    mesh : fem.Mesh
        The body's configuration the displacement starts from.
    u : array_like, shape (N, 3) or (3N,)
        Its displacement (m).
    bbar, nodal_pressure : bool
        As its stiffness was assembled (:func:`fem.gauss_strain`).

    Returns
    -------
    float
        ``max |eig(eps)|`` of the small strain tensor (dimensionless; 0.1 is 10 %).
    """
    if finite:
        logs = fem.log_strain(mesh, np.ravel(u))
        return float(max((np.abs(e).max(initial=0.0) for e in logs.values()), default=0.0))
    eps = fem.gauss_strain(mesh, np.ravel(u), bbar=bbar, nodal_pressure=nodal_pressure)
    peaks = [np.abs(np.linalg.eigvalsh(e.reshape(-1, 3, 3))).max(initial=0.0) for e in eps.values()]
    return float(max(peaks, default=0.0))


def _vector(v: ArrayLike) -> dict[str, Any]:
    a = np.asarray(v, dtype=np.float64).reshape(3)
    return {"force": jsonable(a), "magnitude": float(np.linalg.norm(a))}


def _history(result: FrameResult) -> list[dict[str, Any]]:
    return [
        {
            "iteration": int(r.iteration),
            "n_contacts": int(r.n_contacts),
            "added": int(r.added),
            "released": int(r.released),
            "max_change": float(r.max_change),
            "max_penetration": float(r.max_penetration),
            "total_force": jsonable(np.asarray(r.total_force, dtype=np.float64)),
            "normal_force": float(r.normal_force),
            "relaxation": float(r.relaxation),
            "max_support_force": float(r.max_support_force),
        }
        for r in result.history
    ]


def friction_entry(report: FrictionReport | None) -> dict[str, Any] | None:
    """The ``"friction"`` item of a frame's record: None where every pair is frictionless.

    Parameters
    ----------
    report : FrictionReport or None

    Returns
    -------
    dict or None
        ``iterations``, ``residual``, ``tolerance``, ``stick``, ``slip``, ``max_slip``
        (m), ``max_cone_use`` and ``tangential_force``: pair or plane name ->
        ``{"force": [x, y, z], "magnitude": float}`` (N), names sorted.
    """
    if report is None:
        return None
    return {
        "iterations": int(report.iterations),
        "residual": float(report.residual),
        "tolerance": float(report.tolerance),
        "stick": int(report.stick),
        "slip": int(report.slip),
        "max_slip": float(report.max_slip),
        "max_cone_use": float(report.max_cone_use),
        "tangential_force": {
            k: _vector(report.tangential_force[k]) for k in sorted(report.tangential_force)
        },
    }


def _bone_forces(result: FrameResult) -> dict[str, dict[str, Any]]:
    """Support forces keyed by group name (``body/group`` where a name repeats)."""
    counts: dict[str, int] = {}
    for groups in result.support_forces.values():
        for g in groups:
            counts[g] = counts.get(g, 0) + 1
    out = {}
    for body in sorted(result.support_forces):
        for g in sorted(result.support_forces[body]):
            key = g if counts[g] == 1 else f"{body}/{g}"
            out[key] = {"body": body, **_vector(result.support_forces[body][g])}
    return out


def _slip(result: FrameResult) -> dict[str, Any] | None:
    """A frictional frame's slip: the largest slip increment (m) and, not held, which way.

    ``motion`` (``"slides"`` or ``"turns"``), ``direction`` (the way it slides, or the
    axis it turns about), ``not_carried`` and ``available`` (N where it slides, N m where
    it turns) where friction did not hold a free body (:attr:`FrameResult.slip`), else
    None; ``largest_increment`` the largest slip of a contact in the frame. None without
    friction.
    """
    if result.friction is None and result.slip is None:
        return None
    out: dict[str, Any] = {
        "motion": None, "direction": None, "not_carried": None, "available": None
    }
    if result.slip is not None:
        out.update({k: result.slip[k] for k in ("direction", "not_carried", "available")})
        out["motion"] = "turns" if result.slip.get("turns") else "slides"
    out["largest_increment"] = (
        None if result.friction is None else float(result.friction.max_slip)
    )
    return out


def frame_entry(
    index: int,
    time: float,
    result: FrameResult,
    *,
    vtu: Mapping[str, str],
    max_von_mises: Mapping[str, float],
    picture: str | None,
    status_picture: str | None = None,
    pressure_picture: str | None = None,
    extra: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """The ``summary.json`` record of one frame.

    Parameters
    ----------
    index : int
        Frame number.
    time : float
        Frame time.
    result : FrameResult
        The frame's solve.
    vtu : mapping of str to str
        Body name -> its ``.vtu`` file, relative to the results folder.
    max_von_mises : mapping of str to float
        Body name -> its largest cell-average von Mises stress (Pa).
    picture : str or None
        The frame's picture, relative to the results folder, or None without pictures.
    status_picture : str or None
        Its stick and slip picture, likewise, or None (no pictures or no friction).
    pressure_picture : str or None
        Its held body's contact pressure picture, likewise, or None (no pictures or no
        contact on it).
    extra : mapping, optional
        More JSON-able items (a key of the record may not be repeated).

    Returns
    -------
    dict
        The record, as plain JSON types.

    Raises
    ------
    ValueError
        When ``extra`` repeats a key of the record.
    """
    pairs = result.contacts.get("pair") if result.contacts else None
    per_pair: dict[str, int] = {}
    if pairs is not None:
        names, counts = np.unique(np.asarray(pairs).astype(str), return_counts=True)
        per_pair = {str(n): int(c) for n, c in zip(names, counts, strict=True)}
    entry: dict[str, Any] = {
        "index": index,
        "time": time,
        "converged": bool(result.converged),
        "stop_reason": str(result.stop_reason),
        "algorithm": str(result.algorithm),
        "iterations": int(result.iterations),
        "verdict": verdict(result),
        "max_penetration": float(result.max_penetration),
        "penetration_ratio": float(result.penetration_ratio),
        "separation_ratio": float(result.separation_ratio),
        "contact_force": {
            b: _vector(np.asarray(result.contact_force[b]).sum(axis=0))
            for b in sorted(result.contact_force)
        },
        "obstacle_forces": {
            p: _vector(result.obstacle_forces[p]) for p in sorted(result.obstacle_forces)
        },
        "bone_forces": _bone_forces(result),
        "over_limit": {
            b: {"force": float(f), "limit": float(lim)}
            for b, (f, lim) in sorted(result.over_limit.items())
        },
        "contacts": {"total": int(sum(per_pair.values())), "per_pair": per_pair},
        "held": None if result.held is None else bool(result.held),
        "slip": _slip(result),
        "plane_positions": {
            p: [float(x) for x in result.plane_positions[p]]
            for p in sorted(result.plane_positions)
        },
        "friction": friction_entry(result.friction),
        "max_von_mises": dict(max_von_mises),
        "history": _history(result),
        "files": {
            "vtu": dict(vtu),
            "picture": picture,
            "status_picture": status_picture,
            "pressure_picture": pressure_picture,
        },
        "timings": {k: float(v) for k, v in sorted(result.timings.items())},
    }
    if extra:
        clash = sorted(set(extra) & set(entry))
        if clash:
            raise ValueError(f"extra repeats keys of the frame entry: {clash}")
        entry.update(jsonable(dict(extra)))
    return jsonable(entry)


def summary_text(
    *,
    scene: Mapping[str, Any],
    versions: Mapping[str, str],
    entries: Sequence[Mapping[str, Any]],
    pictures: str,
    stress_components: Sequence[str],
    files: Mapping[str, Any],
    timings: Mapping[str, float],
) -> str:
    """The text of ``summary.json``: the scene, versions, frame records and verdicts.

    Parameters
    ----------
    scene : mapping
        The scene with its defaults filled.
    versions : mapping of str to str
        Package versions (:func:`versions`).
    entries : sequence of dict
        The frame records (:func:`frame_entry`), in frame order.
    pictures : str
        ``"written"``, ``"off"``, or why they were skipped.
    stress_components : sequence of str
        Order of the six components of the VTU ``stress`` array.
    files : mapping
        The folder's series and pictures, relative to the folder.
    timings : mapping of str to float
        Seconds spent on the pictures and on finishing the folder.

    Returns
    -------
    str
        Indented JSON with a final newline; no NaN or infinity.
    """
    summary = {
        "scene": jsonable(scene),
        "versions": jsonable(versions),
        "frames": list(entries),
        "all_converged": all(e["converged"] for e in entries),
        "all_realistic": all(e["verdict"]["realistic"] for e in entries),
        "pictures": pictures,
        "stress_components": list(stress_components),
        "files": files,
        "timings": dict(timings),
    }
    return json.dumps(summary, indent=2, allow_nan=False) + "\n"


def add_least_grip(path: str | Path, record: Mapping[str, Any]) -> None:
    """Add the least-grip search's outcome to a written ``summary.json`` (top-level key).

    Parameters
    ----------
    path : str or Path
        The ``summary.json`` a finished results folder holds.
    record : mapping
        ``scale``, ``forces`` (name -> N), ``margin``, ``steps``, ``solves``, ``seconds``,
        ``bracket`` ``[lo, hi]`` and what else the search reports
        (:meth:`contact.holding.leastgrip.LeastGrip.record`); JSON-able.

    Raises
    ------
    OutputError
        When the file cannot be read or written back.
    """
    update_summary(path, {"least_grip": record}, "the least grip")


def update_summary(path: str | Path, items: Mapping[str, Any], what: str) -> None:
    """Set top-level ``items`` of a written ``summary.json``, the file replaced atomically.

    Raises
    ------
    OutputError
        When the file cannot be read or written back (naming ``what`` was being added).
    """
    path = Path(path)
    try:
        summary = json.loads(path.read_text())
        summary.update(jsonable(dict(items)))
        write_atomic(path, (json.dumps(summary, indent=2, allow_nan=False) + "\n").encode())
    except (OSError, ValueError) as exc:
        raise OutputError(f"cannot add {what} to {path}: {exc}") from None
