"""Fuzz of the scene loader: mutated valid scenes either load or raise one-line SceneError.

A seeded generator starts from the hand-free example scenes and a small scene that uses
most keys, and mutates values (types, signs, huge and tiny numbers, infinities, empty
lists and strings), removes keys, adds unknown ones and puts scalars where tables go.
Every case must load, or raise :class:`SceneError` with one line (what the CLI prints
with exit status 2), never another exception, and within a second.
"""

from __future__ import annotations

import copy
import json
import math
import random
import time
from pathlib import Path
from typing import Any

import pytest

from contact._toml import tomllib
from contact.scene import SceneError, load_scene

ROOT = Path(__file__).resolve().parents[2]
HAND_FREE = ("hertz_plates.toml", "pads.toml")

RICH = """\
[scene]
name = "rich"
gravity = [0.0, 0.0, -9.81]

[ball]
radius = 0.02
kind = "hollow"
thickness = 0.004
pressure = 1.0e4
element = "hex"
mesh_size = 0.006
center = [0.0, 0.0, 0.02]
nodal_pressure = false
friction = 0.3
load = [[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], [1.0, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0]]
material = { E = 1.0e6, nu = 0.4, density = 1000.0 }

[[plane]]
name = "table"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
friction = 0.5

[[plane]]
name = "plate"
point = [0.0, 0.0, 0.04]
normal = [0.0, 0.0, -1.0]
offsets = [[0.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, -0.001]]

[frames]
count = 3

[solver]
algorithm = "contact-space"
max_iterations = 20
tolerance = 1.0e-4
substeps = 2

[output]
pictures = false
gif = false
window_size = [320, 240]
"""

CASES = 300
SEED = 20261126
ODD = [
    0, -1, 1, 2, -0.5, 0.0, -0.0, 1e308, -1e308, 1e-300, -1e-300, 1e-6, 1e-4, 1e9,
    math.inf, -math.inf, math.nan, 10**18, -(10**18), True, False, "", "x", "tet",
    "solid", "contact-space", [], [0.0], [0.0, 0.0, 0.0], [1e200, 0.0, 1e200], [[0.0, 1.0]],
    {}, {"E": 1.0}, [{}],
]  # fmt: skip


def _bases(directory: Path) -> list[dict]:
    out = []
    for name in HAND_FREE:
        out.append(tomllib.loads((ROOT / "examples" / name).read_text()))
    out.append(tomllib.loads(RICH))
    for data in out:
        data.setdefault("output", {})["directory"] = str(directory / "out")
        data["output"]["pictures"] = False
    return out


def _paths(value: Any, prefix: tuple = ()) -> list[tuple]:
    """Every key path into nested tables and lists."""
    out = [prefix] if prefix else []
    if isinstance(value, dict):
        for k, v in value.items():
            out += _paths(v, (*prefix, k))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            out += _paths(v, (*prefix, i))
    return out


def _parent(data: Any, path: tuple) -> Any:
    for k in path[:-1]:
        data = data[k]
    return data


def _mutate(data: dict, rng: random.Random) -> None:
    path = rng.choice(_paths(data))
    parent, key = _parent(data, path), path[-1]
    old = parent[key]
    what = rng.random()
    if what < 0.55:
        parent[key] = copy.deepcopy(rng.choice(ODD))
    elif what < 0.7 and isinstance(old, (int, float)) and not isinstance(old, bool):
        parent[key] = old * rng.choice([-1, 10.0**rng.randint(-300, 300), 1e-9, 1 + 1e-12])
    elif what < 0.8:
        if isinstance(parent, dict):
            del parent[key]
        else:
            parent.pop(key)
    elif what < 0.9 and isinstance(parent, dict):
        parent[rng.choice(["radus", "extra", "mesh", "times", "count", "force"])] = rng.choice(
            ODD
        )
    elif isinstance(old, list):
        parent[key] = old + old  # repeated keys, repeated times
    else:
        parent[key] = [old]


def _toml(value: Any) -> str:
    """A value as TOML (tables inline): enough for the fuzz's values."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value) if abs(value) < 2**63 else repr(float(value))
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    return "{ " + ", ".join(f"{json.dumps(str(k))} = {_toml(v)}" for k, v in value.items()) + " }"


def _document(data: dict) -> str:
    return "\n".join(f"{json.dumps(str(k))} = {_toml(v)}" for k, v in data.items()) + "\n"


def test_fuzzed_scenes_load_or_fail_in_one_line(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    rng = random.Random(SEED)
    bases = _bases(tmp_path)
    for base in bases:  # the bases themselves load
        p = tmp_path / "base.toml"
        p.write_text(_document(base))
        load_scene(p)
    loaded = failed = 0
    for case in range(CASES):
        data = copy.deepcopy(bases[case % len(bases)])
        for _ in range(rng.randint(1, 3)):
            if _paths(data):
                _mutate(data, rng)
        text = _document(data)
        path = tmp_path / f"case{case}.toml"
        path.write_text(text)
        start = time.perf_counter()
        try:
            load_scene(path)
            loaded += 1
        except SceneError as exc:
            failed += 1
            assert "\n" not in str(exc), (text, str(exc))
            assert str(exc).startswith(f"{path}: "), (text, str(exc))
        except Exception as exc:  # the point of the fuzz
            pytest.fail(f"case {case}: {type(exc).__name__}: {exc}\n{text}")
        took = time.perf_counter() - start
        assert took < 1.0, (case, took, text)
        path.unlink()
    assert loaded > 10 and failed > CASES // 2  # the mutations reach both outcomes
