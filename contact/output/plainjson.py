"""Plain JSON for ``summary.json`` and ``pose.json``: values as JSON types, package versions."""

from __future__ import annotations

import math
import os
import sys
from collections.abc import Mapping
from importlib import metadata
from typing import Any

import numpy as np

__all__ = ["jsonable", "versions"]

#: Distributions whose versions :func:`versions` reports (key -> distribution name).
_DISTRIBUTIONS = {
    "numpy": "numpy",
    "scipy": "scipy",
    "meshio": "meshio",
    "pyvista": "pyvista",
    "vtk": "vtk",
    "matplotlib": "matplotlib",
    "pillow": "pillow",
    "pytetwild": "pytetwild",
    "libigl": "libigl",
    "pypardiso": "pypardiso",
    "grasp-contact": "grasp-contact",
}


def versions() -> dict[str, str]:
    """Versions of Python and of the packages the results depend on.

    Returns
    -------
    dict of str to str
        ``python`` and each distribution (``"not installed"`` when missing).
    """
    out = {"python": sys.version.split()[0]}
    for key, dist in _DISTRIBUTIONS.items():
        try:
            out[key] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[key] = "not installed"
    return out


def jsonable(value: Any) -> Any:
    """``value`` as plain JSON types (arrays to lists, non-finite floats to None).

    Parameters
    ----------
    value : any
        Mappings, sequences, sets (sorted by ``repr``), numpy arrays and scalars, paths,
        dataclasses; anything else becomes its ``str``.

    Returns
    -------
    any
        Dicts with string keys, lists, bool, int, float, str or None.
    """
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, (list, tuple, set, frozenset)):
        items = sorted(value, key=repr) if isinstance(value, (set, frozenset)) else value
        return [jsonable(v) for v in items]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        v = float(value) + 0.0  # no -0.0
        return v if math.isfinite(v) else None
    if value is None or isinstance(value, str):
        return value
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if hasattr(value, "__dataclass_fields__"):
        return jsonable({k: getattr(value, k) for k in value.__dataclass_fields__})
    return str(value)
