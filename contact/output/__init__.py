"""Results folders: VTU/PVD series, the summary and verdicts, pictures."""

from __future__ import annotations

from .writer import (
    STRESS_COMPONENTS,
    BodyFrame,
    OutputError,
    ResultsWriter,
    rendering_available,
    verdict,
    versions,
)

__all__ = [
    "STRESS_COMPONENTS",
    "BodyFrame",
    "OutputError",
    "ResultsWriter",
    "rendering_available",
    "verdict",
    "versions",
]
