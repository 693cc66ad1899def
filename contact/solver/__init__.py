"""The contact solver: steps 2 to 5 of a frame.

Contact pairs and rows (steps 2 and 4), the contact-space and seed iterations (steps 3
to 5), the Delassus operator and the unilateral solve.
"""

from __future__ import annotations

from .body import ElasticBody
from .delassus import BodyState, ContactSpace, ContactSystem
from .iteration import ALGORITHMS, LCP_TOLERANCE, RELAXATIONS, ContactSettings, solve_frame
from .lcp import REFACTOR, REPEATS, LcpResult, solve_lcp
from .mortar import MortarCoupling, mortar_coupling
from .pairs import (
    ContactPair,
    ContactRows,
    MortarCandidates,
    Penetrations,
    Survey,
    measure,
    mortar_candidates,
)
from .results import ContactResult, FrameResult, IterationRecord
from .zone import APPROACH, RING, master_zone, slave_zone

__all__ = [
    "ALGORITHMS",
    "APPROACH",
    "LCP_TOLERANCE",
    "REFACTOR",
    "RELAXATIONS",
    "REPEATS",
    "RING",
    "BodyState",
    "ContactPair",
    "ContactResult",
    "ContactRows",
    "ContactSettings",
    "ContactSpace",
    "ContactSystem",
    "ElasticBody",
    "FrameResult",
    "IterationRecord",
    "LcpResult",
    "MortarCandidates",
    "MortarCoupling",
    "Penetrations",
    "Survey",
    "master_zone",
    "measure",
    "mortar_candidates",
    "mortar_coupling",
    "slave_zone",
    "solve_frame",
    "solve_lcp",
]
