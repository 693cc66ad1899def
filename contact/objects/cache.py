"""Filled object meshes kept between runs: the same surface and size give the same tetrahedra.

fTetWild is slow (seconds to tens of seconds for an object) and not deterministic: two
fills of one surface differ, and so would two runs of one scene. The first fill of a
surface at a ``mesh_size`` is kept as a VTU file named by the hash of the surface file's
bytes, the size and the filling's settings; later runs (a rerun, every run of a sweep)
read it. The folder is ``$GRASP_CONTACT_CACHE``, else ``$XDG_CACHE_HOME/grasp-contact``,
else ``~/.cache/grasp-contact``; ``GRASP_CONTACT_CACHE=off`` keeps nothing. A cache that
cannot be written or read is skipped with a log line, never an error.

A kept mesh is trusted only while it is the fill it claims to be: beside it a record
(``<key>.json``) holds the hash of its bytes, and its bounding box and enclosed volume must
match the surface's within fTetWild's envelope. A mesh that fails either is filled again,
with one warning. Runs that fill the same surface at once take a lock (``<key>.lock``,
``fcntl.flock``, released by the system when its holder dies): the first fills, the
others wait and read its mesh, so that every run uses the same tetrahedra.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import tempfile
import time
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

import fem

from ..geometry import enclosed_volume
from ..geometry.triangles import surface_of_mesh

try:
    import fcntl
except ImportError:  # not POSIX: runs fill alone, without a lock
    fcntl = None  # type: ignore[assignment]

__all__ = ["CACHE_ENV", "FILL_TOLERANCE", "LOCK_WAIT", "cache_dir", "cached"]

log = logging.getLogger(__name__)

#: The environment variable that names the cache folder (``off``: no cache).
CACHE_ENV = "GRASP_CONTACT_CACHE"
#: How far (a fraction of the surface's bounding-box diagonal) a kept fill's bounding box
#: and volume may lie from the surface's: five times fTetWild's default envelope.
FILL_TOLERANCE = 5e-3
#: The longest wait (s) for another run's fill of the same surface before filling anyway.
LOCK_WAIT = 3600.0


def cache_dir() -> Path | None:
    """The folder of filled meshes, or None when the cache is off."""
    value = os.environ.get(CACHE_ENV, "").strip()
    if value.lower() == "off":
        return None
    if value:
        return Path(value)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "grasp-contact"


def _key(path: Path, settings: str, content: bytes | None = None) -> str:
    try:
        tetwild = version("pytetwild")
    except PackageNotFoundError:
        tetwild = "?"
    h = hashlib.sha256(path.read_bytes() if content is None else content)
    h.update(f"|{settings}|pytetwild {tetwild}".encode())
    return h.hexdigest()[:32]


def _shape(points: NDArray, triangles: NDArray) -> tuple[NDArray, float, float]:
    """Bounding box (2, 3), enclosed volume and area of a closed surface."""
    x = points[triangles]
    area = 0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), axis=1).sum()
    box = np.array([points.min(axis=0), points.max(axis=0)])
    return box, abs(enclosed_volume(points, triangles)), float(area)


def _mismatch(mesh: fem.Mesh, surface: tuple[NDArray, NDArray], tolerance: float) -> str | None:
    """Why ``mesh`` is not a fill of ``surface``, or None when it matches."""
    box, volume, area = _shape(*surface)
    diag = float(np.linalg.norm(box[1] - box[0]))
    own = np.array([mesh.points.min(axis=0), mesh.points.max(axis=0)])
    own_volume = abs(enclosed_volume(mesh.points, surface_of_mesh(mesh)[1]))
    if np.abs(own - box).max() > tolerance * diag:
        span, size = np.ptp(own, axis=0).max(), np.ptp(box, axis=0).max()
        return f"spans {span:.4g} m, the surface {size:.4g} m"
    if abs(own_volume - volume) > tolerance * diag * area:
        return f"encloses {own_volume:.4g} m^3, the surface {volume:.4g} m^3"
    return None


def _read(
    target: Path, surface: tuple[NDArray, NDArray], tolerance: float
) -> tuple[fem.Mesh | None, str | None]:
    """The kept mesh, or None and why it cannot be used (None: there is none)."""
    if not target.is_file():
        return None, None
    try:
        data = target.read_bytes()
        record = json.loads(target.with_suffix(".json").read_text())
    except FileNotFoundError:  # kept before records were: filled again without a word
        log.info("the cached mesh %s has no record of its fill: filled again", target)
        return None, None
    except (OSError, ValueError):
        return None, "has a damaged record of its fill"
    if not isinstance(record, dict) or record.get("sha256") != hashlib.sha256(data).hexdigest():
        return None, "was changed after it was kept"
    try:
        mesh = fem.read_mesh(target)
    except (fem.FemError, OSError, ValueError) as exc:
        return None, f"cannot be read ({exc})"
    why = _mismatch(mesh, surface, tolerance)
    return (None, f"is not a fill of the surface: it {why}") if why else (mesh, None)


@contextmanager
def _locked(lock: Path, path: Path) -> Iterator[None]:
    """Hold the fill's lock: wait while another run fills the same surface."""
    try:
        lock.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        log.warning("the lock %s cannot be taken (%s): '%s' filled without it", lock, exc, path)
        yield
        return
    try:
        start, said = time.monotonic(), False
        while fcntl is not None:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() - start > LOCK_WAIT:
                    log.warning("'%s': still locked by %s: filled without the lock", path, lock)
                    break
                if not said:
                    log.info("'%s': waiting for another run's fill (%s)", path, lock)
                    said = True
                time.sleep(0.05)
            except OSError:  # a file system without locks
                break
        yield
    finally:
        os.close(fd)  # releases the lock


def _keep(target: Path, mesh: fem.Mesh, path: Path) -> None:
    """Write the mesh and its record, each replaced atomically (the record first)."""
    target.parent.mkdir(parents=True, exist_ok=True)
    tmps = []
    try:
        for suffix in (".vtu", ".json"):
            fd, tmp = tempfile.mkstemp(dir=target.parent, suffix=suffix)
            os.close(fd)
            tmps.append(tmp)
        fem.write_mesh(tmps[0], mesh)
        digest = hashlib.sha256(Path(tmps[0]).read_bytes()).hexdigest()
        Path(tmps[1]).write_text(json.dumps({"sha256": digest, "surface": str(path)}))
        os.replace(tmps[1], target.with_suffix(".json"))
        os.replace(tmps[0], target)
    finally:
        for tmp in tmps:
            if os.path.exists(tmp):
                os.unlink(tmp)


def cached(
    path: Path,
    settings: str,
    fill: Callable[[], fem.Mesh],
    surface: tuple[NDArray, NDArray],
    *,
    tolerance: float = FILL_TOLERANCE,
    content: bytes | None = None,
) -> fem.Mesh:
    """The mesh ``fill`` makes of the file ``path`` with ``settings``, kept between runs.

    Parameters
    ----------
    path : Path
        The surface file (its bytes are part of the key); with ``content``, only the
        surface's name in messages.
    settings : str
        Everything else the fill depends on (the size, fTetWild's options).
    fill : callable
        Makes the mesh when none is kept (or the kept one is not this fill).
    surface : (ndarray, ndarray)
        The surface's points and triangles, which a kept mesh must match.
    tolerance : float
        How far, as a fraction of the surface's bounding-box diagonal, the kept mesh's
        bounding box may lie from the surface's (its volume: that distance times the area).
    content : bytes, optional
        The surface's bytes, for a surface made in memory (a generated ball's), instead
        of the file's.

    Returns
    -------
    fem.Mesh

    Warns
    -----
    UserWarning
        Once, when a kept mesh was changed or is not a fill of the surface: filled again.
    """
    folder = cache_dir()
    if folder is None:
        return fill()
    target = folder / "objects" / f"{_key(path, settings, content)}.vtu"
    mesh, why = _read(target, surface, tolerance)
    if mesh is not None:
        log.info("'%s': its tetrahedra read from the cache %s", path, target)
        return mesh
    with _locked(target.with_suffix(".lock"), path):
        mesh, again = _read(target, surface, tolerance)  # a fill that ended as we waited
        if mesh is not None:
            log.info("'%s': its tetrahedra filled by another run, read from %s", path, target)
            return mesh
        if why or again:
            warnings.warn(
                f"'{path}': the cached mesh {target} {why or again}: filled again", stacklevel=3
            )
        mesh = fill()
        try:
            _keep(target, mesh, path)
        except OSError as exc:
            log.warning("the filled mesh of '%s' cannot be kept in %s: %s", path, folder, exc)
    return mesh
