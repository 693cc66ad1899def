"""Which part of the hand a flesh node or cell belongs to: the palm, the thumb or a finger.

The flesh's cell regions are the rig's hand parts (``skeleton.spec.groups``: palm 0, thumb
1, index 2, middle 3, ring 4, little 5 in the shipped rig). A node takes the part of most
of its cells, the lower part id on a tie, so that a node on the crease between a finger
and the palm belongs to one part only and per-part totals add up to the hand's.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

import fem

from .autoflex import FINGERTIPS, fingertip_node
from .shipped import Hand

__all__ = ["cell_parts", "fingertips", "node_parts", "part_letters"]


def cell_parts(mesh: fem.Mesh) -> dict[str, NDArray[np.int64]]:
    """The hand part of every cell, per cell type: the mesh's regions.

    Parameters
    ----------
    mesh : fem.Mesh
        The flesh, at rest or posed (posing keeps its cells and regions).

    Returns
    -------
    dict of str to ndarray of int64
        Cell type -> part id per cell (0 where the mesh has no regions for the type).
    """
    return {
        kind: np.asarray(mesh.regions.get(kind, np.zeros(len(conn))), dtype=np.int64)
        for kind, conn in mesh.cells.items()
    }


def node_parts(mesh: fem.Mesh, n_parts: int) -> NDArray[np.int64]:
    """The hand part of every node: the part of most of its cells.

    Parameters
    ----------
    mesh : fem.Mesh
        The flesh, at rest or posed.
    n_parts : int
        Number of parts (``len(hand.part_names)``).

    Returns
    -------
    ndarray of int64, shape (n_points,)
        Part id per node; ties go to the lower id, and a node in no cell is part 0.
    """
    counts = np.zeros((mesh.n_points, n_parts), dtype=np.int64)
    for kind, parts in cell_parts(mesh).items():
        conn = mesh.cells[kind]
        np.add.at(counts, (conn, np.repeat(parts[:, None], conn.shape[1], axis=1)), 1)
    return np.argmax(counts, axis=1).astype(np.int64)


def part_letters(names: tuple[str, ...] | list[str]) -> list[str]:
    """One upper-case letter per part for short reports (``P T I M R L``).

    The first letter of each name; where two names share it, the later ones take their
    first letter not yet used.
    """
    used: list[str] = []
    for name in names:
        letter = next((c.upper() for c in name if c.isalpha() and c.upper() not in used), "?")
        used.append(letter)
    return used


def fingertips(hand: Hand) -> dict[str, int]:
    """The tip node of every finger, by finger name.

    The tip is a skin node: the boundary node farthest along the finger's distal bone,
    among those nearest that bone's axis (:func:`contact.hand.autoflex.fingertip_node`).

    Parameters
    ----------
    hand : Hand

    Returns
    -------
    dict of str to int
        ``thumb``, ``index``, ``middle``, ``ring``, ``little`` -> flesh node.
    """
    return {finger: fingertip_node(hand, finger) for finger in FINGERTIPS}
