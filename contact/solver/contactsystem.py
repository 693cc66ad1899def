"""What a contact solve answers with: a row set's system in contact space, a body's state."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["BodyState", "ContactSystem"]


@dataclass(frozen=True)
class BodyState:
    """A body's answer to its loads and contact forces.

    Attributes
    ----------
    u : ndarray, shape (n_dofs,)
        Displacements.
    reactions : ndarray, shape (n_dofs,)
        Support reactions at the prescribed DOFs (zero elsewhere).
    rigid : ndarray
        Rigid-mode amplitudes of a free body (empty otherwise).
    """

    u: NDArray[np.float64]
    reactions: NDArray[np.float64]
    rigid: NDArray[np.float64]


@dataclass(frozen=True)
class ContactSystem:
    """The contact-space system ``[[W, G], [G^T, -H]] [lam; a] = [rhs; c]`` of a row set.

    Attributes
    ----------
    w : ndarray, shape (m, m)
        Delassus operator.
    g : ndarray, shape (m, r)
        The rows' values of the free bodies' placing modes (a bordered body's eighteen
        columns, :meth:`fem.TurningInverse.extended`) and of the force-driven planes'.
    rhs : ndarray, shape (m,)
        ``-(g0 + sum_b E_b u0_b)``.
    c : ndarray, shape (r,)
        Minus the free bodies' loads in their modes (a border's, as ``g``).
    free : tuple of str
        The free bodies.
    load_scale : float
        Size of the free bodies' loads.
    h : ndarray, shape (r, r), optional
        The modes' stiffness (zero but for bodies that turn with their stiffness).
    aux : ndarray of bool, shape (r,), optional
        The amplitudes that are a border's auxiliaries, not a body's modes
        (:meth:`fem.TurningInverse.extended`).
    prox : ndarray, shape (r,), optional
        Springs on the amplitudes, in the contacts' stiffness seen in the modes
        (:attr:`contact.solver.natural_map.NaturalMap.unit`): a Newton step's damping of
        the free finite bodies' steps (zero on a border's auxiliaries and on planes).
    """

    w: NDArray[np.float64]
    g: NDArray[np.float64]
    rhs: NDArray[np.float64]
    c: NDArray[np.float64]
    free: tuple[str, ...]
    load_scale: float
    h: NDArray[np.float64] | None = None
    aux: NDArray[np.bool_] | None = None
    prox: NDArray[np.float64] | None = None

    @property
    def mode_rows(self) -> NDArray[np.float64] | None:
        """``H`` in the rows' units (times the mean compliance), None where it is zero.

        What holds the modes besides ``G``'s rows (:meth:`ContactSpace.gauged`).
        """
        if self.h is None or not self.h.any():
            return None
        return self.h * float(np.mean(np.diag(self.w))) if self.w.size else self.h
