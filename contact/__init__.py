"""contact: the grasp of a deformable ball by a hand (geometry, contact, rig, scenes, CLI).

Built on :mod:`fem`; the modules arrive with the issues that follow the FE core.
"""

from __future__ import annotations

__all__: list[str] = []
