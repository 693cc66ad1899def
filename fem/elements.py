"""Reference elements: shape functions, their derivatives, quadrature and faces.

Node orderings follow VTK/meshio for ``tetra`` and ``hexahedron``. For ``wedge`` the
triangle ``(0, 1, 2)`` is the bottom face and ``(3, 4, 5)`` the top face, with node
``i + 3`` above node ``i`` and the bottom triangle counter-clockwise seen from the top
(positive Jacobian with the shape functions below). This is VTK's own wedge (checked
with VTK 9.7: positive cell volumes, the same outward faces); meshio 5.3 swaps wedge
nodes 1-2 and 4-5 when it reads and writes VTK files, which :mod:`fem.io` undoes.

Faces are listed with their nodes counter-clockwise seen from outside, so that the
right-hand normal of every face of a positively oriented element points outward.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "ELEMENTS",
    "HEX8",
    "TET4",
    "TRI_RULE5",
    "WEDGE6",
    "ReferenceElement",
    "face_quadrature",
]

_G = 1.0 / np.sqrt(3.0)


@dataclass(frozen=True)
class ReferenceElement:
    """A reference element: nodes, quadrature and faces.

    Attributes
    ----------
    name : str
        The meshio cell type name (``"tetra"``, ``"hexahedron"``, ``"wedge"``).
    n_nodes : int
        Number of nodes.
    points : ndarray, shape (n_quad, 3)
        Quadrature points in reference coordinates.
    weights : ndarray, shape (n_quad,)
        Quadrature weights (they sum to the reference volume).
    faces : tuple of tuple of int
        Local node indices of each face, outward oriented.
    mean_dilatation : bool
        The volumetric strain is the element's mean (B-bar, Hughes 1980): the
        deviatoric strain is integrated at every Gauss point, the dilatation once per
        element, so that the element does not lock as Poisson's ratio nears 1/2. For
        the multi-point elements (hexahedron, wedge); a linear tetrahedron's strain is
        constant already.
    """

    name: str
    n_nodes: int
    points: NDArray[np.float64]
    weights: NDArray[np.float64]
    faces: tuple[tuple[int, ...], ...]
    _shape: object = field(repr=False)
    _grad: object = field(repr=False)
    mean_dilatation: bool = False

    def shape(self, xi: NDArray[np.float64]) -> NDArray[np.float64]:
        """Shape functions at reference points ``xi (q, 3)``, shape ``(q, n_nodes)``."""
        return self._shape(np.atleast_2d(xi))  # type: ignore[operator]

    def grad(self, xi: NDArray[np.float64]) -> NDArray[np.float64]:
        """Reference gradients at ``xi (q, 3)``, shape ``(q, n_nodes, 3)``."""
        return self._grad(np.atleast_2d(xi))  # type: ignore[operator]

    @property
    def n_quad(self) -> int:
        """Number of quadrature points."""
        return len(self.weights)


# --- tetrahedron -----------------------------------------------------------------------


def _tet_shape(x: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.stack([1.0 - x[:, 0] - x[:, 1] - x[:, 2], x[:, 0], x[:, 1], x[:, 2]], axis=1)


def _tet_grad(x: NDArray[np.float64]) -> NDArray[np.float64]:
    g = np.array([[-1.0, -1.0, -1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    return np.broadcast_to(g, (len(x), 4, 3)).copy()


TET4 = ReferenceElement(
    name="tetra",
    n_nodes=4,
    points=np.array([[0.25, 0.25, 0.25]]),
    weights=np.array([1.0 / 6.0]),
    faces=((0, 2, 1), (0, 1, 3), (1, 2, 3), (0, 3, 2)),
    _shape=_tet_shape,
    _grad=_tet_grad,
)

# --- hexahedron ------------------------------------------------------------------------

_HEX_NODES = np.array(
    [
        [-1, -1, -1],
        [1, -1, -1],
        [1, 1, -1],
        [-1, 1, -1],
        [-1, -1, 1],
        [1, -1, 1],
        [1, 1, 1],
        [-1, 1, 1],
    ],
    dtype=float,
)


def _hex_shape(x: NDArray[np.float64]) -> NDArray[np.float64]:
    t = 1.0 + x[:, None, :] * _HEX_NODES[None, :, :]
    return 0.125 * t[..., 0] * t[..., 1] * t[..., 2]


def _hex_grad(x: NDArray[np.float64]) -> NDArray[np.float64]:
    t = 1.0 + x[:, None, :] * _HEX_NODES[None, :, :]
    s = _HEX_NODES[None, :, :]
    g = np.empty((len(x), 8, 3))
    g[..., 0] = 0.125 * s[..., 0] * t[..., 1] * t[..., 2]
    g[..., 1] = 0.125 * t[..., 0] * s[..., 1] * t[..., 2]
    g[..., 2] = 0.125 * t[..., 0] * t[..., 1] * s[..., 2]
    return g


HEX8 = ReferenceElement(
    name="hexahedron",
    n_nodes=8,
    points=np.array([[a, b, c] for c in (-_G, _G) for b in (-_G, _G) for a in (-_G, _G)]),
    weights=np.ones(8),
    faces=(
        (0, 3, 2, 1),
        (4, 5, 6, 7),
        (0, 1, 5, 4),
        (1, 2, 6, 5),
        (2, 3, 7, 6),
        (3, 0, 4, 7),
    ),
    _shape=_hex_shape,
    _grad=_hex_grad,
    mean_dilatation=True,
)

# --- wedge (triangular prism) ----------------------------------------------------------


def _wedge_shape(x: NDArray[np.float64]) -> NDArray[np.float64]:
    r, s, t = x[:, 0], x[:, 1], x[:, 2]
    a = 1.0 - r - s
    lo, hi = 0.5 * (1.0 - t), 0.5 * (1.0 + t)
    return np.stack([a * lo, r * lo, s * lo, a * hi, r * hi, s * hi], axis=1)


def _wedge_grad(x: NDArray[np.float64]) -> NDArray[np.float64]:
    r, s, t = x[:, 0], x[:, 1], x[:, 2]
    a = 1.0 - r - s
    lo, hi = 0.5 * (1.0 - t), 0.5 * (1.0 + t)
    g = np.empty((len(x), 6, 3))
    g[:, :, 0] = np.stack([-lo, lo, 0 * t, -hi, hi, 0 * t], axis=1)
    g[:, :, 1] = np.stack([-lo, 0 * t, lo, -hi, 0 * t, hi], axis=1)
    g[:, :, 2] = 0.5 * np.stack([-a, -r, -s, a, r, s], axis=1)
    return g


_TRI3 = np.array([[1 / 6, 1 / 6], [2 / 3, 1 / 6], [1 / 6, 2 / 3]])
WEDGE6 = ReferenceElement(
    name="wedge",
    n_nodes=6,
    points=np.array([[p[0], p[1], z] for z in (-_G, _G) for p in _TRI3]),
    weights=np.full(6, 1.0 / 6.0),
    faces=((0, 2, 1), (3, 4, 5), (0, 1, 4, 3), (1, 2, 5, 4), (2, 0, 3, 5)),
    _shape=_wedge_shape,
    _grad=_wedge_grad,
    mean_dilatation=True,
)

ELEMENTS: dict[str, ReferenceElement] = {e.name: e for e in (TET4, HEX8, WEDGE6)}
"""Supported volume elements keyed by meshio cell type name."""


_S15 = np.sqrt(15.0)
_A5, _B5 = (6 - _S15) / 21, (6 + _S15) / 21
#: A 7-point rule of degree 5 on a triangle: barycentric points ``(7, 3)`` and weights as
#: fractions of its area (Strang and Fix).
TRI_RULE5 = (
    np.array([[1 / 3, 1 / 3, 1 / 3], [_A5, _A5, 1 - 2 * _A5], [_A5, 1 - 2 * _A5, _A5],
              [1 - 2 * _A5, _A5, _A5], [_B5, _B5, 1 - 2 * _B5], [_B5, 1 - 2 * _B5, _B5],
              [1 - 2 * _B5, _B5, _B5]]),
    np.array([9 / 40] + [(155 - _S15) / 1200] * 3 + [(155 + _S15) / 1200] * 3),
)  # fmt: skip
_G3 = np.array([-np.sqrt(0.6), 0.0, np.sqrt(0.6)])
_W3 = np.array([5 / 9, 8 / 9, 5 / 9])


def face_quadrature(n_face_nodes: int, degree: int = 2) -> tuple[NDArray, NDArray, NDArray]:
    """Quadrature on a reference face.

    Parameters
    ----------
    n_face_nodes : int
        3 for a linear triangle, 4 for a bilinear quadrilateral.
    degree : int
        Polynomials up to this degree are integrated exactly: up to 2 on a triangle (3
        points) and 3 on a quadrilateral (2 x 2 Gauss points), up to 5 with 7 points and
        3 x 3 Gauss points.

    Returns
    -------
    N : ndarray, shape (q, n_face_nodes)
        Shape functions at the quadrature points.
    dN : ndarray, shape (q, n_face_nodes, 2)
        Their reference derivatives.
    w : ndarray, shape (q,)
        Weights (they sum to the reference area: 1/2 or 4).
    """
    if not 0 <= degree <= 5:
        raise ValueError(f"face quadrature of degree {degree!r}: 0 to 5")
    if n_face_nodes == 3:
        if degree <= 2:
            p = _TRI3
            n = np.stack([1 - p[:, 0] - p[:, 1], p[:, 0], p[:, 1]], axis=1)
            w = np.full(3, 1.0 / 6.0)
        else:
            n, w = TRI_RULE5[0].copy(), TRI_RULE5[1] / 2
        dn = np.array([[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]])
        return n, np.broadcast_to(dn, (len(n), 3, 2)).copy(), w
    if n_face_nodes == 4:
        c = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=float)
        g, gw = (np.array([-_G, _G]), np.ones(2)) if degree <= 3 else (_G3, _W3)
        p = np.array([[a, b] for b in g for a in g])
        t = 1.0 + p[:, None, :] * c[None]
        n = 0.25 * t[..., 0] * t[..., 1]
        dn = np.stack([0.25 * c[None, :, 0] * t[..., 1], 0.25 * t[..., 0] * c[None, :, 1]], axis=-1)
        return n, dn, np.outer(gw, gw).ravel()
    raise ValueError(f"faces with {n_face_nodes} nodes are not supported (3 or 4)")
