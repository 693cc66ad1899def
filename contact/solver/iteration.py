"""The contact iteration of a frame: steps 2 to 5, by the algorithm the settings pick.

Both algorithms share the frame's state (:class:`contact.solver.frame.FrameState`) and
its geometry: step 2 (:mod:`contact.solver.pairs`) finds the slave nodes behind a plane
or inside another body's surface and takes, for each, a gap row along the master's normal
at its closest point (:mod:`contact.solver.rows`); a node in contact stays in contact
(contact memory) until its force pulls, and is then released
(:mod:`contact.solver.contactset`). Steps 3 to 5 are solved in contact space
(:mod:`contact.solver.contact_space`, the default) or as the literal Dirichlet-Neumann
loop of Gourret, Magnenat-Thalmann and Thalmann 1989 (:mod:`contact.solver.seed`).

Each body is factored once per frame (when its contact zone is marked); nothing is
refactored in the iteration.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

import fem

from ..errors import ContactError
from ..geometry.plane import Plane
from .anchors import Anchors
from .body import ElasticBody
from .contact_space import solve_contact_space
from .frame import FrameState
from .pairs import ContactPair
from .results import FrameResult, IterationRecord
from .seed import solve_seed
from .settings import ContactSettings
from .tangential import friction_zone

__all__ = ["solve_frame"]


def solve_frame(
    bodies: Sequence[ElasticBody],
    pairs: Sequence[ContactPair],
    planes: Sequence[Plane] = (),
    settings: ContactSettings | None = None,
    *,
    dirichlet: str | None = None,
    callback: Callable[[IterationRecord], None] | None = None,
    anchors: Anchors | None = None,
    search_from: dict[str, NDArray[np.float64]] | None = None,
    slip_from: bool = False,
    prox: dict[str, float] | None = None,
) -> FrameResult:
    """Resolve the contacts of one frame.

    Parameters
    ----------
    bodies : sequence of ElasticBody
        The deformable bodies (the first is the one whose total contact force the
        history records: the ball), each at its frame's reference position.
    pairs : sequence of ContactPair
        Which slave nodes touch which master (both directions between two bodies: two
        pairs).
    planes : sequence of Plane
        The rigid planes the pairs refer to, moved to the frame's position.
    settings : ContactSettings, optional
        Algorithm and tolerances.
    dirichlet : str, optional
        Seed loop: the body solved with its contacts prescribed (default the first).
    callback : callable, optional
        Called with each iteration's record as it is made (progress display).
    anchors : Anchors, optional
        Where each frictional contact stuck at the end of the previous frame (its
        ``FrameResult.anchors``): Coulomb's law acts on the slip since then. None: the
        first frame, every contact anchored where it is first found.
    search_from : dict of str to ndarray, optional
        Without friction, displacements ``(N, 3)`` of some bodies at which the first
        contact set is measured instead of at rest (see
        :func:`~contact.solver.contact_space.solve_contact_space`).
    slip_from : bool
        With friction, give the anchors the frame measured slip from
        (``FrameResult.slip_from``), for a Newton loop's next step of the same frame.
    prox : dict of str to float, optional
        With friction, springs on these free bodies' rigid modes, in the contacts'
        stiffness seen there: a Newton step's damping of bodies whose displacements are
        a step (:func:`contact.solver.finite.solve_finite_frame`).

    Returns
    -------
    FrameResult
        Never raises on non-convergence: ``converged`` is False and ``stop_reason`` says
        why, with the last state kept. A free body that no contact holds (its loads out
        of balance where nothing holds it, or touching nothing at the end) is such a
        result: ``stop_reason`` starts with ``"not held: "`` and ``held`` is False.

    Raises
    ------
    ContactError
        Bad settings, or friction with the seed loop.
    """
    settings = settings or ContactSettings()
    with fem.sparse_threads():  # the cores are PARDISO's: no spinning OpenBLAS workers
        frame = FrameState(bodies, planes, pairs, settings, callback=callback)
        try:
            frame.mark_zones(*friction_zone(frame, anchors))
            if settings.algorithm == "seed":
                if any(p.friction for p in pairs):
                    raise ContactError(
                        "the seed loop takes no friction: set solver.algorithm = "
                        '"contact-space" or every friction to 0'
                    )
                if frame.driven:
                    raise ContactError(
                        "the seed loop takes no force-driven plane: set solver.algorithm = "
                        '"contact-space"'
                    )
                return solve_seed(frame, dirichlet or frame.bodies[0].name)
            return solve_contact_space(frame, anchors, search_from, slip_from, prox)
        finally:
            # the contact set refers back to its frame: without the cycle, the frame's
            # bodies and factorisations go as soon as the caller lets them go
            del frame.contacts
