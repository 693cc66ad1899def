"""Off-screen rendering: can pyvista render here, PNG bytes of an image, a GIF of PNG files.

A failing VTK can abort the process that renders, so :func:`rendering_available` asks a
child process to render a small picture first, once per process, and
:func:`run_in_child` renders in a child process, whose death costs only its pictures.
On Linux without a display it asks for an EGL window (``VTK_DEFAULT_OPENGL_WINDOW``)
first and keeps it where it renders, so that VTK does not try X and log a warning on every run.

This module imports nothing of :mod:`contact`: the results writer and the hand's pictures
both use it.
"""

from __future__ import annotations

import functools
import io
import multiprocessing
import os
import signal
import subprocess
import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["ChildDied", "png_bytes", "rendering_available", "run_in_child", "write_gif"]

_PROBE = """
import numpy as np, pyvista as pv
p = pv.Plotter(off_screen=True, window_size=[64, 48])
p.add_mesh(pv.Sphere(), color="red")
img = p.screenshot(return_img=True)
p.close()
assert img.shape[:2] == (48, 64) and np.ptp(img) > 0, "blank image"
"""

#: The environment variable by which VTK (9.4 on) is told which OpenGL window to make.
_WINDOW_VARIABLE = "VTK_DEFAULT_OPENGL_WINDOW"
#: Asked for first on Linux without a display: left to choose, VTK tries X first, logs
#: "bad X server connection" on every run, and only then falls back to EGL.
_HEADLESS_WINDOW = "vtkEGLRenderWindow"


def _probe(env: Mapping[str, str]) -> tuple[bool, str]:
    """Render a small picture in a child process with ``env`` added to the environment."""
    try:
        proc = subprocess.run(
            [sys.executable, "-c", _PROBE],
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
            env={**os.environ, **env},
        )
    except (OSError, subprocess.SubprocessError) as exc:
        return False, f"off-screen rendering check failed: {exc}"
    if proc.returncode == 0:
        return True, "ok"
    lines = [ln.strip() for ln in proc.stderr.splitlines() if ln.strip()]
    last = lines[-1] if lines else f"exit status {proc.returncode}"
    return False, f"off-screen rendering unavailable: {last[:300]}"


@functools.cache
def rendering_available() -> tuple[bool, str]:
    """Can pyvista render off-screen here? Checked once per process, in a child process.

    On Linux without a display (``DISPLAY`` and ``WAYLAND_DISPLAY`` unset), and unless the
    user chose a window (``VTK_DEFAULT_OPENGL_WINDOW``), EGL is tried first; where it
    renders, this process asks VTK for it too, so that VTK does not try X and log a
    warning on every run. Otherwise VTK chooses, as it would.

    Returns
    -------
    ok : bool
    reason : str
        ``"ok"``, or why not (the child's last error line).
    """
    headless = not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    if sys.platform.startswith("linux") and headless and _WINDOW_VARIABLE not in os.environ:
        ok, _ = _probe({_WINDOW_VARIABLE: _HEADLESS_WINDOW})
        if ok:
            os.environ[_WINDOW_VARIABLE] = _HEADLESS_WINDOW
            return True, "ok"
    return _probe({})


def png_bytes(image: NDArray[np.uint8]) -> bytes:
    """An image ``(height, width, 3 or 4)`` encoded as PNG (Pillow).

    Parameters
    ----------
    image : ndarray of uint8

    Returns
    -------
    bytes
    """
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(image)).save(buf, format="PNG")
    return buf.getvalue()


def write_gif(
    frames: Sequence[str | os.PathLike], path: str | os.PathLike, fps: float = 10.0
) -> Path:
    """Assemble PNG frames into a looping GIF (Pillow).

    Parameters
    ----------
    frames : sequence of path-like
        The PNG files, in order.
    path : path-like
        The GIF to write.
    fps : float
        Frame rate.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ValueError
        When ``frames`` is empty.
    """
    from PIL import Image

    if not frames:
        raise ValueError("write_gif: no frames")
    images = [Image.open(f).convert("RGB") for f in frames]
    path = Path(path)
    images[0].save(
        path,
        save_all=True,
        append_images=images[1:],
        duration=max(1, round(1000.0 / fps)),
        loop=0,
    )
    return path


class ChildDied(RuntimeError):
    """A child process ended without saying how it went (killed, aborted, timed out)."""


def _child(conn: Any, func: Callable, args: tuple) -> None:
    """Run ``func(*args)`` and send None, or ``(kind, message)`` on an error."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    try:
        func(*args)
        conn.send(None)
    except OSError as exc:
        conn.send(("os", str(exc)))
    except Exception as exc:
        conn.send(("other", f"{type(exc).__name__}: {exc}"))
    finally:
        conn.close()


def run_in_child(func: Callable, args: tuple, timeout: float = 3600.0) -> None:
    """Run ``func(*args)`` in a fresh (spawned) child process and wait for it.

    Parameters
    ----------
    func : callable
        A module-level function (it is pickled by name); its return value is dropped.
    args : tuple
        Its arguments (pickled).
    timeout : float
        Seconds after which the child is killed.

    Raises
    ------
    OSError
        When ``func`` raised one (a file that could not be written).
    RuntimeError
        When ``func`` raised anything else (the message names the exception).
    ChildDied
        When the child died (a signal, an abort) or took over ``timeout``.
    """
    ctx = multiprocessing.get_context("spawn")
    receive, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(send, func, args), daemon=True)
    proc.start()
    send.close()
    answer: object = "timeout"
    try:
        if receive.poll(timeout):
            answer = receive.recv()
    except EOFError:
        answer = "died"
    finally:
        proc.join(5.0 if answer is None or isinstance(answer, tuple) else 1.0)
        if proc.is_alive():
            proc.kill()
            proc.join()
        receive.close()
    if answer is None:
        return
    if isinstance(answer, tuple):
        raise (OSError if answer[0] == "os" else RuntimeError)(answer[1])
    if answer == "timeout":
        raise ChildDied(f"the renderer took over {timeout:g} s and was stopped")
    code = proc.exitcode
    how = f"signal {signal.Signals(-code).name}" if code and code < 0 else f"exit status {code}"
    raise ChildDied(f"the renderer's process died ({how})")
