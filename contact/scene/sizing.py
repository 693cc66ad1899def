"""A scene's size before anything is allocated: nodes, elements, frames and memory.

The loader (:func:`contact.scene.load_scene`) estimates what a scene will build from its
keys alone, so that a ball meshed far too finely or a frame count far too large is refused
in a fraction of a second with the estimate, instead of exhausting the machine's memory
minutes later. The ball's bricks are counted exactly from the cubed-sphere generators
(:func:`fem.ball_mesh`, :func:`fem.shell_mesh` with the divisions of
:func:`contact.objects.ball.make_ball`); its tetrahedra are bounded from the volume (fTetWild's
count moves in steps with the edge length: about 0.5 to 1 times the bound); the hand is
fixed by its resolution. The memory is a per-DOF figure for assembly and sparse
factorisation, grown with the cube root of the DOFs above a reference size (the fill of
a nested-dissection factorisation of a 3-D mesh grows faster than the DOFs).

An object's fill (:func:`fill_size`) is estimated from its target edge, not from the
surface it is given: fTetWild remeshes the surface within its envelope, so that a scan of
millions of triangles fills to as few tetrahedra as a smooth surface of the same shape.
What the input costs is fTetWild's own memory and time, a figure per input triangle.
"""

from __future__ import annotations

import logging
import math
import os
from dataclasses import dataclass
from pathlib import Path

from ..objects.ball import BallSpec

__all__ = [
    "BASE_BYTES",
    "BYTES_PER_DOF",
    "BYTES_PER_FRAME",
    "ENVELOPE",
    "FILL_BYTES_PER_TRIANGLE",
    "HAND_SIZE",
    "LARGE_SURFACE",
    "MAX_FRAMES",
    "REFERENCE_DOFS",
    "SURFACE_NODES_PER_H2",
    "TETS_PER_NODE",
    "TET_ELEMENTS_PER_H3",
    "WARN_DOFS",
    "WARN_FRAMES",
    "FillSize",
    "SceneSize",
    "available_memory",
    "ball_size",
    "body_memory",
    "estimate",
    "fill_size",
    "format_bytes",
]

log = logging.getLogger(__name__)

#: Upper bound of fTetWild's tetrahedra per ``mesh_size**3`` of volume (a regular mesh
#: of that edge has 8.5; fTetWild's count moves in steps up to this).
TET_ELEMENTS_PER_H3 = 16.0
#: Tetrahedra per interior node of a tetrahedral mesh.
TETS_PER_NODE = 6.0
#: Upper bound of fTetWild's surface nodes per ``area / edge**2`` (a regular triangulation
#: has 1.15; unoptimised fills of spheres reach 16).
SURFACE_NODES_PER_H2 = 16.0
#: fTetWild's default envelope: how far (a fraction of the bounding-box diagonal) its
#: surface may lie from the input; it bounds the surface edge on curved parts.
ENVELOPE = 1e-3
#: fTetWild's peak memory (bytes) per input triangle, about four times the measured.
FILL_BYTES_PER_TRIANGLE = 2.0e3
#: Input triangles above which a fill takes minutes: better simplified first.
LARGE_SURFACE = 200_000
#: Nodes and elements of the shipped hand's flesh per resolution.
HAND_SIZE = {"coarse": (4419, 15355), "fine": (21041, 90177)}
#: Peak memory (bytes) per DOF of a body's assembly and factorisation up to
#: :data:`REFERENCE_DOFS`: above the peaks (VmHWM) measured on bricks and on tetrahedra with
#: nodal pressures, so that the refusal errs on the safe side.
BYTES_PER_DOF = 20.0e3
#: Above this many DOFs the per-DOF figure grows as the cube root of the DOFs.
REFERENCE_DOFS = 250_000
#: The interpreter, the libraries and the hand's rig, before any body.
BASE_BYTES = 400.0e6
#: What one frame keeps in memory (its record, the plots' series), rounded up.
BYTES_PER_FRAME = 64.0e3
#: A frame count no run can finish in reasonable time: refused whatever the memory.
MAX_FRAMES = 100_000
#: Above this many frames, or a body above :data:`WARN_DOFS`, the loader warns.
WARN_FRAMES = 1000
#: A body's DOFs above which a factorisation takes minutes and gigabytes: a warning.
WARN_DOFS = 300_000


@dataclass(frozen=True)
class SceneSize:
    """What a scene will build, estimated from its keys.

    Attributes
    ----------
    ball_nodes, ball_elements : int
        The ball's mesh (0 for a mesh file: its size on disk bounds it).
    hand_nodes, hand_elements : int
        The hand's flesh (0 without a hand).
    frames : int
    memory : float
        Peak memory (bytes), conservative.
    """

    ball_nodes: int
    ball_elements: int
    hand_nodes: int
    hand_elements: int
    frames: int
    memory: float

    def describe(self) -> str:
        """One phrase: the ball's nodes and elements, the frames and the memory."""
        return (
            f"about {_count(self.ball_nodes)} nodes and {_count(self.ball_elements)} elements "
            f"in the ball, {_count(self.frames)} frames, {format_bytes(self.memory)} of memory"
        )


def _count(n: float) -> str:
    return f"{n:.3g}" if n >= 1e6 else f"{int(n)}"


def format_bytes(b: float) -> str:
    """``b`` bytes in kB, MB, GB or TB, three digits."""
    for unit, size in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if b >= size:
            return f"{b / size:.3g} {unit}"
    return f"{b / 1e3:.3g} kB"


def _cube_sphere(n: float, layers: float) -> float:
    """Nodes of ``layers`` cubed-sphere shells of ``n`` cells a face edge."""
    return layers * (6.0 * n * n + 2.0)


def ball_size(spec: BallSpec) -> tuple[float, float]:
    """The ball's nodes and elements estimated from its spec (floats: they may be huge).

    Parameters
    ----------
    spec : BallSpec
        With ``mesh_size`` (a mesh file gives ``(0, 0)``).

    Returns
    -------
    (float, float)
        Nodes and elements: exact for bricks, an upper bound for tetrahedra.
    """
    if spec.mesh_size is None:
        return 0.0, 0.0
    r, a = spec.radius, spec.inner_radius
    # below a millionth of the radius the count is beyond any machine: the bound keeps
    # the arithmetic finite
    h = max(float(spec.mesh_size), 1e-6 * r)
    if spec.element == "hex":  # the divisions of contact.objects.ball._generate
        n = 2.0 * math.ceil(0.25 * math.pi * r / h - 1e-9)
        if spec.kind == "solid":
            layers = max(1.0, math.ceil((r - 0.6 * r) / h - 1e-9))
            return (n + 1) ** 3 + _cube_sphere(n, layers), n**3 + 6.0 * n * n * layers
        layers = max(2.0, math.ceil((r - a) / h - 1e-9))
        return _cube_sphere(n, layers + 1), 6.0 * n * n * layers
    volume = 4.0 / 3.0 * math.pi * (r**3 - a**3)
    elements = TET_ELEMENTS_PER_H3 * volume / h**3
    surface = sum(_icosphere_nodes(s, h) for s in (r, a) if s > 0)
    return elements / TETS_PER_NODE + surface, elements


def _icosphere_nodes(radius: float, size: float) -> float:
    """Nodes of the icosphere :func:`contact.objects.ball.make_ball` fills: edges below ``size``."""
    edge = 4.0 / math.sqrt(10.0 + 2.0 * math.sqrt(5.0))  # icosahedron edge / circumradius
    k = min(6, max(2, math.ceil(math.log2(edge * radius / size))))
    return 10.0 * 4.0**k + 2.0


def body_memory(dofs: float) -> float:
    """Peak bytes of assembling and factoring a body of ``dofs`` DOFs."""
    return BYTES_PER_DOF * dofs * max(1.0, dofs / REFERENCE_DOFS) ** (1.0 / 3.0)


def estimate(ball: BallSpec | None, hand_resolution: str | None, frames: int) -> SceneSize:
    """The scene's size and peak memory.

    Parameters
    ----------
    ball : BallSpec or None
        None: no ball (the ``[[object]]`` meshes are checked as they are read).
    hand_resolution : str or None
        ``hand.resolution``; None without a hand.
    frames : int

    Returns
    -------
    SceneSize
    """
    nodes, elements = ball_size(ball) if ball is not None else (0, 0)
    hn, he = HAND_SIZE.get(hand_resolution, (0, 0)) if hand_resolution else (0, 0)
    if ball is None:
        memory_ball = 0.0
    elif ball.mesh is not None:  # a mesh file: some hundred bytes a node on disk
        memory_ball = body_memory(3.0 * Path(ball.mesh).stat().st_size / 100.0)
    else:
        memory_ball = body_memory(3.0 * nodes)
    memory = BASE_BYTES + memory_ball + body_memory(3.0 * hn) + BYTES_PER_FRAME * frames
    return SceneSize(int(min(nodes, 1e18)), int(min(elements, 1e18)), hn, he, frames, memory)


@dataclass(frozen=True)
class FillSize:
    """What an object's fill will build, estimated from its surface's shape and the edge.

    Attributes
    ----------
    nodes : float
        Nodes of the tetrahedra (an upper bound).
    memory : float
        Peak memory (bytes) of the fill and of the body it makes, conservative.
    fill_memory : float
        fTetWild's part of it, set by the input's triangles.
    triangles : float
        Triangles the surface needs at this edge: what a simplified input may keep.
    """

    nodes: float
    memory: float
    fill_memory: float
    triangles: float


def fill_size(
    volume: float,
    area: float,
    diagonal: float,
    n_triangles: int,
    mesh_size: float,
    envelope: float = ENVELOPE,
) -> FillSize:
    """The size of fTetWild's fill of a closed surface at the target edge ``mesh_size``.

    Parameters
    ----------
    volume, area : float
        The surface's enclosed volume (m^3) and area (m^2).
    diagonal : float
        Its bounding box's diagonal (m).
    n_triangles : int
        The input's triangles (fTetWild's own memory).
    mesh_size : float
        Target tetrahedron edge (m).
    envelope : float
        fTetWild's ``epsilon``: the surface edge on curved parts is at most about
        ``diagonal * sqrt(2 envelope)`` (a chord within the envelope of a curvature
        radius a quarter of the diagonal), whatever the target.

    Returns
    -------
    FillSize
    """
    h = max(float(mesh_size), 1e-6 * diagonal)
    edge = min(h, diagonal * math.sqrt(2.0 * envelope))
    nodes = TET_ELEMENTS_PER_H3 * volume / h**3 / TETS_PER_NODE
    nodes += SURFACE_NODES_PER_H2 * area / edge**2
    fill = FILL_BYTES_PER_TRIANGLE * n_triangles
    memory = BASE_BYTES + max(fill, body_memory(3.0 * nodes))  # fTetWild's freed before
    return FillSize(nodes, memory, fill, 4.0 * area / (0.433 * edge**2))


def available_memory() -> float | None:
    """The memory (bytes) this process may still take: the machine's, within its cgroup.

    ``MemAvailable`` of ``/proc/meminfo`` (else the free physical pages), less what the
    cgroup's ``memory.max`` leaves; None where neither can be read.
    """
    avail = None
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    avail = float(line.split()[1]) * 1024.0
                    break
    except OSError:
        pass
    if avail is None:
        try:
            avail = float(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
        except (ValueError, OSError, AttributeError):
            return None
    try:
        root = Path("/sys/fs/cgroup")
        limit = (root / "memory.max").read_text().strip()
        if limit != "max":
            used = float((root / "memory.current").read_text().strip())
            avail = min(avail, float(limit) - used)
    except (OSError, ValueError):
        pass
    return avail
