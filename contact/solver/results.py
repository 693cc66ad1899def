"""What a contact solve returns: the state of every body and the history of the iteration."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

__all__ = ["ContactResult", "FrameResult", "FrictionReport", "IterationRecord"]


@dataclass(frozen=True)
class IterationRecord:
    """One iteration of a contact solve.

    Attributes
    ----------
    iteration : int
        1-based.
    n_contacts : int
        Constraints active in this iteration's solve (contact space: the rows it
        closed, of its candidates).
    added, released : int
        Contacts added (penetrating, or renewed after sliding off their facet) and
        released (pulling) after it; contact space: rows added after it, and rows its
        unilateral solve opened that the previous one had closed.
    max_change : float
        Largest change of a nodal displacement since the previous iteration (m).
    max_penetration : float
        Deepest penetration of a free node after the solve (m, >= 0).
    total_force : ndarray, shape (3,)
        Sum of the contact forces on the body (N); for several bodies, on the first one
        (the ball).
    normal_force : float
        Sum of the normal contact forces of every contact (N): for a ball squeezed
        between two plates, twice the squeeze.
    relaxation : float
        Relaxation factor applied to the Neumann side's answer (seed loop; 1 otherwise).
    max_support_force : float
        Largest support (bone) force magnitude after this iteration (N), 0 if none.
    """

    iteration: int
    n_contacts: int
    added: int
    released: int
    max_change: float
    max_penetration: float
    total_force: NDArray[np.float64]
    normal_force: float = 0.0
    relaxation: float = 1.0
    max_support_force: float = 0.0


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


@dataclass(frozen=True)
class FrictionReport:
    """Coulomb friction in a frame's last contact solve.

    Attributes
    ----------
    iterations : int
        Newton iterations of the frictional solves, summed over the frame's updates.
    residual : float
        Complementarity residual of the last solve (the Alart-Curnier natural map, over
        the frame's force scale): normal complementarity, the cone and stick or slip.
    tolerance : float
        The residual a solve must reach to count as solved.
    stick, slip : int
        Closed contacts that stick (inside their cone) and that slip (on its boundary).
    max_slip : float
        Largest tangential slip increment of a contact in this frame (m).
    max_cone_use : float
        Largest ``|t| / (mu n)`` of a closed frictional contact (1 on the cone).
    tangential_force : dict of str to ndarray
        Pair name -> total tangential force ``(3,)`` its slave nodes receive (N); a plane's
        pairs also appear under the plane's name as the force the bodies exert on it.
    """

    iterations: int
    residual: float
    tolerance: float
    stick: int
    slip: int
    max_slip: float
    max_cone_use: float
    tangential_force: dict[str, NDArray[np.float64]] = field(default_factory=dict)


@dataclass(frozen=True)
class FrameResult:
    """The outcome of the contact solve of one frame, for every body.

    A frame whose seed loop diverged (``stop_reason`` ``"diverged: ..."``) holds no
    figure of its last iterate, which solves nothing: its bodies at rest (zero
    displacements), no contacts, zero contact, plane and bone forces, ``over_limit``
    empty; only ``history`` keeps each iterate's figures (how it grew). A bone over its
    limit does not make a frame unconverged: it is solved as without the limit, and
    ``over_limit`` names the bone (the verdict calls the frame unrealistic).

    Attributes
    ----------
    converged : bool
        The contacts settled within the limits (a support force over its limit says
        nothing of this: see ``over_limit``).
    stop_reason : str
        ``"converged"``, ``"iteration limit"``, ``"cycling"``, ``"penetration left: ..."``
        (naming the node and the pair), ``"not held: ..."`` (a free body slid off its
        contacts, touches nothing at the end, or its loads are out of balance where no
        contact holds it: how far or how hard and which way), or the seed loop's
        ``"diverged: ..."`` (which node of which body moved how far) or ``"singular
        contact rows ..."``.
    algorithm : str
        ``"contact-space"`` or ``"seed"``.
    iterations : int
        Iterations performed (contact-set updates, or loops of seed steps 2 to 5).
    history : tuple of IterationRecord
        One record per iteration.
    displacement : dict of str to ndarray
        Body name -> ``(N, 3)`` nodal displacements (m).
    contact_force : dict of str to ndarray
        Body name -> ``(N, 3)`` contact force on each node (N).
    obstacle_forces : dict of str to ndarray
        Plane name -> force the bodies exert on it ``(3,)`` (N).
    support_forces : dict of str to dict of str to ndarray
        Body name -> support group (bone) -> force ``(3,)`` the support exerts on the body
        to hold it (N): what the musculature carries.
    over_limit : dict of str to tuple of float
        Support groups whose force magnitude passed its limit at the end: name ->
        (force, limit) (N); empty where none did, or the frame diverged.
    contacts : dict of str to ndarray
        The active contacts: ``pair`` (name per row), ``node`` (slave node), ``force``
        (normal force, N, positive pushes apart), ``normal`` ``(m, 3)``.
    max_penetration : float
        Deepest penetration of a slave node into its master at the end (m).
    penetration_ratio : float
        Largest penetration of a slave node over its local element size (the square
        root of its tributary area); the solver keeps it under ``gap_tolerance`` when
        it converges.
    separation_ratio : float
        Largest gap of a pushing contact's node at the end over its element size (0 where
        every pushing node touches): how far the linearised rows have drifted from the
        surfaces they stand for (see :meth:`contact.solver.frame.FrameState.separation`).
    timings : dict of str to float
        Seconds per phase.
    friction : FrictionReport or None
        Coulomb friction's figures, None where every pair is frictionless.
    held : bool or None
        Whether every free body is held (in balance under its contacts): False where
        ``stop_reason`` starts with ``"not held"``; None where the scene has no free
        body or the frame stopped for another reason.
    anchors : object or None
        Where each closed contact is anchored at the end of the frame, for Coulomb
        friction in the next (:class:`contact.solver.anchors.Anchors`; a stuck contact
        keeps its anchor, any other is anchored where it ended); None from the seed loop.
    slip_from : object or None
        The anchors this frame measured each frictional contact's slip from: those
        carried in and those met in the frame, each where it was first met, with the
        frame's starting placements (:class:`contact.solver.anchors.Anchors`); None
        without friction or where not asked for (``solve_frame``'s ``slip_from``).
        Newton's next linearisation of the same frame starts from them
        (:mod:`contact.solver.finite`), so that its friction law stays the frame's.
    contact_fields : dict of str to dict of str to ndarray
        Body name -> nodal fields of the contacts: ``normal_force`` ``(N,)`` (N),
        ``tangential_force`` ``(N, 3)`` (N), ``contact_status`` ``(N,)`` (0 none or open,
        1 stick, 2 slip; a frictionless closed contact slips), ``cone_use`` ``(N,)``
        (``|t| / (mu n)``, 0 where frictionless); the largest over a node's contacts.
    plane_positions : dict of str to ndarray
        Each plane's translation at the end (m, shape (3,)): its motion, and for a
        force-driven plane the distance the solve moved it along its normal.
    slip : dict or None
        Where friction does not hold a free body: ``body``, ``direction`` (unit, the way
        it slips), ``not_carried`` (the load its contacts leave, N) and ``available``
        (their friction, ``sum mu N``, N); None otherwise.
    below_grip : bool
        Its force-driven fingers stopped short of their forces, every one below its own
        (a force that jumps over it as a node enters the contact), the frame itself
        solved: what it says of holding holds for the forces asked, which are larger.
    """

    converged: bool
    stop_reason: str
    algorithm: str
    iterations: int
    history: tuple[IterationRecord, ...]
    displacement: dict[str, NDArray[np.float64]]
    contact_force: dict[str, NDArray[np.float64]]
    obstacle_forces: dict[str, NDArray[np.float64]]
    support_forces: dict[str, dict[str, NDArray[np.float64]]]
    over_limit: dict[str, tuple[float, float]]
    contacts: dict[str, NDArray]
    max_penetration: float
    penetration_ratio: float = 0.0
    separation_ratio: float = 0.0
    timings: dict[str, float] = field(default_factory=dict)
    friction: FrictionReport | None = None
    held: bool | None = None
    anchors: object | None = None
    slip_from: object | None = None
    contact_fields: dict[str, dict[str, NDArray]] = field(default_factory=dict)
    plane_positions: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    slip: dict | None = None
    below_grip: bool = False

    def total_contact_force(self, body: str) -> NDArray[np.float64]:
        """Sum of the contact forces on one body (N)."""
        return self.contact_force[body].sum(axis=0)
