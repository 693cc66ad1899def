"""Contact fields in the results: the VTU point data of every body and the stick/slip picture.

Every body of every frame carries four point arrays in its ``.vtu`` file, taken from
:attr:`contact.solver.results.FrameResult.contact_fields`, zeros of the right shape where
the result has none for the body:

- ``normal_force`` ``(N,)``: normal contact force on the node (N);
- ``tangential_force`` ``(N, 3)``: tangential (friction) force on the node (N);
- ``contact_status`` ``(N,)``: 0 none or open, 1 stick, 2 slip (a frictionless closed
  contact slips);
- ``cone_use`` ``(N,)``: ``|t| / (mu n)``, 1 on the Coulomb cone, 0 where frictionless.

A frame with friction also gets a picture of its contact nodes coloured by status on the
deformed bodies (:func:`draw_status`); :mod:`contact.output.pictures` renders it beside
the stress picture, with the same camera.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    import pyvista

__all__ = [
    "CONTACT_FIELDS",
    "OPEN",
    "SLIP",
    "STICK",
    "StatusMarkers",
    "contact_point_data",
    "draw_status",
    "status_markers",
]

#: Values of ``contact_status``.
OPEN, STICK, SLIP = 0, 1, 2
#: The contact point arrays and the trailing shape of each (``()`` for a scalar).
CONTACT_FIELDS: dict[str, tuple[int, ...]] = {
    "normal_force": (),
    "tangential_force": (3,),
    "contact_status": (),
    "cone_use": (),
}
#: Marker colours, legible on white and against the grey bodies (also to most
#: colour-blind readers: blue against orange).
_COLOURS = {STICK: "#1f77b4", SLIP: "#ff7f0e"}
_LABELS = {STICK: "stick", SLIP: "slip"}
#: Largest opacity of a body in the status picture: contacts lie between bodies, and must
#: show through them.
_BODY_OPACITY = 0.3


@dataclass(frozen=True)
class StatusMarkers:
    """The closed contact nodes of a frame at their deformed positions, with their status.

    Attributes
    ----------
    points : ndarray, shape (k, 3)
        Deformed positions of the nodes whose status is stick or slip, every body together.
    status : ndarray of int, shape (k,)
        :data:`STICK` or :data:`SLIP` per point.
    """

    points: NDArray[np.float64]
    status: NDArray[np.int32]

    def count(self, status: int) -> int:
        """Number of markers with ``status``."""
        return int(np.count_nonzero(self.status == status))


def contact_point_data(
    fields: Mapping[str, NDArray] | None, n_points: int, body: str = "body"
) -> dict[str, NDArray]:
    """A body's contact point arrays, zeros where the result has none.

    Parameters
    ----------
    fields : mapping of str to ndarray, or None
        The body's entry of ``FrameResult.contact_fields`` (None or a missing key: zeros).
    n_points : int
        Points of the body's mesh.
    body : str
        The body's name, for the error message.

    Returns
    -------
    dict of str to ndarray
        :data:`CONTACT_FIELDS`: ``float64`` forces and cone use, ``int32`` status.

    Raises
    ------
    ValueError
        When an array does not have the shape of its field.
    """
    fields = fields or {}
    out = {}
    for name, tail in CONTACT_FIELDS.items():
        dtype = np.int32 if name == "contact_status" else np.float64
        shape = (n_points, *tail)
        value = fields.get(name)
        if value is None:
            out[name] = np.zeros(shape, dtype=dtype)
            continue
        a = np.asarray(value)
        if a.shape != shape:
            raise ValueError(
                f"contact field {name!r} of body {body!r} has shape {a.shape}, "
                f"its mesh needs {shape}"
            )
        out[name] = a.astype(dtype)
    return out


def status_markers(
    points: Mapping[str, NDArray[np.float64]], status: Mapping[str, NDArray]
) -> StatusMarkers:
    """The stick and slip nodes of every body, at their deformed positions.

    Parameters
    ----------
    points : mapping of str to ndarray (N, 3)
        Body name -> deformed nodal positions.
    status : mapping of str to ndarray (N,)
        Body name -> ``contact_status`` (a body missing here has no contact).

    Returns
    -------
    StatusMarkers
    """
    pts, sts = [np.zeros((0, 3))], [np.zeros(0, dtype=np.int32)]
    for name, x in points.items():
        s = status.get(name)
        if s is None:
            continue
        s = np.asarray(s)
        closed = np.flatnonzero((s == STICK) | (s == SLIP))
        pts.append(np.asarray(x, dtype=np.float64)[closed])
        sts.append(s[closed].astype(np.int32))
    return StatusMarkers(np.concatenate(pts), np.concatenate(sts))


def draw_status(
    plotter: pyvista.Plotter,
    surfaces: list[tuple[pyvista.PolyData, float]],
    markers: StatusMarkers,
    point_size: float,
) -> None:
    """Draw the bodies in translucent grey, their stick and slip nodes as dots, a legend.

    Parameters
    ----------
    plotter : pyvista.Plotter
        The frame's plotter (background, planes, title and camera are the caller's).
    surfaces : list of (pyvista.PolyData, float)
        The deformed surfaces and their opacity (at most :data:`_BODY_OPACITY` here).
    markers : StatusMarkers
        The contact nodes.
    point_size : float
        Dot diameter in pixels.
    """
    import pyvista as pv

    for surface, opacity in surfaces:
        plotter.add_mesh(
            surface, color="#b0b0b0", opacity=min(opacity, _BODY_OPACITY), smooth_shading=True
        )
    legend = []
    for status in (STICK, SLIP):
        n = markers.count(status)
        legend.append([f"{_LABELS[status]} ({n})", _COLOURS[status], "circle"])
        if n:
            plotter.add_mesh(
                pv.PolyData(markers.points[markers.status == status]),
                color=_COLOURS[status],
                point_size=point_size,
                render_points_as_spheres=True,
            )
    plotter.add_legend(legend, bcolor="white", size=(0.2, 0.1), loc="lower left")
