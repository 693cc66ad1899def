"""Results folders: VTU/PVD series, staging, summary and verdicts, contact fields, pictures."""

from __future__ import annotations

from ..errors import OutputError
from ..rendering import rendering_available
from .pictures import (
    Picture,
    convergence_png,
    deformed_surface,
    render_pictures,
    write_gif_atomically,
)
from .staging import check_target, make_staging, swap_into_place, write_atomic
from .status import CONTACT_FIELDS, StatusMarkers, contact_point_data, status_markers
from .summary import frame_entry, friction_entry, jsonable, summary_text, verdict, versions
from .writer import STRESS_COMPONENTS, BodyFrame, ResultsWriter

__all__ = [
    "CONTACT_FIELDS",
    "STRESS_COMPONENTS",
    "BodyFrame",
    "OutputError",
    "Picture",
    "ResultsWriter",
    "StatusMarkers",
    "check_target",
    "contact_point_data",
    "convergence_png",
    "deformed_surface",
    "frame_entry",
    "friction_entry",
    "jsonable",
    "make_staging",
    "render_pictures",
    "rendering_available",
    "status_markers",
    "summary_text",
    "swap_into_place",
    "verdict",
    "versions",
    "write_atomic",
    "write_gif_atomically",
]
