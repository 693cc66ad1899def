"""What both command lines share: SIGTERM as an exception, interrupts, internal errors.

``python -m contact.grasp`` and ``python -m contact.sweep`` keep one exit-status contract
(:func:`guarded`): Ctrl-C and SIGTERM are one line and 130 / 143, any unexpected error
one line naming it and a log file holding its traceback, 3.
"""

from __future__ import annotations

import os
import signal
import sys
import tempfile
import traceback
from collections.abc import Callable

__all__ = ["SIGNALLED", "Terminated", "catch_sigterm", "check_terminated", "guarded",
           "internal_error"]  # fmt: skip


class Terminated(BaseException):
    """SIGTERM, raised where the run is, so that it unwinds as Ctrl-C does."""


#: SIGTERMs received: the handler's exception is lost where it lands in a callback whose
#: exceptions Python ignores (a weakref's, a ``__del__``), so frames check this too.
SIGNALLED: list[int] = []


def check_terminated() -> None:
    """Raise :class:`Terminated` where a SIGTERM came and its exception was swallowed."""
    if SIGNALLED:
        raise Terminated


def guarded(command: Callable[[], int], interrupted: str) -> int:
    """Run a CLI's ``command`` under the exit-status contract both CLIs share.

    Ctrl-C and SIGTERM give one line (``interrupted; <interrupted>``) and 130 / 143; any
    other exception one line and a log file (:func:`internal_error`), 3. The SIGTERM
    handler before is put back.
    """
    term = catch_sigterm()
    try:
        return command()
    except (KeyboardInterrupt, Terminated) as exc:
        print(f"interrupted; {interrupted}", file=sys.stderr)
        return 143 if isinstance(exc, Terminated) else 130
    except Exception as exc:
        return internal_error(exc)
    finally:
        if term is not None:
            signal.signal(signal.SIGTERM, term)  # type: ignore[arg-type]


def catch_sigterm() -> object:
    """Make SIGTERM raise :class:`Terminated`; the handler before, or None (not main thread)."""

    def handler(signum: int, frame: object) -> None:
        SIGNALLED.append(signum)
        raise Terminated

    SIGNALLED.clear()
    try:
        return signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread
        return None


def internal_error(exc: Exception) -> int:
    """Write the traceback to a log file; one line on stderr naming both; exit status 3."""
    text = traceback.format_exc()
    what = (str(exc).splitlines() or [""])[0][:300]
    try:
        fd, name = tempfile.mkstemp(prefix="grasp-contact-", suffix=".log")
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        where = f"traceback in {name}"
    except OSError:
        where = "no log file could be written"
    print(
        f"error: internal error: {type(exc).__name__}: {what}; {where}; please report it",
        file=sys.stderr,
    )
    return 3


