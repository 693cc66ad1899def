"""A body's VTU file of a frame: its arrays, and field data for units, names, bone forces.

:func:`write_body_vtu` writes the arrays that :mod:`contact.output.writer` documents.

VTK keeps arrays that belong to a whole data set (not to its points or cells) as *field
data*; ParaView lists them in its Information panel and shows them in a spreadsheet view
of *Field Data*. :func:`fem.write_mesh` writes points and cells; :func:`add_field_data`
then inserts a ``<FieldData>`` element into the written XML, before the ``<Piece>`` as
VTK's own writer puts it.

Every field array is numeric (ASCII ``Float64``): meshio, and so :func:`fem.read_mesh`,
cannot read VTK string arrays. Names therefore carry the words: ``region palm`` holds the
region id of the palm, ``bone index_distal`` the bone id of that bone,
``bone_force index_distal (N)`` its force, and the array named by :func:`units_name` (value
0) states the unit of every array.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

import fem
from fem.stress import cell_stress, von_mises

from .staging import write_atomic

__all__ = [
    "STRESS_COMPONENTS",
    "UNITS",
    "add_field_data",
    "field_data_xml",
    "units_name",
    "write_body_vtu",
    "write_pvd",
]

#: Order of the six components of the ``stress`` cell array (ParaView's for 6-component
#: symmetric tensors).
STRESS_COMPONENTS = ("xx", "yy", "zz", "xy", "yz", "xz")
_VOIGT = (np.array([0, 1, 2, 0, 1, 0]), np.array([0, 1, 2, 1, 2, 2]))

#: Units of the point and cell arrays the results writer puts in a VTU file.
UNITS: dict[str, str] = {
    "points": "m",
    "displacement": "m",
    "contact_force": "N",
    "normal_force": "N",
    "tangential_force": "N",
    "cone_use": "1",
    "von_mises": "Pa",
    "stress": "Pa",
    "max_log_strain": "1",
}

_GRID = b"<UnstructuredGrid>"


def units_name() -> str:
    """The name of the field array that states the units (:data:`UNITS`)."""
    return "units: " + ", ".join(f"{k} {v}" for k, v in UNITS.items())


def field_data_xml(fields: Mapping[str, ArrayLike]) -> bytes:
    """The ``<FieldData>`` element of ``fields``.

    Parameters
    ----------
    fields : mapping of str to array_like
        Name -> numbers, one row per tuple (a 2-D array gives its columns as components).
        An empty array is left out.

    Returns
    -------
    bytes
        The element, ASCII.
    """
    parts = ["<FieldData>"]
    for name, value in fields.items():
        a = np.asarray(value, dtype=np.float64)
        a = a.reshape(len(a), -1) if a.ndim else a.reshape(1, 1)
        if not a.size:
            continue
        attr = name.replace("&", "&amp;").replace("<", "&lt;").replace('"', "&quot;")
        values = " ".join(repr(float(v)) for v in a.ravel())
        parts.append(
            f'<DataArray type="Float64" Name="{attr}" NumberOfComponents="{a.shape[1]}" '
            f'NumberOfTuples="{a.shape[0]}" format="ascii">{values}</DataArray>'
        )
    parts.append("</FieldData>")
    return "\n".join(parts).encode("ascii", errors="replace")


def add_field_data(vtu: bytes, fields: Mapping[str, ArrayLike]) -> bytes:
    """The VTU file ``vtu`` with ``fields`` as its field data.

    Parameters
    ----------
    vtu : bytes
        An XML ``UnstructuredGrid`` file without field data (as :func:`fem.write_mesh`
        writes it).
    fields : mapping of str to array_like
        As in :func:`field_data_xml`.

    Returns
    -------
    bytes

    Raises
    ------
    ValueError
        When ``vtu`` is not such a file.
    """
    at = vtu.find(_GRID)
    if at < 0 or b"<FieldData>" in vtu[: vtu.find(b"<Piece")]:
        raise ValueError("not an XML UnstructuredGrid file without field data")
    end = at + len(_GRID)
    return vtu[:end] + b"\n" + field_data_xml(fields) + vtu[end:]


def write_body_vtu(
    path: Path,
    mesh: fem.Mesh,
    materials: fem.LinearElastic | Mapping[int, fem.LinearElastic],
    displacement: NDArray[np.float64],
    contact_force: ArrayLike,
    fields: Mapping[str, NDArray],
    *,
    time: float,
    bbar: bool = True,
    nodal_pressure: bool = False,
    support: Mapping[str, ArrayLike] | None = None,
    region_names: Sequence[str] = (),
    cell_bone: ArrayLike | None = None,
    bone_names: Sequence[str] = (),
    finite: bool = False,
) -> dict[str, NDArray[np.float64]]:
    """Write a body's ``.vtu`` file of a frame, atomically.

    Parameters
    ----------
    path : Path
        The file.
    mesh : fem.Mesh
        The body's reference configuration of the frame (the file's points).
    materials : fem.LinearElastic or mapping of int to fem.LinearElastic
        For the stress.
    displacement, contact_force : ndarray (N, 3)
        Point data (m, N).
    fields : mapping of str to ndarray
        The contact point data (:func:`contact.output.status.contact_point_data`).
    time : float
        Frame time (s), field data.
    bbar, nodal_pressure : bool
        The stress's strain, as the body's stiffness was assembled.
    support : mapping of str to array_like (3,), optional
        Bone (support group) -> the force it exerts on the body (N), field data.
    region_names, bone_names : sequence of str
        Names of the region ids and of the bone ids, field data.
    cell_bone : array_like of int, optional
        The bone of each cell, cell data ``bone``.
    finite : bool
        A neo-Hookean body: its stress is the law's Cauchy stress on the deformed body
        (the mean of its Gauss points), and each cell's largest principal logarithmic
        strain in magnitude is cell data ``max_log_strain``.

    Returns
    -------
    dict of str to ndarray
        The cell-average von Mises stress per cell type (Pa).

    Raises
    ------
    fem.MeshError
        When the mesh file cannot be written.
    OSError
        When the field data cannot be added.
    """
    u = np.asarray(displacement, dtype=np.float64)
    if finite:
        gauss = fem.cauchy_stress(mesh, materials, u.ravel())
        sigma = {k: s.mean(axis=1) for k, s in gauss.items()}
    else:
        sigma = cell_stress(mesh, materials, u.ravel(), bbar=bbar, nodal_pressure=nodal_pressure)
    vm = {k: von_mises(s) for k, s in sigma.items()}
    cells: dict[str, Any] = {
        "von_mises": vm,
        "stress": {k: s[:, _VOIGT[0], _VOIGT[1]] for k, s in sigma.items()},
    }
    if finite:
        logs = fem.log_strain(mesh, u.ravel())
        cells["max_log_strain"] = {k: np.abs(e).max(axis=(1, 2)) for k, e in logs.items()}
    if cell_bone is not None:
        cells["bone"] = np.asarray(cell_bone, dtype=np.int32)
    support = support or {}
    data: dict[str, ArrayLike] = {"time (s)": [time], units_name(): [0.0]}
    data.update({f"region {r}": [k] for k, r in enumerate(region_names)})
    data.update({f"bone {b}": [k] for k, b in enumerate(bone_names)})
    data.update({f"bone_force {g} (N)": [support[g]] for g in sorted(support)})
    point_data = {
        "displacement": u,
        "contact_force": np.asarray(contact_force, dtype=np.float64),
        **fields,
    }
    fem.write_mesh(path, mesh, point_data=point_data, cell_data=cells)
    write_atomic(path, add_field_data(path.read_bytes(), data))
    return vm


def write_pvd(path: Path, series: Sequence[tuple[float, str]]) -> None:
    """A ParaView time series: ``(time, file)`` pairs, written atomically to ``path``."""
    root = ET.Element("VTKFile", type="Collection", version="0.1", byte_order="LittleEndian")
    coll = ET.SubElement(root, "Collection")
    for t, name in series:
        ET.SubElement(coll, "DataSet", timestep=repr(t), group="", part="0", file=name)
    ET.indent(root)
    write_atomic(path, b'<?xml version="1.0"?>\n' + ET.tostring(root) + b"\n")
