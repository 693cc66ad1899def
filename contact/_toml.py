"""One strict TOML reader for the scene and rig files: typed values, key paths, hints.

:class:`TomlReader` checks a parsed TOML value against what a section expects (a table
with known keys, a finite number, an integer, a boolean, a non-empty string, a list of
numbers, increasing times, a readable file) and turns the first problem into one line
naming the file and the key path: ``<file>: <key.path> = <value>: <what is wrong>``, or
``<file>: <key.path>: <what is wrong>`` when there is no value to show. An unknown key
gets the closest valid one as a hint. Ranges that a dataclass checks are left to it:
the reader reads, the dataclasses hold the defaults and checks.

The scene reader (:mod:`contact.scene.read`) and the rig reader
(:mod:`contact.hand.rigspec`) subclass it to choose their exception and wording.
"""

from __future__ import annotations

import difflib
import errno
import math
import os
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["MISSING", "TomlReader", "hint", "join", "short", "tomllib"]

#: Stands for an absent value: the message then names the key path alone.
MISSING: Any = object()


def short(value: Any) -> str:
    """``repr(value)``, cut to 60 characters."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def hint(key: str, options: Iterable[str]) -> str:
    """``"; did you mean 'x'?"`` for the closest option (difflib, else a unique prefix).

    Parameters
    ----------
    key : str
        What the file says.
    options : iterable of str
        What it may say.

    Returns
    -------
    str
        The hint, or ``""`` when no option is close.
    """
    options = list(options)
    close = difflib.get_close_matches(key, options, n=1)
    if not close:
        close = [o for o in options if o.startswith(key) or key.startswith(o)][:1]
    return f"; did you mean {close[0]!r}?" if close else ""


def join(path: str, key: str) -> str:
    """The key path of ``key`` inside the table at ``path`` (``""``: the top level)."""
    return f"{path}.{key}" if path else key


class TomlReader:
    """Typed access to parsed TOML values; every failure is one line naming file and key path.

    Subclasses set the exception raised and the wording that differs between file kinds.

    Parameters
    ----------
    source : str
        The file as the messages name it.
    """

    #: The exception every failure raises.
    error: type[Exception] = ValueError
    #: Suggest the closest valid key for an unknown one.
    hints: bool = True
    #: What a missing required key is called.
    missing: str = "missing (required)"

    def __init__(self, source: str) -> None:
        self.source = source

    def show(self, value: Any) -> str:
        """How a value appears in a message."""
        return short(value)

    def fail(self, path: str, value: Any, why: str) -> Exception:
        """The error for ``path`` holding ``value`` (:data:`MISSING`: no value shown)."""
        if value is MISSING:
            return self.error(f"{self.source}: {path}: {why}")
        return self.error(f"{self.source}: {path} = {self.show(value)}: {why}")

    def table(
        self, data: Any, path: str, required: Iterable[str] = (), optional: Iterable[str] = ()
    ) -> dict:
        """Check that ``data`` is a table with only allowed keys and every required one.

        Parameters
        ----------
        data : object
            The parsed value.
        path : str
            Its key path (``""``: the whole file).
        required, optional : iterable of str
            The keys it must have, and those it may have.

        Returns
        -------
        dict
            ``data``.
        """
        required, optional = set(required), set(optional)
        allowed = required | optional
        if not isinstance(data, dict):
            raise self.fail(path, data, "must be a table")
        for key in data:
            if key not in allowed:
                close = hint(key, sorted(allowed)) if self.hints else ""
                raise self.error(
                    f"{self.source}: {join(path, key)}: unknown key{close} "
                    f"(allowed: {', '.join(sorted(allowed))})"
                )
        for key in sorted(required):
            if key not in data:
                raise self.fail(join(path, key), MISSING, self.missing)
        return data

    def number(
        self, value: Any, path: str, *, positive: bool = False, nonnegative: bool = False
    ) -> float:
        """A finite number (a boolean is not one), optionally positive or not negative."""
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(path, value, "must be a number")
        if not math.isfinite(value):
            raise self.fail(path, value, "must be finite")
        if positive and not value > 0:
            raise self.fail(path, value, "must be positive")
        if nonnegative and value < 0:
            raise self.fail(path, value, "must not be negative")
        return float(value)

    def integer(self, value: Any, path: str, minimum: int | None = None) -> int:
        """An integer (a boolean or ``5.0`` is not one), at least ``minimum`` if given."""
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(path, value, "must be an integer")
        if minimum is not None and value < minimum:
            raise self.fail(path, value, f"must be at least {minimum}")
        return value

    def boolean(self, value: Any, path: str) -> bool:
        """``true`` or ``false``."""
        if not isinstance(value, bool):
            raise self.fail(path, value, "must be true or false")
        return value

    def string(self, value: Any, path: str, choices: Iterable[str] | None = None) -> str:
        """A non-empty string, one of ``choices`` if given."""
        if not isinstance(value, str) or not value:
            raise self.fail(path, value, "must be a non-empty string")
        if choices is not None:
            choices = tuple(choices)
            if value not in choices:
                raise self.fail(path, value, f"unknown; expected one of {', '.join(choices)}")
        return value

    def vector(
        self, value: Any, path: str, n: int = 3, *, positive: bool = False
    ) -> tuple[float, ...]:
        """A list of ``n`` numbers, each positive if asked."""
        if not isinstance(value, list) or len(value) != n:
            raise self.fail(path, value, f"must be a list of {n} numbers")
        return tuple(self.number(v, f"{path}[{i}]", positive=positive) for i, v in enumerate(value))

    def times(self, value: Any, path: str) -> tuple[float, ...]:
        """A non-empty list of strictly increasing times."""
        if not isinstance(value, list) or not value:
            raise self.fail(path, value, "must be a non-empty list of numbers")
        out = tuple(self.number(v, f"{path}[{i}]") for i, v in enumerate(value))
        for i in range(1, len(out)):
            if not out[i] > out[i - 1]:
                raise self.fail(
                    f"{path}[{i}]", value[i], f"times must increase (previous {out[i - 1]:g})"
                )
        return out

    def file(self, value: Any, path: str, base: Path) -> Path:
        """An existing readable file; a relative path is taken from ``base``."""
        name = self.string(value, path)
        try:
            full = (base / Path(name).expanduser()).resolve()
            os.stat(full)  # a symlink loop: ELOOP here, or RuntimeError above
        except RuntimeError:
            raise self.fail(path, value, "a symlink loop") from None
        except OSError as exc:
            if exc.errno == errno.ELOOP:
                raise self.fail(path, value, "a symlink loop") from None
        if not full.exists():
            raise self.fail(path, value, f"no such file ({full})")
        if not full.is_file():
            raise self.fail(path, value, f"not a file ({full})")
        try:
            with open(full, "rb") as f:
                f.read(1)
        except OSError as exc:
            raise self.fail(path, value, f"cannot be read ({exc.strerror or exc})") from None
        return full
