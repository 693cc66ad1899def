"""The contact solver's settings: the one source of their defaults and checks.

The scene reader builds a :class:`ContactSettings` from the ``[solver]`` table and adds
the key path to its errors; nothing else repeats a default or a check.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

from ..errors import ContactError

__all__ = ["ALGORITHMS", "GAPS", "RELAXATIONS", "ContactSettings"]

#: Contact algorithms by name.
ALGORITHMS = ("contact-space", "seed")
#: Relaxations of the seed loop.
RELAXATIONS = ("none", "fixed", "aitken")
#: How an object's gaps are measured: at its nodes, or weighted over its faces.
GAPS = ("nodal", "weighted")


@dataclass(frozen=True)
class ContactSettings:
    """Settings of the contact iteration.

    Parameters
    ----------
    algorithm : {"contact-space", "seed"}
        ``"contact-space"`` (:mod:`contact.solver.contact_space`) or the seed's literal
        Dirichlet-Neumann loop (:mod:`contact.solver.seed`).
    max_iterations : int
        Limit on the iterations (>= 1).
    tolerance : float
        Seed loop: converged when the largest change of a nodal displacement between two
        iterations is at most this fraction of the largest displacement (> 0).
    gap_tolerance : float
        A node is penetrating when it is inside its master by more than this fraction of
        its local element size (square root of its tributary area); at the start, nodes
        that touch within it are taken in contact (> 0).
    force_tolerance : float
        Seed loop: a contact is released when it pulls by more than this fraction of
        the largest contact force (>= 0). Contact space opens every row that would pull
        (its unilateral solve: forces below 1e-10 of the scale of its gaps are round-off).
    relaxation : {"none", "fixed", "aitken"}
        Relaxation of the seed loop's step 5.
    relaxation_factor : float
        The fixed factor, and Aitken's first one, in (0, 1].
    gaps : {"nodal", "weighted"}
        How an object's gaps are measured: at its surface nodes, or weighted over its
        faces, against a plane on its smoothed surface
        (:mod:`contact.solver.planemortar`), which resolves a patch smaller than the
        faces, and against another object by one mortar pair, with friction too
        (:mod:`contact.solver.mortar`). The hand keeps its node rows.
    support_limits : mapping of str to float, optional
        Largest force (N) each support group (bone) may carry; a frame whose force passes
        it is reported over the limit (``FrameResult.over_limit``), its solve unchanged.
        Groups not named have no limit.

    Raises
    ------
    ContactError
        On a setting out of its range, naming it as ``solver.<key>``.
    """

    algorithm: str = "contact-space"
    max_iterations: int = 50
    tolerance: float = 1e-4
    gap_tolerance: float = 1e-3
    force_tolerance: float = 1e-9
    relaxation: str = "none"
    relaxation_factor: float = 0.5
    gaps: str = "nodal"
    support_limits: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.algorithm not in ALGORITHMS:
            raise ContactError(
                f"solver.algorithm must be one of {', '.join(ALGORITHMS)}, got {self.algorithm!r}"
            )
        if self.relaxation not in RELAXATIONS:
            raise ContactError(
                f"solver.relaxation must be one of {', '.join(RELAXATIONS)}, "
                f"got {self.relaxation!r}"
            )
        if self.gaps not in GAPS:
            raise ContactError(f"solver.gaps must be one of {', '.join(GAPS)}, got {self.gaps!r}")
        if not isinstance(self.max_iterations, int) or self.max_iterations < 1:
            raise ContactError(
                f"solver.max_iterations must be an integer >= 1, got {self.max_iterations!r}"
            )
        for key in ("tolerance", "gap_tolerance"):
            v = getattr(self, key)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ContactError(f"solver.{key} must be a positive number, got {v!r}")
        if not (math.isfinite(self.force_tolerance) and self.force_tolerance >= 0):
            raise ContactError(f"solver.force_tolerance must be >= 0, got {self.force_tolerance!r}")
        if not (0 < self.relaxation_factor <= 1):
            raise ContactError(
                f"solver.relaxation_factor must lie in (0, 1], got {self.relaxation_factor!r}"
            )
        for k, v in self.support_limits.items():
            if not (isinstance(v, (int, float)) and v > 0):
                raise ContactError(f"bone force limit of {k!r} must be positive, got {v!r}")
