"""``docs/scene.md`` against the dataclasses: every documented key exists, every default agrees.

Each table of the document with a ``key`` column is held against the dataclass that owns
its section: a documented key must be a field (or a documented sub-table), a literal
default (``"coarse"``, ``1e-4``, ``[1024, 768]``, ``{ E = ... }``) must equal the field's
default, ``required`` must be a field without one, and ``none`` / ``absent`` / ``every
frame`` must be ``None``. Other prose defaults (``the file's stem``) only need the field.
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path
from typing import Any

import pytest

from contact import Key
from contact._toml import tomllib
from contact.objects.ball import BallSpec
from contact.scene import (
    CONTACT_KEYS,
    AutoFlex,
    Follow,
    HandScene,
    ObjectScene,
    OutputScene,
    PlaneScene,
    Scene,
    SolverScene,
)
from contact.solver import ContactSettings

DOC = Path(__file__).resolve().parents[2] / "docs" / "scene.md"
NO_DEFAULT = object()


def _defaults(cls: type, keys: tuple[str, ...] | None = None) -> dict[str, Any]:
    """Field name -> default (NO_DEFAULT when it has none)."""
    out = {}
    for f in dataclasses.fields(cls):
        if keys is not None and f.name not in keys:
            continue
        if f.default is not dataclasses.MISSING:
            out[f.name] = f.default
        elif f.default_factory is not dataclasses.MISSING:
            out[f.name] = f.default_factory()
        else:
            out[f.name] = NO_DEFAULT
    return out


def _material(m: Any) -> dict[str, float]:
    return {"E": m.E, "nu": m.nu, "density": m.density}


#: The owner of each documented table, as key -> default; the heading's text names it.
OWNERS: dict[str, dict[str, Any]] = {
    "[scene]": _defaults(Scene, ("name", "description", "gravity")),
    "[ball]": {
        **{
            k: v
            for k, v in _defaults(BallSpec).items()
            if k not in ("E", "nu", "density", "model")
        },
        "material": _material(BallSpec),
        "friction": Scene.ball_friction,
    },
    "material": _defaults(BallSpec, ("E", "nu", "density", "model")),
    "[ball.follow]": _defaults(Follow),
    "[[object]]": {
        **{k: v for k, v in _defaults(ObjectScene).items() if k != "material"},
        "material": _material(ObjectScene.material),
        "kind": "solid",
    },
    "[hand]": {**_defaults(HandScene), "flesh": _material(HandScene.flesh)},
    "[[hand.keyframe]]": _defaults(Key),
    "[[hand.auto_flexion]]": _defaults(AutoFlex),
    "[[plane]]": _defaults(PlaneScene),
    "[solver]": {
        **_defaults(ContactSettings, CONTACT_KEYS),
        **_defaults(SolverScene, ("linear_solver", "substeps")),
    },
    "[output]": _defaults(OutputScene),
}
#: Tables documented without a default column: what they are read into has no dataclass.
NO_DEFAULTS = {"[frames]"}


def _tables(text: str) -> list[tuple[str, list[dict[str, str]]]]:
    """Every markdown table with a ``key`` column, with the heading or lead-in above it."""
    out = []
    lines = text.splitlines()
    heading = ""
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.startswith("#"):
            heading = line.lstrip("#").strip().strip("`")
        elif line.startswith("`material`"):
            heading = "material"
        if line.startswith("| key |"):
            names = [c.strip() for c in line.strip("|").split("|")]
            rows = []
            i += 2
            while i < len(lines) and lines[i].startswith("|"):
                cells = [c.strip() for c in lines[i].strip().strip("|").split("|")]
                rows.append(dict(zip(names, cells, strict=False)))
                i += 1
            out.append((heading, rows))
            continue
        i += 1
    return out


TABLES = _tables(DOC.read_text())


def _literal(cell: str) -> tuple[bool, Any]:
    """``(True, value)`` for a default written as a TOML value, else ``(False, None)``.

    A cell that opens with a code span stands for that span; the rest is a comment.
    """
    text = cell.split("`")[1] if cell.startswith("`") else cell
    try:
        return True, tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return False, None


def _plain(value: Any) -> Any:
    """Tuples as lists and paths as strings, for comparing with a TOML value."""
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    return value


def test_every_table_is_held() -> None:
    headings = [h for h, _ in TABLES]
    assert sorted(headings) == sorted([*OWNERS, *NO_DEFAULTS]), headings


@pytest.mark.parametrize(("heading", "rows"), TABLES, ids=[h for h, _ in TABLES])
def test_table_against_dataclass(heading: str, rows: list[dict[str, str]]) -> None:
    if heading in NO_DEFAULTS:
        assert all("default" not in r for r in rows)
        return
    owner = OWNERS[heading]
    for row in rows:
        key = row["key"].strip("`")
        assert key in owner, f"{heading}: {key} is not a field"
        cell, default = row["default"], owner[key]
        is_literal, value = _literal(cell)
        if cell == "required":
            assert default is NO_DEFAULT, f"{heading}: {key} has a default, {default!r}"
        elif re.match(r"(none|absent|every frame)\b", cell):
            assert default is None or default is NO_DEFAULT, f"{heading}: {key} = {default!r}"
        elif is_literal:
            assert _plain(default) == value, f"{heading}: {key}: docs {value!r}, code {default!r}"


def test_a_changed_default_fails(monkeypatch: pytest.MonkeyPatch) -> None:
    rows = dict(TABLES)["[solver]"]
    row = next(r for r in rows if r["key"] == "`gap_tolerance`")
    monkeypatch.setitem(OWNERS["[solver]"], "gap_tolerance", 2e-3)
    with pytest.raises(AssertionError, match="gap_tolerance"):
        test_table_against_dataclass("[solver]", [row])
