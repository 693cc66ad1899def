"""Force-driven planes in a frame: where each one is, its part of the rows, its first press.

A force-driven plane (:attr:`contact.geometry.plane.Plane.force`) is a rigid body with one
mode, its translation along its normal, loaded by its force: the contact-space system
places it with the free bodies (:class:`contact.solver.delassus.ContactSpace`). This
module keeps what the frame knows of it between solves: its translation from its
``motion`` as last solved (the measure of step 2 looks there), its part ``E`` of the
rows, and the starting forces that put it in contact.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from ..geometry.plane import Plane
from .delassus import BodyState
from .pairs import ContactPair, measure
from .rows import ContactRows

__all__ = ["DrivenPlanes"]


class DrivenPlanes:
    """The frame's force-driven planes and their translations along their normals.

    Parameters
    ----------
    planes : sequence of Plane
        Every plane of the frame; those with a force are driven.
    pairs : sequence of ContactPair
        The frame's pairs.
    """

    def __init__(self, planes: Sequence[Plane], pairs: Sequence[ContactPair]) -> None:
        self.all = list(planes)
        self.planes = [pl for pl in planes if pl.force is not None]
        self.pairs = list(pairs)
        #: each driven plane's translation ``(1, 3)`` from its motion, as last solved
        self.shift = {pl.name: np.zeros((1, 3)) for pl in self.planes}

    def __iter__(self) -> Iterator[Plane]:
        return iter(self.planes)

    def __bool__(self) -> bool:
        return bool(self.planes)

    def _pairs_of(self, plane: Plane) -> list[int]:
        return [i for i, p in enumerate(self.pairs) if p.master is plane]

    def touch(self, u: Mapping[str, NDArray]) -> None:
        """Bring each driven plane that touches nothing to its nearest candidate node.

        Its translation is found with the contact forces, which need rows against it: a
        plane short of the bodies at ``u`` moves first to touch the nearest one.
        """
        for pl in self.planes:
            gaps = [measure(self.pairs[i], u, np.inf)[0].gap for i in self._pairs_of(pl)]
            nearest = float(np.min(np.concatenate(gaps), initial=np.inf)) if gaps else np.inf
            if np.isfinite(nearest) and nearest > 0:
                self.shift[pl.name] = nearest * pl.normal[None, :]

    def where(self, i: int, u: Mapping[str, NDArray]) -> Mapping[str, NDArray]:
        """``u`` for measuring pair ``i``: with its plane's translation where it is driven."""
        name = self.pairs[i].master.name
        return {**u, name: self.shift[name]} if name in self.shift else u

    def pressed(
        self, rows: ContactRows, start: NDArray[np.float64] | None
    ) -> NDArray[np.float64] | None:
        """Starting forces with each driven plane pressing on its nearest row.

        A plane none of whose rows pushes in ``start`` starts with its whole force on its
        row of least gap: the solve starts from the plane in contact (an open row does
        not move the plane, and a plane no row holds has no position).
        """
        if not self.planes or not len(rows):
            return start
        out = np.zeros(len(rows)) if start is None else np.array(start, dtype=np.float64)
        for pl in self.planes:
            mine = np.flatnonzero(np.isin(rows.pair, self._pairs_of(pl)))
            if mine.size and not (out[mine] > 0).any():
                out[mine[np.argmin(rows.g0[mine])]] = float(pl.force)  # type: ignore[arg-type]
        return out

    def moved(self, states: Mapping[str, BodyState]) -> None:
        """The driven planes' translations from a solve's ``states``."""
        for pl in self.planes:
            if pl.name in states:
                self.shift[pl.name] = states[pl.name].u.reshape(1, 3)

    def positions(self) -> dict[str, NDArray[np.float64]]:
        """Every plane's translation (m, shape (3,)): its motion, and a driven one's move."""
        zero = np.zeros((1, 3))
        return {pl.name: pl.motion + self.shift.get(pl.name, zero)[0] for pl in self.all}

    def matrices(self, rows: ContactRows) -> dict[str, sp.csr_matrix]:
        """Each driven plane's part ``E`` ``(m, 3)`` of the rows against it.

        A rigid master with one node: minus the row's direction (a plane that moves by
        ``d`` closes the row by its direction's component of ``d``).
        """
        m = len(rows)
        out = {}
        for pl in self.planes:
            r = np.flatnonzero(np.isin(rows.pair, self._pairs_of(pl))) if m else np.zeros(0, int)
            if r.size:
                out[pl.name] = sp.csr_matrix(
                    (-rows.normal[r].ravel(), (np.repeat(r, 3), np.tile(np.arange(3), r.size))),
                    shape=(m, 3),
                )
        return out
