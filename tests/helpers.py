"""Helpers shared by the tests: distorted meshes, a mixed wedge-brick box, a plates scene,
round-off perturbations of the contact solve."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path

import numpy as np

import fem
from contact.solver.delassus import ContactSpace

ROOT = Path(__file__).resolve().parents[1]
#: The model of the shipped hand examples' flesh (and of the pinch's ball).
SHIPPED = 'model = "neo-hookean"'


def example(name: str, model: str | None = None) -> str:
    """The text of ``examples/<name>.toml``, its mesh paths absolute.

    ``model``: ``"linear"`` or ``"neo-hookean"`` on every material the example sets
    neo-Hookean (a test of the linear model's behaviour names it); None leaves it as
    shipped.
    """
    text = (ROOT / "examples" / f"{name}.toml").read_text()
    text = text.replace('"../meshes/', f'"{ROOT.as_posix()}/meshes/')
    if model is not None:
        assert SHIPPED in text, f"examples/{name}.toml has no neo-Hookean material"
        text = text.replace(SHIPPED, f'model = "{model}"')
    return text


def distort(mesh: fem.Mesh, amount: float, seed: int = 0, boundary: bool = True) -> fem.Mesh:
    """Move nodes randomly by up to ``amount`` times the smallest grid spacing."""
    rng = np.random.default_rng(seed)
    pts = mesh.points.copy()
    span = np.ptp(pts, axis=0)
    h = span.min() / max(4, round(len(pts) ** (1 / 3)))
    move = rng.uniform(-amount * h, amount * h, pts.shape)
    if not boundary:
        move[mesh.boundary.nodes] = 0.0
    return fem.Mesh(pts + move, mesh.cells, mesh.regions)


def mixed_mesh() -> fem.Mesh:
    """A 3x2x2 brick box: its left third split into wedges, the rest hexahedra; conforming."""
    box = fem.box_mesh((3.0, 2.0, 2.0), (3, 2, 2))
    hexes = box.cells["hexahedron"]
    left = box.points[hexes].mean(axis=1)[:, 0] < 1.0
    wedges = np.concatenate(
        [hexes[left][:, [0, 1, 2, 4, 5, 6]], hexes[left][:, [0, 2, 3, 4, 6, 7]]]
    )
    return fem.Mesh(
        box.points,
        {"hexahedron": hexes[~left], "wedge": wedges},
        {"hexahedron": np.zeros((~left).sum(), int), "wedge": np.ones(len(wedges), int)},
    )


#: A solid ball between a table and a plate that presses 2 mm by t = 1 (no hand): a scene
#: that runs in about a second.
PLATES = """\
[scene]
name = "plates"

[ball]
radius = 0.02
kind = "solid"
element = "hex"
mesh_size = {mesh_size}
center = [0.0, 0.0, 0.02]
material = {{ E = 1.0e6, nu = 0.3 }}

[[plane]]
name = "table"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]

[[plane]]
name = "plate"
point = [0.0, 0.0, 0.04]
normal = [0.0, 0.0, -1.0]
offsets = [[0.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, -0.002]]

[frames]
times = {times}

[solver]
max_iterations = {iterations}

[output]
directory = "{out}"
pictures = {pictures}
gif = {pictures}
"""


def plates_scene(
    path: Path,
    out: Path,
    *,
    mesh_size: float = 0.006,
    times: tuple[float, ...] = (0.5, 1.0),
    iterations: int = 30,
    pictures: bool = False,
) -> Path:
    """Write :data:`PLATES` to ``path``, its results folder ``out``; return ``path``."""
    text = PLATES.format(
        out=out.as_posix(), mesh_size=mesh_size, times=list(times), iterations=iterations,
        pictures=str(pictures).lower(),
    )  # fmt: skip
    path.write_text(text)
    return path


@contextmanager
def roundoff(seed: int, rel: float = 1e-15) -> Iterator[None]:
    """Perturb every contact-space system by relative noise ``rel``: compliance, gaps, loads.

    What another CPU's or thread count's round-off does to the same problem: a result
    that changes its verdict or its motion under it depends on the machine.
    """
    rng = np.random.default_rng(seed)
    original = ContactSpace.system

    def noisy(self, e, g0):
        sys_ = original(self, e, g0)
        noise = rng.uniform(-rel, rel, sys_.w.shape)
        w = sys_.w * (1.0 + (noise + noise.T) / 2)  # still symmetric
        rhs = sys_.rhs * (1.0 + rng.uniform(-rel, rel, sys_.rhs.shape))
        c = sys_.c * (1.0 + rng.uniform(-rel, rel, sys_.c.shape))
        return replace(sys_, w=w, rhs=rhs, c=c)

    ContactSpace.system = noisy
    try:
        yield
    finally:
        ContactSpace.system = original


def same_outcome(a, b, rtol: float = 1e-8) -> None:
    """Assert two frame results give the same verdict and the same motion to ``rtol``.

    Held: the same displacements. Not held: the same slip (the way, the load not carried);
    the last iterate of a solve that found no balance is no motion to compare.
    """
    assert (a.converged, a.held, a.stop_reason) == (b.converged, b.held, b.stop_reason)
    if a.slip is not None or b.slip is not None:
        assert a.slip["body"] == b.slip["body"] and a.slip["turns"] == b.slip["turns"]
        assert np.allclose(a.slip["direction"], b.slip["direction"], rtol=0, atol=1e-6)
        assert abs(a.slip["not_carried"] - b.slip["not_carried"]) <= 1e-6 * a.slip["available"]
        return
    for name, u in a.displacement.items():
        scale = max(float(np.abs(u).max()), 1e-300)
        assert np.abs(b.displacement[name] - u).max() <= rtol * scale, name


def uniaxial_stress(lam: float, mu: float, stretch: float) -> tuple[float, float]:
    """The neo-Hookean law's uniaxial stress at axial ``stretch``: the lateral stretch
    (free sides) and the axial first Piola-Kirchhoff stress ``P33`` (Pa)."""
    from scipy.optimize import brentq

    def p11(s: float) -> float:
        return mu * (s - 1 / s) + lam * np.log(s * s * stretch) / s

    side = brentq(p11, 0.5, 2.0, xtol=1e-15)
    j = side * side * stretch
    return side, mu * (stretch - 1 / stretch) + lam * np.log(j) / stretch
