"""Checks shared by the scene's dataclasses: a failed field, a friction coefficient."""

from __future__ import annotations

import math
from dataclasses import fields
from typing import Any

from .._toml import short
from ..errors import SceneError

__all__ = ["as_dict", "check_friction", "invalid"]


def invalid(key: str, value: Any, why: str) -> SceneError:
    """A failed check of field ``key``, relative to its table."""
    return SceneError(f"{key} = {short(value)}: {why}")


def check_friction(key: str, mu: Any) -> None:
    """Coulomb's coefficient ``key`` must be a finite number >= 0 (None: not given)."""
    if mu is None:
        return
    if isinstance(mu, bool) or not isinstance(mu, (int, float)) or not 0.0 <= mu < math.inf:
        raise invalid(key, mu, "must be a finite number >= 0")


def as_dict(obj: Any) -> dict:
    """A dataclass's fields as a dict (not recursing, unlike :func:`dataclasses.asdict`)."""
    return {f.name: getattr(obj, f.name) for f in fields(obj)}
