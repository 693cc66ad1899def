"""Shipped meshes and rigs (``meshes/hand/``) and the script that rebuilds them.

Run ``python -m meshes.build`` to regenerate the hand from ``meshes/hand/rig.toml``.
"""

from __future__ import annotations

__all__: list[str] = []
