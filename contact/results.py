"""What a contact solve returns: the state of every body and the history of the iteration."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

__all__ = ["ContactResult", "IterationRecord"]


@dataclass(frozen=True)
class IterationRecord:
    """One iteration of a contact solve.

    Attributes
    ----------
    iteration : int
        1-based.
    n_contacts : int
        Constraints active in this iteration's solve.
    added, released : int
        Contacts added (penetrating) and released (pulling) after it.
    max_change : float
        Largest change of a nodal displacement since the previous iteration (m).
    max_penetration : float
        Deepest penetration of a free node after the solve (m, >= 0).
    total_force : ndarray, shape (3,)
        Sum of the contact forces on the body (N).
    """

    iteration: int
    n_contacts: int
    added: int
    released: int
    max_change: float
    max_penetration: float
    total_force: NDArray[np.float64]


@dataclass(frozen=True)
class ContactResult:
    """The outcome of a contact solve of one frame.

    Attributes
    ----------
    converged : bool
        The contact set settled (no node to add or release) within the limits.
    stop_reason : str
        ``"converged"``, ``"iteration limit"``, ``"cycling"``, ...
    iterations : int
        Solves performed.
    history : tuple of IterationRecord
        One record per iteration.
    displacement : ndarray, shape (N, 3)
        Final displacement of the body.
    contact_force : ndarray, shape (N, 3)
        Contact force on each node of the body (N), zero off contact.
    obstacle_forces : dict of str to ndarray
        Force the body exerts on each obstacle (N): minus what it receives from it.
    contact_nodes : ndarray of int
        Nodes in contact at the end.
    max_penetration : float
        Deepest penetration left (m).
    timings : dict of str to float
        Seconds spent per phase.
    """

    converged: bool
    stop_reason: str
    iterations: int
    history: tuple[IterationRecord, ...]
    displacement: NDArray[np.float64]
    contact_force: NDArray[np.float64]
    obstacle_forces: dict[str, NDArray[np.float64]]
    contact_nodes: NDArray[np.int64]
    max_penetration: float
    timings: dict[str, float] = field(default_factory=dict)

    @property
    def total_contact_force(self) -> NDArray[np.float64]:
        """Sum of the contact forces on the body (N)."""
        return self.contact_force.sum(axis=0)
