"""Results folders: VTU/PVD series, staging, summary and verdicts, contact fields, pictures."""

from __future__ import annotations

from ..errors import OutputError
from .forces import FrameForces, Push, frame_forces
from .framing import View, body_views, focus_box, grasp_axis, main_view
from .pictures import (
    BodyPicture,
    Picture,
    body_picture,
    deformed_surface,
    render_pictures,
    write_gif_atomically,
)
from .plainjson import jsonable, versions
from .plots import convergence_png, forces_png
from .rendering import rendering_available
from .staging import (
    MARKER,
    Staging,
    check_target,
    clean_leftovers,
    make_staging,
    swap_into_place,
    write_atomic,
)
from .status import CONTACT_FIELDS, StatusMarkers, contact_point_data, status_markers
from .summary import frame_entry, friction_entry, summary_text, verdict
from .vtufields import UNITS, add_field_data, units_name, write_body_vtu, write_pvd
from .writer import STRESS_COMPONENTS, BodyFrame, ResultsWriter

__all__ = [
    "CONTACT_FIELDS",
    "MARKER",
    "STRESS_COMPONENTS",
    "UNITS",
    "BodyFrame",
    "BodyPicture",
    "FrameForces",
    "OutputError",
    "Picture",
    "Push",
    "ResultsWriter",
    "Staging",
    "StatusMarkers",
    "View",
    "add_field_data",
    "body_picture",
    "body_views",
    "check_target",
    "clean_leftovers",
    "contact_point_data",
    "convergence_png",
    "deformed_surface",
    "focus_box",
    "forces_png",
    "frame_entry",
    "frame_forces",
    "friction_entry",
    "grasp_axis",
    "jsonable",
    "main_view",
    "make_staging",
    "render_pictures",
    "rendering_available",
    "status_markers",
    "summary_text",
    "swap_into_place",
    "units_name",
    "verdict",
    "versions",
    "write_atomic",
    "write_body_vtu",
    "write_gif_atomically",
    "write_pvd",
]
