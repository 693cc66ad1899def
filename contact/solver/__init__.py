"""The contact solver: steps 2 to 5 of a frame.

Step 2, repel: contact pairs and their penetrations (:mod:`.pairs`); step 4, dispatch:
the contact rows ``E_b`` (:mod:`.rows`); the contact set they form (:mod:`.contactset`);
steps 3 to 5 in contact space (:mod:`.contact_space`, with the Delassus operator of
:mod:`.delassus` and the unilateral solve of :mod:`.lcp`) or as the seed's
Dirichlet-Neumann loop (:mod:`.seed`); :func:`solve_frame` picks one (:mod:`.iteration`).
Coulomb friction: tangential rows against stick anchors (:mod:`.tangential`,
:mod:`.anchors`), solved with the normal rows by a semismooth Newton method
(:mod:`.friction`).
"""

from __future__ import annotations

from .anchors import Anchors
from .body import ElasticBody
from .contact_space import LCP_TOLERANCE
from .contactset import ContactSet
from .delassus import BodyState, ContactSpace, ContactSystem
from .frame import FrameState
from .friction import FrictionResult, solve_friction
from .iteration import solve_frame
from .lcp import REFACTOR, REPEATS, LcpResult, solve_lcp
from .mortar import MortarCoupling, mortar_coupling
from .pairs import ContactPair, Penetrations, Survey, measure
from .results import ContactResult, FrameResult, FrictionReport, IterationRecord
from .rows import ContactRows, MortarCandidates, mortar_candidates
from .settings import ALGORITHMS, RELAXATIONS, ContactSettings
from .tangential import Friction, tangent_basis
from .zone import APPROACH, RING, master_zone, slave_zone

__all__ = [
    "ALGORITHMS",
    "APPROACH",
    "LCP_TOLERANCE",
    "REFACTOR",
    "RELAXATIONS",
    "REPEATS",
    "RING",
    "Anchors",
    "BodyState",
    "ContactPair",
    "ContactResult",
    "ContactRows",
    "ContactSet",
    "ContactSettings",
    "ContactSpace",
    "ContactSystem",
    "ElasticBody",
    "FrameResult",
    "FrameState",
    "Friction",
    "FrictionReport",
    "FrictionResult",
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
    "solve_friction",
    "solve_lcp",
    "tangent_basis",
]
