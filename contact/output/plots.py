"""The run's plots (matplotlib): convergence per frame, and forces against time.

``convergence.png``: the largest change of a nodal displacement against iteration, one
line per frame. ``forces.png``: the normal force of every finger and the grip force, and
the force on every bone, against time (:class:`contact.output.forces.FrameForces`).
"""

from __future__ import annotations

import io
from collections.abc import Sequence

import numpy as np

from .forces import FrameForces

__all__ = ["convergence_png", "forces_png"]

#: At most this many bones are drawn by name in ``forces.png``; the rest are summed up in
#: the legend, so that 21 bones of a hand do not hide the few that carry the grasp.
_MAX_BONES = 8
#: A bone whose force stays below this fraction of the largest bone force is not drawn.
_SMALL = 1e-3


def _png(fig) -> bytes:
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def convergence_png(curves: Sequence[tuple[float, Sequence[float]]]) -> bytes:
    """The convergence plot: largest change against iteration, one line per frame.

    Parameters
    ----------
    curves : sequence of (float, sequence of float)
        Frame time and the largest change of a nodal displacement at each iteration (m).
        More than ten frames are coloured by time with a colour bar, fewer get a legend.

    Returns
    -------
    bytes
        The PNG.
    """
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.0, 4.5), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    drawn = [(t, h) for t, h in curves if h]
    many = len(drawn) > 10
    times = [t for t, _ in drawn]
    norm = Normalize(min(times, default=0.0), max(times, default=1.0) or 1.0)
    cmap = colormaps["viridis"]
    for k, (t, h) in enumerate(drawn):
        y = np.asarray(h)
        y = np.where(y > 0, y, np.nan)  # a log scale cannot show a zero change
        it = np.arange(1, len(y) + 1)
        color = cmap(norm(t)) if many else f"C{k % 10}"
        ax.plot(it, y, "o-", ms=3, lw=1.2, color=color, label=f"t = {t:g}")
    ax.set_yscale("log")
    ax.set_xlabel("iteration")
    ax.set_ylabel("largest change of a nodal displacement (m)")
    ax.set_title("Contact iteration: convergence per frame")
    ax.grid(True, which="both", alpha=0.3)
    if not drawn:
        ax.text(0.5, 0.5, "no iterations", ha="center", va="center", transform=ax.transAxes)
    elif many:
        fig.colorbar(ScalarMappable(norm, cmap), ax=ax, label="frame time")
    else:
        ax.legend(fontsize=8)
    ax.xaxis.get_major_locator().set_params(integer=True)
    return _png(fig)


def forces_png(frames: Sequence[FrameForces]) -> bytes:
    """``forces.png``: normal force per finger and the grip, and force per bone, over time.

    Parameters
    ----------
    frames : sequence of FrameForces
        In time order.

    Returns
    -------
    bytes
        The PNG.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10.0, 4.2), dpi=100)
    FigureCanvasAgg(fig)
    left, right = fig.subplots(1, 2)
    t = np.array([f.time for f in frames])
    style = {"marker": "o", "ms": 4, "lw": 1.5}
    names = list(dict.fromkeys(n for f in frames for n in f.fingers))
    idle = [n for n in names if not any(f.fingers.get(n, 0.0) > 0 for f in frames)]
    for k, name in enumerate(n for n in names if n not in idle):
        left.plot(
            t, [f.fingers.get(name, 0.0) for f in frames], color=f"C{k % 10}", label=name, **style
        )
    left.plot(t, [f.grip for f in frames], color="black", ls="--", label="grip force", **style)
    if idle:
        left.plot([], [], " ", label=f"no contact: {', '.join(idle)}")
    left.set_title("normal contact force per finger" if names else "grip force")
    left.set_ylabel("force (N)")
    bones = list(dict.fromkeys(n for f in frames for n in f.bones))
    peak = {b: max(f.bones.get(b, 0.0) for f in frames) for b in bones}
    most = max(peak.values(), default=0.0)
    carry = [b for b in bones if peak[b] > _SMALL * most]
    shown = sorted(carry, key=lambda b: -peak[b])[:_MAX_BONES]
    for k, name in enumerate(shown):
        right.plot(
            t, [f.bones.get(name, 0.0) for f in frames], color=f"C{k % 10}", label=name, **style
        )
    rest = [b for b in bones if b not in shown]
    if rest:
        top = max((peak[b] for b in rest), default=0.0)
        right.plot([], [], " ", label=f"{len(rest)} more, each <= {top:.3g} N")
    right.set_title("force on each bone (support)")
    for ax in (left, right):
        ax.set_xlabel("time (s)")
        ax.grid(True, alpha=0.3)
        ax.set_ylim(bottom=0.0)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
        else:
            ax.text(0.5, 0.5, "none", ha="center", va="center", transform=ax.transAxes)
    return _png(fig)
