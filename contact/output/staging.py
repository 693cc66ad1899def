"""A results folder that is never half-written, and never holds what the user kept there.

Everything is written into a hidden sibling of the results folder (same filesystem, so that
renames are atomic), every file through a temporary file and a rename. When all is written,
:meth:`Staging.swap` writes the marker :data:`MARKER` (program, version, kind, the list of
files written), renames an existing results folder aside, the staging folder into its
place, and only then deletes the old one's listed files: a crash between the two renames
leaves both complete, the old one under a hidden name, which the next run restores (no
results folder) or removes (:func:`clean_leftovers`).

Only an empty folder, or one whose marker lists every file it holds, is ever replaced: a
file the program did not write (a user's notes) makes the folder refused, and is never
deleted. A run holds a lock file beside its staging folder (``.<name>.lock-<id>``, an
advisory ``flock`` held for its lifetime), so that a later run tells a live run's staging
folder from a dead run's.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import shutil
import signal
import uuid
from collections.abc import Iterator
from pathlib import Path

from ..errors import OutputError, TargetError

try:
    import fcntl
except ImportError:  # not POSIX: leftovers are never judged stale
    fcntl = None  # type: ignore[assignment]

__all__ = [
    "MARKER",
    "Staging",
    "check_target",
    "clean_leftovers",
    "make_staging",
    "swap_into_place",
    "write_atomic",
]

log = logging.getLogger(__name__)

#: The marker file of every folder this program writes: what wrote it and what it holds.
MARKER = ".grasp-contact.json"
#: The files that said "results" or "pose" before markers existed.
_OLD_MARKERS = {"results": "summary.json", "pose": "pose.json"}


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


def _files(folder: Path) -> set[str]:
    """Every file (not folder) under ``folder``, as posix paths relative to it."""
    return {
        p.relative_to(folder).as_posix()
        for p in folder.rglob("*")
        if p.is_symlink() or not p.is_dir()
    }


def _listed(folder: Path) -> tuple[str, set[str]] | None:
    """The kind and files of ``folder``'s marker; None without a readable one."""
    try:
        doc = json.loads((folder / MARKER).read_text())
        return str(doc["kind"]), {str(f) for f in doc["files"]}
    except (OSError, ValueError, KeyError, TypeError):
        return None


def check_target(directory: Path, kind: str = "results") -> None:
    """Refuse a folder that exists and is neither empty nor wholly written by this program.

    Parameters
    ----------
    directory : Path
    kind : str
        The folder's kind (``results``, ``pose``), for the marker and the message.

    Raises
    ------
    TargetError
        When ``directory`` is a file or a link; a folder without a marker; or one that
        holds a file its marker does not list. One line: why and what to do.
    """
    d = Path(directory)
    if not (d.exists() or d.is_symlink()):
        return
    if d.is_symlink() or not d.is_dir():
        raise TargetError(f"{kind} folder {d} exists and is not a folder: choose another --out")
    present = _files(d)
    if not present:
        return
    listed = _listed(d)
    if listed is None:
        old = _OLD_MARKERS.get(kind, "")
        why = (
            f"it holds a {old} but no {MARKER} (written by an older version?)"
            if old in present
            else f"it is not a {kind} folder of this program (no {MARKER})"
        )
        raise TargetError(
            f"{kind} folder {d}: {why}: refusing to replace it; move or delete it "
            "yourself, or choose another --out"
        )
    foreign = sorted(present - listed[1] - {MARKER})
    if listed[0] != kind or foreign:
        what = f"a {listed[0]} folder" if listed[0] != kind else f"{foreign[0]}"
        more = f" and {len(foreign) - 1} more" if len(foreign) > 1 else ""
        raise TargetError(
            f"{kind} folder {d} holds {what}{more}, which this run would not replace: "
            "move it out, or choose another --out"
        )


def _locked_by_another(lock: Path) -> bool:
    """Whether ``lock`` is held by a live run (taken and dropped again when free)."""
    if fcntl is None:
        return True
    try:
        fd = os.open(lock, os.O_RDWR)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return True
    finally:
        os.close(fd)
    return False


def _remove_written(folder: Path) -> bool:
    """Delete the files ``folder``'s marker lists, the marker, then empty folders.

    Returns whether ``folder`` is gone; anything not listed is left in place.
    """
    listed = _listed(folder)
    for name in (listed[1] if listed else set()) | {MARKER}:
        with contextlib.suppress(OSError):
            (folder / name).unlink()
    for sub in sorted((p for p in folder.rglob("*") if p.is_dir()), reverse=True):
        with contextlib.suppress(OSError):
            sub.rmdir()
    with contextlib.suppress(OSError):
        folder.rmdir()
    return not folder.exists()


def clean_leftovers(directory: Path) -> list[str]:
    """Clean what dead runs of this program left beside ``directory``; say so in one line.

    A dead run's staging folder and lock file are removed; a half-done swap's old folder
    (``.<name>.old-<id>``) is put back where the results folder is missing, else its
    listed files are deleted. A live run's (its lock held) are left alone.

    Parameters
    ----------
    directory : Path
        The results folder (absolute).

    Returns
    -------
    list of str
        What was done, one phrase each (also logged as one warning line).
    """
    parent, name = directory.parent, directory.name
    if fcntl is None or not parent.is_dir():
        return []
    groups: dict[str, dict[str, Path]] = {}
    for p in parent.iterdir():
        for part in ("staging", "old", "lock"):
            head = f".{name}.{part}-"
            if p.name.startswith(head):
                groups.setdefault(p.name[len(head) :], {})[part] = p
    done: list[str] = []
    for parts in groups.values():
        lock = parts.get("lock")
        if lock is not None and _locked_by_another(lock):
            continue
        if "staging" in parts:
            shutil.rmtree(parts["staging"], ignore_errors=True)
            done.append(f"removed {parts['staging'].name}")
        old = parts.get("old")
        if old is not None:
            if not (directory.exists() or directory.is_symlink()):
                os.rename(old, directory)
                done.append(f"restored {directory.name} from {old.name}")
            elif _remove_written(old):
                done.append(f"removed {old.name}")
        if lock is not None:
            lock.unlink(missing_ok=True)
    if done:
        log.warning("cleaned what an earlier run left beside %s: %s", directory, "; ".join(done))
    return done


def _missing_parents(folder: Path) -> list[Path]:
    """The ancestors of ``folder`` (itself included) that do not exist, outermost first."""
    out = []
    p = folder
    while not (p.exists() or p.is_symlink()) and p != p.parent:
        out.append(p)
        p = p.parent
    return out[::-1]


class Staging:
    """A run's staging folder beside its results folder, its lock, and the swap.

    Parameters
    ----------
    directory : Path
        The results folder (absolute).
    kind : str
        ``results`` or ``pose`` (the marker's kind).

    Raises
    ------
    OutputError
        When a folder or the lock cannot be created.
    """

    def __init__(self, directory: Path, kind: str = "results") -> None:
        self.directory = Path(directory)
        self.kind = kind
        parent = self.directory.parent
        self.created = _missing_parents(parent)
        ident = uuid.uuid4().hex[:12]
        self.lock = parent / f".{self.directory.name}.lock-{ident}"
        self.path = parent / f".{self.directory.name}.staging-{ident}"
        self._fd: int | None = None
        try:
            parent.mkdir(parents=True, exist_ok=True)
            self._fd = os.open(self.lock, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o644)
            if fcntl is not None:
                fcntl.flock(self._fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            if os.stat(self.lock).st_ino != os.fstat(self._fd).st_ino:  # a cleaner took it
                raise OSError("lost a race with another run for the lock")
            os.write(self._fd, f"{os.getpid()}\n".encode())
            # not mkdtemp: its mode 0700 would become the results folder's
            self.path.mkdir()
        except OSError as exc:
            self._release()
            self._remove_parents()
            raise OutputError(
                f"cannot write the {kind} folder {directory}: {exc.strerror or exc}"
            ) from None

    def swap(self) -> None:
        """Write the marker, rename the old folder aside and this one in; delete the old.

        Raises
        ------
        OutputError
            When ``directory`` became unreplaceable meanwhile (a lost race with another
            run or the user), or a rename fails; the old results are then put back.
        """
        files = sorted(_files(self.path) - {MARKER})
        doc = {"program": "grasp-contact", "version": _version(), "kind": self.kind}
        write_atomic(self.path / MARKER, (json.dumps({**doc, "files": files}, indent=1)).encode())
        d = self.directory
        try:
            check_target(d, self.kind)
        except TargetError as exc:
            raise OutputError(f"{exc} (it changed during this run)") from None
        old = None
        with _signals_held():
            if d.exists():
                old = d.with_name(f".{d.name}.old-{self.path.name.rsplit('-', 1)[-1]}")
                os.rename(d, old)
            try:
                os.rename(self.path, d)
            except OSError as exc:
                if old is not None:
                    try:
                        os.rename(old, d)
                    except OSError:
                        log.error("the previous %s of %s are left in %s", self.kind, d, old)
                raise OutputError(
                    f"cannot put the {self.kind} folder {d} in place: {exc}"
                ) from None
        if old is not None and not _remove_written(old):
            log.warning("%s: files this program did not write are left in %s", d, old)
        self._release()

    def discard(self) -> None:
        """Remove the staging folder, the lock and the parents this run created. Idempotent."""
        shutil.rmtree(self.path, ignore_errors=True)
        self._release()
        self._remove_parents()

    def _release(self) -> None:
        if self._fd is not None:
            self.lock.unlink(missing_ok=True)
            os.close(self._fd)
            self._fd = None

    def _remove_parents(self) -> None:
        for p in reversed(self.created):
            with contextlib.suppress(OSError):
                p.rmdir()


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    """SIGINT and SIGTERM held back across the two renames of a swap (delivered after)."""
    sigs = {signal.SIGINT, signal.SIGTERM}
    try:
        before = signal.pthread_sigmask(signal.SIG_BLOCK, sigs)
    except (AttributeError, ValueError, OSError):
        yield
        return
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, before)


def _version() -> str:
    try:
        from importlib.metadata import version

        return version("grasp-contact")
    except Exception:  # not installed as a distribution
        return "unknown"


def make_staging(directory: Path, kind: str = "results") -> Staging:
    """Clean leftovers, refuse a foreign folder, and start a staging folder beside it.

    Parameters
    ----------
    directory : Path
        The results folder (absolute).
    kind : str
        ``results`` or ``pose``.

    Returns
    -------
    Staging

    Raises
    ------
    TargetError
        When ``directory`` may not be replaced (:func:`check_target`).
    OutputError
        When a folder cannot be created.
    """
    clean_leftovers(directory)
    check_target(directory, kind)
    return Staging(directory, kind)


def swap_into_place(staging: Staging) -> None:
    """Swap a complete staging folder into place (:meth:`Staging.swap`)."""
    staging.swap()
