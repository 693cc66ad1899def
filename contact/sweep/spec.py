"""Reading a sweep file (``SWEEP.toml``) and expanding it into scene files.

A sweep is a base scene (``[sweep] scene``, relative to the sweep file) and the keys to
vary (``[vary]``), each a dotted path into the scene file's TOML (``ball.material.E``,
``"plane[0].friction"``, ``"hand.auto_flexion[0].force"``) with a list of values or a
range ``{ start, stop, num }`` (``numpy.linspace``), combined as a product or zipped
(``[sweep] mode``). ``docs/sweep.md`` documents every key.

A sweep has at most :data:`MAX_RUNS` runs (the run folders are ``runs/0000`` to
``runs/9999``): the count is worked out from the lists' lengths and the ranges' ``num``
before any list or scene is built, so that a huge sweep is refused at once.

Reading is as strict as a scene's: an unknown key, a wrong type, an empty list or a key
path that is neither in the base scene's TOML document nor in its echo (the scene's keys
with their defaults, :meth:`contact.scene.spec.Scene.echo`) raises :class:`SweepError`
with one line naming the file and the key. Each generated scene is written as TOML with
its file paths made absolute (they were relative to the base scene's folder) and is
loaded with :func:`contact.scene.read.load_scene` before anything runs.
"""

from __future__ import annotations

import copy
import datetime
import itertools
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._toml import MISSING, TomlReader, tomllib
from ..errors import ContactError
from ..scene.read import load_scene

__all__ = [
    "MAX_RUNS", "METRICS", "Sweep", "SweepError", "SweepRun", "dump_toml", "expand", "load_sweep",
    "parse_path", "run_count",
]  # fmt: skip

#: The most runs a sweep may have: its run folders are named by four digits.
MAX_RUNS = 10_000
#: The table's per-run figures that ``[plot] y`` may name (see docs/sweep.md).
METRICS = (
    "grip_force", "max_bone_force", "iterations", "seconds", "least_grip_scale",
    "exit_status", "converged", "realistic", "held",
)  # fmt: skip
_SWEEP = ("scene", "mode", "pictures", "least_grip", "directory")
_RANGE = {"start", "stop", "num"}
#: Scene keys holding a file or folder path, relative to the scene file's folder.
_PATH_KEYS = (("ball", "mesh"), ("hand", "rig"), ("hand", "directory"))
_SEGMENT = re.compile(r"^([A-Za-z_][A-Za-z0-9_-]*)((?:\[\d+\])*)$")
_BARE = re.compile(r"^[A-Za-z0-9_-]+$")


class SweepError(ContactError):
    """A bad sweep file: one line naming the file and the key."""


class _Reader(TomlReader):
    error = SweepError


@dataclass(frozen=True)
class SweepRun:
    """One run of a sweep: its id, its varied values and its scene's TOML text."""

    index: int
    values: dict[str, Any]
    text: str

    @property
    def name(self) -> str:
        """The run's folder name, ``NNNN``."""
        return f"{self.index:04d}"


@dataclass(frozen=True)
class Sweep:
    """A validated sweep file (see :func:`load_sweep`)."""

    path: Path
    scene: Path
    vary: dict[str, list[Any]]
    mode: str = "product"
    pictures: bool = False
    least_grip: bool = False
    directory: Path | None = None
    plot_y: str = "grip_force"
    base: dict = field(default_factory=dict, repr=False)

    @property
    def keys(self) -> list[str]:
        """The varied key paths, in the file's order."""
        return list(self.vary)


def parse_path(key: str) -> list[str | int]:
    """``"plane[0].friction"`` -> ``["plane", 0, "friction"]``.

    Raises
    ------
    ValueError
        On a malformed path.
    """
    out: list[str | int] = []
    for seg in key.split("."):
        m = _SEGMENT.match(seg)
        if not m:
            raise ValueError(f"malformed key path segment {seg!r}")
        out.append(m.group(1))
        out.extend(int(i) for i in re.findall(r"\[(\d+)\]", m.group(2)))
    return out


def _walk(doc: Any, steps: list[str | int]) -> bool:
    """Whether ``steps`` leads somewhere inside ``doc`` (dicts and lists)."""
    for s in steps:
        if isinstance(s, int):
            if not isinstance(doc, list) or s >= len(doc):
                return False
        elif not isinstance(doc, dict) or s not in doc:
            return False
        doc = doc[s]
    return True


def _settable(doc: dict, steps: list[str | int]) -> bool:
    """Whether :func:`_set` can set ``steps`` in ``doc``: tables on the way, list items there."""
    for s in steps[:-1]:
        if isinstance(s, str) and isinstance(doc, dict) and s not in doc:
            doc = {}
        elif isinstance(s, int) and isinstance(doc, list) and s < len(doc):
            doc = doc[s]
        elif isinstance(s, str) and isinstance(doc, dict):
            doc = doc[s]
        else:
            return False
    last = steps[-1]
    return isinstance(doc, dict) if isinstance(last, str) else (
        isinstance(doc, list) and last < len(doc))  # fmt: skip


def run_count(vary: dict[str, list[Any]], mode: str) -> int:
    """The number of runs: the product of the lists' lengths, or their common length (zip)."""
    lengths = [len(v) for v in vary.values()]
    return math.prod(lengths) if mode == "product" else min(lengths, default=0)


def _set(doc: dict, steps: list[str | int], value: Any) -> None:
    """Set ``value`` at ``steps``, creating the missing tables (never list items)."""
    for s in steps[:-1]:
        if isinstance(s, str) and s not in doc:
            doc[s] = {}
        doc = doc[s]
    doc[steps[-1]] = value


def _flatten(table: dict, prefix: str = "") -> dict[str, Any]:
    """Dotted TOML keys parse as nested tables: back to ``{"a.b.c": leaf}``."""
    out: dict[str, Any] = {}
    for k, v in table.items():
        key = f"{prefix}.{k}" if prefix else k
        if isinstance(v, dict) and not (set(v) & _RANGE):
            out.update(_flatten(v, key))
        else:
            out[key] = v
    return out


def _values(r: _Reader, key: str, v: Any) -> list[Any]:
    """A key's values: a non-empty list, or ``{start, stop, num}`` as a linspace."""
    path = f"vary.{key}"
    if isinstance(v, dict):
        v = r.table(v, path, required=("start", "stop", "num"))
        start = r.number(v["start"], f"{path}.start")
        stop = r.number(v["stop"], f"{path}.stop")
        num = r.integer(v["num"], f"{path}.num", minimum=1)
        if num > MAX_RUNS:
            raise r.fail(f"{path}.num", num, f"past the bound of {MAX_RUNS:,} runs a sweep")
        return [float(x) for x in np.linspace(start, stop, num)]
    if not isinstance(v, list):
        raise r.fail(path, v, "must be a list of values or a table { start, stop, num }")
    if not v:
        raise r.fail(path, v, "empty: give at least one value")
    return list(v)


def load_sweep(path: str | Path) -> Sweep:
    """Read and check a sweep file; the base scene is loaded and its key paths checked.

    Raises
    ------
    SweepError
        One line naming the file and the key.
    """
    p = Path(path)
    r = _Reader(p.name)
    try:
        data = tomllib.loads(p.read_text())
    except OSError as exc:
        raise SweepError(f"{p}: cannot read: {exc.strerror or exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise SweepError(f"{p.name}: not valid TOML: {exc}") from None
    top = r.table(data, "", required=("sweep", "vary"), optional=("plot",))
    sw = r.table(top["sweep"], "sweep", required=("scene",), optional=_SWEEP[1:])
    for k in ("scene", "directory"):  # a NUL is no path: the OS would refuse it
        if isinstance(sw.get(k), str) and "\x00" in sw[k]:
            raise r.fail(f"sweep.{k}", sw[k], "a path may not hold a NUL character")
    scene = r.file(sw["scene"], "sweep.scene", p.resolve().parent)
    mode = r.string(sw.get("mode", "product"), "sweep.mode", ("product", "zip"))
    pictures = r.boolean(sw.get("pictures", False), "sweep.pictures")
    least = r.boolean(sw.get("least_grip", False), "sweep.least_grip")
    directory = Path(r.string(sw["directory"], "sweep.directory")) if "directory" in sw else None
    plot = r.table(top.get("plot", {}), "plot", optional=("y",))
    plot_y = r.string(plot.get("y", "grip_force"), "plot.y", METRICS)
    if not isinstance(top["vary"], dict) or not top["vary"]:
        raise r.fail("vary", top["vary"], "give at least one key path to vary")
    try:
        base_scene = load_scene(scene)
    except (ContactError, ValueError, OSError) as exc:
        raise SweepError(f"{p.name}: sweep.scene: {exc}") from None
    base = tomllib.loads(scene.read_text())
    echo = base_scene.echo()
    vary: dict[str, list[Any]] = {}
    for key, v in _flatten(top["vary"]).items():
        try:
            steps = parse_path(key)
        except ValueError as exc:
            raise r.fail(f"vary.{key}", MISSING, str(exc)) from None
        if not (_walk(base, steps) or _walk(echo, steps)) or not _settable(base, steps):
            raise r.fail(f"vary.{key}", MISSING, f"no key {key} in the scene {scene.name}")
        vary[key] = _values(r, key, v)
    if not vary:  # only empty tables under [vary]
        raise r.fail("vary", top["vary"], "give at least one key path to vary")
    if mode == "zip" and len({len(v) for v in vary.values()}) > 1:
        lengths = ", ".join(f"{k}: {len(v)}" for k, v in vary.items())
        raise r.fail("sweep.mode", mode, f"zip needs lists of one length ({lengths})")
    count = run_count(vary, mode)
    if count > MAX_RUNS:
        sizes = " x ".join(str(len(v)) for v in vary.values())
        raise r.fail("vary", MISSING, f"{count:,} runs ({sizes}): past the bound of "
                     f"{MAX_RUNS:,} runs a sweep")  # fmt: skip
    return Sweep(p, scene, vary, mode, pictures, least, directory, plot_y, base)


def _absolute(doc: dict, folder: Path) -> None:
    """Make the scene's file paths absolute: they were relative to ``folder``."""
    objects = doc.get("object")
    tables = [(doc.get(table), key) for table, key in _PATH_KEYS]
    tables += [(t, "mesh") for t in objects] if isinstance(objects, list) else []
    for t, key in tables:
        if isinstance(t, dict) and isinstance(t.get(key), str) and "\x00" not in t[key]:
            t[key] = str((folder / Path(t[key]).expanduser()).resolve())


def expand(sweep: Sweep, results: Path | None = None) -> list[SweepRun]:
    """The sweep's runs: each scene's TOML text with its values set.

    Parameters
    ----------
    sweep : Sweep
    results : Path, optional
        Written as each scene's ``output.directory`` (``NNNN/results`` appended).

    Returns
    -------
    list of SweepRun
        In order: the product's (last key fastest) or the zip's.
    """
    keys = sweep.keys
    lists = [sweep.vary[k] for k in keys]
    combos = itertools.product(*lists) if sweep.mode == "product" else zip(*lists)
    runs = []
    for i, combo in enumerate(combos):
        doc = copy.deepcopy(sweep.base)
        for k, v in zip(keys, combo):
            _set(doc, parse_path(k), v)
        _absolute(doc, sweep.scene.resolve().parent)
        if results is not None:
            where = (results / f"{i:04d}" / "results").resolve()
            doc.setdefault("output", {})["directory"] = str(where)
        runs.append(SweepRun(i, dict(zip(keys, combo)), dump_toml(doc)))
    return runs


def _key(k: str) -> str:
    return k if _BARE.match(k) else json.dumps(k)


def _value(v: Any) -> str:
    """A TOML inline value."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + " }"
    if isinstance(v, (datetime.date, datetime.time)):  # TOML's dates and times, bare
        return v.isoformat()
    raise TypeError(f"cannot write {type(v).__name__} as TOML")


def dump_toml(doc: dict) -> str:
    """A parsed TOML document written back: top tables as ``[t]``, lists of tables ``[[t]]``.

    Deeper tables are inline; ``tomllib.loads(dump_toml(d)) == d``.
    """
    head, body = [], []
    for k, v in doc.items():
        if isinstance(v, dict):
            body.append(f"\n[{_key(k)}]")
            body.extend(f"{_key(kk)} = {_value(vv)}" for kk, vv in v.items())
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            for item in v:
                body.append(f"\n[[{_key(k)}]]")
                body.extend(f"{_key(kk)} = {_value(vv)}" for kk, vv in item.items())
        else:
            head.append(f"{_key(k)} = {_value(v)}")
    return "\n".join(head + body).lstrip("\n") + "\n"
