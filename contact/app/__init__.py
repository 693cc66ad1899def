"""The command line's pieces: its exit-status guard, report lines, pose-only run, lost bodies.

``python -m contact.grasp`` (:mod:`contact.grasp`) puts them together.
"""

from __future__ import annotations

__all__: list[str] = []
