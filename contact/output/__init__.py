"""Results folders: VTU/PVD series (writer), staging, the summary and verdicts, pictures."""

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
from .summary import frame_entry, jsonable, summary_text, verdict, versions
from .writer import STRESS_COMPONENTS, BodyFrame, ResultsWriter

__all__ = [
    "STRESS_COMPONENTS",
    "BodyFrame",
    "OutputError",
    "Picture",
    "ResultsWriter",
    "check_target",
    "convergence_png",
    "deformed_surface",
    "frame_entry",
    "jsonable",
    "make_staging",
    "render_pictures",
    "rendering_available",
    "summary_text",
    "swap_into_place",
    "verdict",
    "versions",
    "write_atomic",
    "write_gif_atomically",
]
