"""Filled object meshes kept between runs: the same surface and size give the same tetrahedra.

fTetWild is slow (seconds to tens of seconds for an object) and not deterministic: two
fills of one surface differ, and so would two runs of one scene. The first fill of a
surface at a ``mesh_size`` is kept as a VTU file named by the hash of the surface file's
bytes, the size and the filling's settings; later runs (a rerun, every run of a sweep)
read it. The folder is ``$GRASP_CONTACT_CACHE``, else ``$XDG_CACHE_HOME/grasp-contact``,
else ``~/.cache/grasp-contact``; ``GRASP_CONTACT_CACHE=off`` keeps nothing. A cache that
cannot be written or read is skipped with a log line, never an error.
"""

from __future__ import annotations

import hashlib
import logging
import os
import tempfile
from collections.abc import Callable
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import fem

__all__ = ["CACHE_ENV", "cache_dir", "cached"]

log = logging.getLogger(__name__)

#: The environment variable that names the cache folder (``off``: no cache).
CACHE_ENV = "GRASP_CONTACT_CACHE"


def cache_dir() -> Path | None:
    """The folder of filled meshes, or None when the cache is off."""
    value = os.environ.get(CACHE_ENV, "").strip()
    if value.lower() == "off":
        return None
    if value:
        return Path(value)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "grasp-contact"


def _key(path: Path, settings: str) -> str:
    try:
        tetwild = version("pytetwild")
    except PackageNotFoundError:
        tetwild = "?"
    h = hashlib.sha256(path.read_bytes())
    h.update(f"|{settings}|pytetwild {tetwild}".encode())
    return h.hexdigest()[:32]


def cached(path: Path, settings: str, fill: Callable[[], fem.Mesh]) -> fem.Mesh:
    """The mesh ``fill`` makes of the file ``path`` with ``settings``, kept between runs.

    Parameters
    ----------
    path : Path
        The surface file (its bytes are part of the key).
    settings : str
        Everything else the fill depends on (the size, fTetWild's options).
    fill : callable
        Makes the mesh when none is kept.

    Returns
    -------
    fem.Mesh
    """
    folder = cache_dir()
    if folder is None:
        return fill()
    target = folder / "objects" / f"{_key(path, settings)}.vtu"
    if target.is_file():
        try:
            mesh = fem.read_mesh(target)
            log.info("'%s': its tetrahedra read from the cache %s", path, target)
            return mesh
        except (fem.FemError, OSError, ValueError) as exc:
            log.warning("the cached mesh %s cannot be read (%s): filled again", target, exc)
    mesh = fill()
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=target.parent, suffix=".vtu")
        os.close(fd)
        try:
            fem.write_mesh(tmp, mesh)
            os.replace(tmp, target)  # atomic: a sweep's workers may fill the same surface
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
    except OSError as exc:
        log.warning("the filled mesh of '%s' cannot be kept in %s: %s", path, folder, exc)
    return mesh
