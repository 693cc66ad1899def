"""A results folder that is never half-written: a staging folder, atomic files, a swap.

Everything is written into a hidden sibling of the results folder (same filesystem, so that
renames are atomic), every file through a temporary file and a rename. When all is written,
:func:`swap_into_place` renames an existing results folder aside, the staging folder into
its place, and only then deletes the old one: a crash between the two renames leaves both
complete, the old one under a hidden name. Only an empty folder or a results folder (one
that holds a ``summary.json``) is ever replaced.
"""

from __future__ import annotations

import logging
import os
import shutil
import uuid
from pathlib import Path

from ..errors import OutputError

__all__ = ["check_target", "make_staging", "swap_into_place", "write_atomic"]

log = logging.getLogger(__name__)


def write_atomic(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder.

    Parameters
    ----------
    path : Path
        The file; replaced only once ``data`` is on disk.
    data : bytes
    """
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex[:12]}.tmp")
    try:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def check_target(directory: Path, marker: str = "summary.json", kind: str = "results") -> None:
    """Refuse a folder that exists and is neither empty nor one this program wrote.

    Parameters
    ----------
    directory : Path
    marker : str
        The file a folder of this kind holds (``summary.json``, ``pose.json``).
    kind : str
        The folder's kind, for the message.

    Raises
    ------
    OutputError
        When ``directory`` is a file or a link, or a folder with files but no ``marker``.
    """
    d = directory
    if d.exists() or d.is_symlink():
        if d.is_symlink() or not d.is_dir():
            raise OutputError(f"{kind} folder {d} exists and is not a folder")
        if any(d.iterdir()) and not (d / marker).is_file():
            raise OutputError(
                f"{kind} folder {d} exists and is not a {kind} folder (no {marker}):"
                " refusing to replace it"
            )


def make_staging(directory: Path) -> Path:
    """Create the parent of ``directory`` if needed and a fresh staging folder beside it.

    Parameters
    ----------
    directory : Path
        The results folder (absolute).

    Returns
    -------
    Path
        The staging folder, ``.<name>.staging-<random>`` in the same parent.

    Raises
    ------
    OutputError
        When a folder cannot be created.
    """
    parent = directory.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
        # not mkdtemp: its mode 0700 would become the results folder's
        staging = parent / f".{directory.name}.staging-{uuid.uuid4().hex[:12]}"
        staging.mkdir()
    except OSError as exc:
        raise OutputError(
            f"cannot write the results folder {directory}: {exc.strerror or exc}"
        ) from None
    return staging


def swap_into_place(
    staging: Path, directory: Path, marker: str = "summary.json", kind: str = "results"
) -> None:
    """Rename the old folder aside, the staging folder into place, delete the old.

    Parameters
    ----------
    staging : Path
        The complete new results.
    directory : Path
        The results folder.
    marker, kind
        As for :func:`check_target`.

    Raises
    ------
    OutputError
        When ``directory`` is no longer replaceable (:func:`check_target`).
    OSError
        When a rename fails; the old results are then put back where possible.
    """
    check_target(directory, marker, kind)
    d = directory
    old = None
    if d.exists():
        old = d.with_name(f".{d.name}.old-{uuid.uuid4().hex[:12]}")
        os.rename(d, old)
    try:
        os.rename(staging, d)
    except BaseException:
        if old is not None:
            try:
                os.rename(old, d)
            except OSError:
                log.error("the previous results of %s are left in %s", d, old)
        raise
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
