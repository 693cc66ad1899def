"""The scene file's reader: typed TOML values, and the dataclasses' checks with key paths.

:class:`SceneReader` is the strict :class:`~contact._toml.TomlReader` with
:class:`SceneError`; :meth:`SceneReader.build` constructs a scene dataclass and turns its
failed check (``E = 0.0: must be positive``) into one line naming the file and the full
key path (``grasp.toml: hand.flesh.E = 0.0: must be positive``); :meth:`SceneReader.bounded`
reads a number within the physical bounds of its kind (:mod:`contact.scene.bounds`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

from .._toml import TomlReader, join
from ..errors import SceneError
from .bounds import out_of_bounds
from .model import MODELS, Material

__all__ = ["SceneReader"]

T = TypeVar("T")


class SceneReader(TomlReader):
    """Typed access to a scene's TOML values; every failure is a one-line :class:`SceneError`.

    Parameters
    ----------
    source : str
        The scene file as the messages name it.
    """

    error = SceneError

    def build(self, path: str, cls: Callable[..., T], /, *args: Any, **kw: Any) -> T:
        """``cls(*args, **kw)``, its failed check re-raised with the file and ``path``.

        Parameters
        ----------
        path : str
            Key path of the table the dataclass holds (``""``: the top level).
        cls : callable
            A scene dataclass (:mod:`contact.scene.model`, :mod:`contact.scene.spec`).
        *args, **kw
            Its fields.

        Returns
        -------
        object
            The dataclass.
        """
        try:
            return cls(*args, **kw)
        except SceneError as exc:
            raise SceneError(f"{self.source}: {join(path, str(exc))}") from None

    def bounded(self, value: Any, path: str, kind: str, **kw: Any) -> float:
        """A finite number (:meth:`number`, with its ``kw``) within the bounds of ``kind``.

        Parameters
        ----------
        value : object
            The parsed value.
        path : str
            Its key path.
        kind : str
            A key of :data:`contact.scene.bounds.BOUNDS` (``"length"``, ``"modulus"``...).
        **kw
            ``positive`` or ``nonnegative``.

        Returns
        -------
        float
        """
        x = self.number(value, path, **kw)
        why = out_of_bounds(kind, x)
        if why:
            raise self.fail(path, value, why)
        return x

    def bounded_vector(self, value: Any, path: str, kind: str, n: int = 3) -> tuple[float, ...]:
        """A list of ``n`` numbers, each within the bounds of ``kind``."""
        v = self.vector(value, path, n)
        for i, x in enumerate(v):
            why = out_of_bounds(kind, x)
            if why:
                raise self.fail(f"{path}[{i}]", value[i], why)
        return v

    def material(self, value: Any, path: str, defaults: Material) -> Material:
        """A ``{E, nu, density, model}`` table; a missing key takes its value in ``defaults``."""
        self.table(value, path, optional=("E", "nu", "density", "model"))
        e = self.bounded(value.get("E", defaults.E), f"{path}.E", "modulus", positive=True)
        nu = self.number(value.get("nu", defaults.nu), f"{path}.nu")
        rho = value.get("density", defaults.density)
        rho = self.bounded(rho, f"{path}.density", "density", nonnegative=True)
        model = defaults.model
        if "model" in value:
            model = self.string(value["model"], f"{path}.model", MODELS)
        return self.build(path, Material, e, nu, rho, model)
