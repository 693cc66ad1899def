"""Shipped object surfaces (``can.stl``, ``cube.stl``) and the script that writes them.

Run ``python -m meshes.objects.make`` to regenerate them.
"""

from __future__ import annotations

__all__: list[str] = []
