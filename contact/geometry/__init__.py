"""Stateless geometry: rigid planes, closest points on triangle surfaces, surface helpers."""

from __future__ import annotations

from ..errors import SurfaceError
from .closestkernels import LEAF, TIE, build_tree, closest_faces, facet_cross, refit
from .plane import Plane, tributary_areas
from .surfacequery import WINDING_THRESHOLD, TriangleSurface
from .surfaces import (
    check_closed_surface,
    count_pieces,
    enclosed_volume,
    poly_from_arrays,
    self_intersections,
    surface_arrays,
)
from .triangles import (
    DEGENERATE_TOL,
    Closest,
    closest_on_triangles,
    degenerate_triangles,
    surface_of_mesh,
)

__all__ = [
    "DEGENERATE_TOL",
    "LEAF",
    "TIE",
    "WINDING_THRESHOLD",
    "Closest",
    "Plane",
    "SurfaceError",
    "TriangleSurface",
    "build_tree",
    "check_closed_surface",
    "closest_faces",
    "closest_on_triangles",
    "count_pieces",
    "degenerate_triangles",
    "enclosed_volume",
    "facet_cross",
    "poly_from_arrays",
    "refit",
    "self_intersections",
    "surface_arrays",
    "surface_of_mesh",
    "tributary_areas",
]
