"""Readers of the common surface files (STL, OBJ, PLY) that check the file as they read it.

VTK's and meshio's readers of these formats take a malformed file badly: a truncated
binary STL is decoded as text (``UnicodeDecodeError``), a negative OBJ index (legal: it
counts back from the last vertex) fills stderr with VTK's errors, a truncated binary PLY
crashes the interpreter and a PLY header without its end hangs meshio. These readers
parse the three formats with numpy and say in one :class:`~contact.errors.ObjectError`
line what is wrong with the file: a size that does not match the header, a face index
that refers to no vertex, a header line that is not PLY's.
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
from numpy.lib.recfunctions import structured_to_unstructured
from numpy.typing import NDArray

from ..errors import ObjectError

__all__ = ["SURFACE_FORMATS", "read_surface_file"]

#: The suffixes read here (any case); other files go to pyvista.
SURFACE_FORMATS = (".stl", ".obj", ".ply")

Surface = tuple[NDArray[np.float64], NDArray[np.int64]]
#: An element's rows: one array when all are alike, else lists.
Rows = NDArray[np.float64] | list[list[float]]

#: PLY's scalar types as numpy's (without the byte order).
_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}  # fmt: skip
_STL_RECORD = np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attr", "<u2")])
_OBJ_LINE = re.compile(rb"^[ \t]*([vf])[ \t]+([^\r\n]*)", re.M)
_STL_VERTEX = re.compile(rb"^\s*vertex\s+(\S+)\s+(\S+)\s+(\S+)", re.M)


def _fans(polygons: NDArray[np.int64] | list[list[int]]) -> NDArray[np.int64]:
    """Polygons (an array of equal ones, or lists) split into triangles fanned from corner 0."""
    if isinstance(polygons, np.ndarray):
        c = polygons
        fan = [np.stack([c[:, 0], c[:, k], c[:, k + 1]], axis=1) for k in range(1, c.shape[1] - 1)]
        return np.stack(fan, axis=1).reshape(-1, 3)
    tri = [(p[0], p[k], p[k + 1]) for p in polygons for k in range(1, len(p) - 1)]
    return np.asarray(tri, np.int64).reshape(-1, 3)


def _shared(corners: NDArray[np.float64]) -> Surface:
    """STL's corners, three a triangle, as points shared by the triangles that meet there."""
    corners = np.ascontiguousarray(corners + 0.0)  # -0.0 as 0.0: one point, one key
    key = corners.view(np.dtype((np.void, 24))).ravel()
    _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    return corners[first], inverse.reshape(-1, 3).astype(np.int64)


def _read_stl(data: bytes) -> Surface:
    """A binary STL (its size told by its triangle count) or an ASCII one."""
    is_text = data.lstrip().startswith(b"solid")
    if len(data) >= 84:
        n = int(np.frombuffer(data, "<u4", 1, 80)[0])
        if len(data) == 84 + 50 * n or (len(data) > 84 + 50 * n and not is_text):  # padded
            corners = np.frombuffer(data, _STL_RECORD, n, 84)["corners"]
            return _shared(corners.reshape(-1, 3).astype(np.float64))
    if not is_text:
        if len(data) < 84:
            raise ObjectError(f"not an STL file: {len(data)} bytes, no binary header")
        raise ObjectError(
            f"a truncated or damaged binary STL: its header declares {n} triangles "
            f"({84 + 50 * n} bytes), the file has {len(data)} bytes"
        )
    try:
        ascii_text = data.decode("ascii")
    except UnicodeDecodeError as exc:
        size = "" if len(data) < 84 else f": {n} triangles, {84 + 50 * n} bytes"
        raise ObjectError(
            f"neither a binary STL (the file has {len(data)} bytes, its header declares "
            f"{size.lstrip(': ') or 'none'}) nor ASCII text (byte {exc.start} is "
            f"0x{data[exc.start]:02x}): truncated or damaged"
        ) from None
    found = _STL_VERTEX.findall(data)
    if not re.search(r"^\s*endsolid", ascii_text, re.M):
        raise ObjectError(f"a truncated ASCII STL: no 'endsolid' after {len(found)} vertices")
    if len(found) % 3:
        raise ObjectError(f"a damaged ASCII STL: {len(found)} vertices, not three a facet")
    try:
        points = np.array(found, dtype=np.float64)
    except ValueError:
        raise ObjectError("a damaged ASCII STL: a vertex coordinate is not a number") from None
    return _shared(points.reshape(-1, 3))


def _numbers(lines: list[bytes]) -> NDArray[np.float64] | None:
    """Lines of as many numbers as the first as one array, or None when they are not."""
    width = len(lines[0].split()) if lines else 0
    with warnings.catch_warnings():  # numpy's notice of text it could not parse
        warnings.simplefilter("ignore")
        flat = np.fromstring(b" ".join(lines).decode("ascii", "replace"), sep=" ")
    return flat.reshape(len(lines), width) if width and flat.size == len(lines) * width else None


def _read_obj_at_once(data: bytes) -> Surface | None:
    """An OBJ file of alike vertex and face lines read with numpy; None if they are not.

    None also for a file with any fault: the line by line reader then names the line.
    """
    found = _OBJ_LINE.findall(data)
    is_v = np.fromiter((kind == b"v" for kind, _ in found), bool, len(found))
    points = _numbers([rest for kind, rest in found if kind == b"v"])
    faces = [re.sub(rb"/[^ \t]*", b"", rest) for kind, rest in found if kind == b"f"]
    corners = _numbers(faces)
    if points is None or corners is None or points.shape[1] < 3 or corners.shape[1] < 3:
        return None
    index = corners.astype(np.int64)
    before = np.cumsum(is_v)[~is_v][:, None]  # the vertices defined before each face
    if (index != corners).any() or (index == 0).any() or (np.abs(index) > before).any():
        return None
    return points[:, :3].copy(), _fans(np.where(index > 0, index - 1, before + index))


def _read_obj(data: bytes) -> Surface:
    """An OBJ file's vertices and faces; 1-based indices, negative ones counting back."""
    fast = _read_obj_at_once(data)
    if fast is not None:
        return fast
    points: list[list[float]] = []
    polygons: list[list[int]] = []
    try:
        lines = data.decode("utf-8").splitlines()
    except UnicodeDecodeError as exc:
        raise ObjectError(f"not an OBJ file: not text (byte {exc.start})") from None
    for number, line in enumerate(lines, 1):
        words = line.split()
        if not words or words[0] not in ("v", "f"):
            continue  # comments, normals, texture coordinates, groups, materials
        try:
            if words[0] == "v":
                points.append([float(w) for w in words[1:4]])
                if len(points[-1]) != 3:
                    raise ValueError
                continue
            face = [int(w.split("/")[0]) for w in words[1:]]
        except ValueError:
            raise ObjectError(
                f"line {number}: {line.strip()[:60]!r} is not a valid OBJ "
                f"{'vertex' if words[0] == 'v' else 'face'}"
            ) from None
        if len(face) < 3:
            raise ObjectError(f"line {number}: a face of {len(face)} corners")
        n = len(points)
        for i in face:
            if i == 0 or not -n <= i <= n:
                raise ObjectError(
                    f"line {number}: face index {i} refers to no vertex ({n} defined before "
                    f"it; indices are 1..{n}, or -1..-{n} counting back)"
                )
        polygons.append([i - 1 if i > 0 else n + i for i in face])
    if not polygons:
        raise ObjectError("holds no faces ('f' lines)")
    return np.asarray(points, np.float64).reshape(-1, 3), _fans(polygons)


def _ply_header(data: bytes) -> tuple[str, list[tuple[str, int, list[list[str]]]], int]:
    """The format, the elements (name, count, properties) and where the data starts."""
    if not data.startswith(b"ply"):
        raise ObjectError("not a PLY file: it does not start with 'ply'")
    end = re.search(rb"^end_header\r?\n", data, re.M)
    if end is None:
        raise ObjectError("a PLY header without 'end_header'")
    try:
        lines = data[: end.start()].decode("ascii").splitlines()[1:]
    except UnicodeDecodeError:
        raise ObjectError("a PLY header that is not ASCII text") from None
    fmt, elements = "", []
    for number, line in enumerate(lines, 2):
        w = line.split()
        bad = f"PLY header line {number}: {line.strip()[:60]!r}"
        if not w or w[0] in ("comment", "obj_info"):
            continue
        if w[0] == "format":
            if len(w) != 3 or w[1] not in ("ascii", "binary_little_endian", "binary_big_endian"):
                raise ObjectError(f"{bad} is not a format (ascii or binary_*_endian 1.0)")
            fmt = w[1]
        elif w[0] == "element":
            if len(w) != 3 or not w[2].isdigit():
                raise ObjectError(f"{bad} is not 'element <name> <count>'")
            elements.append((w[1], int(w[2]), []))
        elif w[0] == "property":
            scalar = len(w) == 3 and w[1] in _PLY_TYPES
            listed = len(w) == 5 and w[1] == "list" and w[2] in _PLY_TYPES and w[3] in _PLY_TYPES
            if not elements or not (scalar or listed):
                raise ObjectError(f"{bad} is not a property of an element")
            elements[-1][2].append(w[1:])
        else:
            raise ObjectError(f"{bad} is not a PLY header line")
    if not fmt:
        raise ObjectError("a PLY header without a 'format' line")
    return fmt, elements, end.end()


def _truncated(k: int, count: int, name: str) -> ObjectError:
    return ObjectError(f"a truncated PLY file: {k} of its {count} {name} rows")


def _ply_ascii(body: bytes, elements: list) -> dict[str, Rows]:
    """Each element's rows (a list's count and items in line) from an ASCII body."""
    lines = body.decode("ascii", "replace").splitlines()
    rows: dict[str, Rows] = {}
    at = 0
    for name, count, _ in elements:
        block = lines[at : at + count]
        if len(block) < count:
            raise _truncated(len(block), count, name)
        at += count
        width = len(block[0].split()) if count else 0
        with warnings.catch_warnings():  # numpy's notice of text it could not parse
            warnings.simplefilter("ignore")
            flat = np.fromstring(" ".join(block), sep=" ") if count else np.zeros(0)
        if count and flat.size == count * width:  # rows alike: one array at once
            rows[name] = flat.reshape(count, width)
            continue
        try:
            rows[name] = [[float(v) for v in line.split()] for line in block]
        except ValueError:
            raise ObjectError(f"a damaged PLY file: a {name} row that is not numbers") from None
    return rows


def _uniform_lists(body: bytes, at: int, count: int, props: list, order: str) -> NDArray | None:
    """A one-list element whose lists all match the first's length, read at once, or None."""
    if count == 0 or len(props) != 1 or props[0][0] != "list":
        return None
    head = np.dtype(order + _PLY_TYPES[props[0][1]])
    if at + head.itemsize > len(body):
        return None
    n = int(np.frombuffer(body, head, 1, at)[0])
    if n < 1:
        return None
    dtype = np.dtype([("n", head), ("i", order + _PLY_TYPES[props[0][2]], (n,))])
    if at + count * dtype.itemsize > len(body):
        return None
    block = np.frombuffer(body, dtype, count, at)
    return block if (block["n"] == n).all() else None


def _ply_binary(body: bytes, elements: list, order: str) -> dict[str, Rows]:
    """Each element's rows from a binary body, every size checked against the data."""
    rows: dict[str, Rows] = {}
    at = 0
    for name, count, props in elements:
        if all(p[0] != "list" for p in props):  # fixed rows: one read
            dtype = np.dtype([(f"p{i}", order + _PLY_TYPES[p[0]]) for i, p in enumerate(props)])
            if at + count * dtype.itemsize > len(body):
                raise _truncated((len(body) - at) // max(dtype.itemsize, 1), count, name)
            block = np.frombuffer(body, dtype, count, at)
            rows[name] = structured_to_unstructured(block, np.float64).reshape(count, -1)
            at += block.nbytes
            continue
        uniform = _uniform_lists(body, at, count, props, order)
        if uniform is not None:
            rows[name] = structured_to_unstructured(uniform, np.float64)
            at += uniform.nbytes
            continue
        out: list[list[float]] = []
        for k in range(count):
            row: list[float] = []
            for p in props:
                kinds = (p[1], p[2]) if p[0] == "list" else (None, p[0])
                n = 1
                if kinds[0] is not None:
                    t = np.dtype(order + _PLY_TYPES[kinds[0]])
                    if at + t.itemsize > len(body):
                        raise _truncated(k, count, name)
                    n = int(np.frombuffer(body, t, 1, at)[0])
                    row.append(n)
                    at += t.itemsize
                t = np.dtype(order + _PLY_TYPES[kinds[1]])
                if n < 0 or at + n * t.itemsize > len(body):
                    raise _truncated(k, count, name)
                row.extend(np.frombuffer(body, t, n, at).tolist())
                at += n * t.itemsize
            out.append(row)
        rows[name] = out
    return rows


def _ply_polygons(rows: Rows, skip: int, props: list) -> NDArray[np.int64] | list[list[int]]:
    """The faces' corner indices: an array when every face has as many, else lists."""
    if isinstance(rows, np.ndarray) and len(props) == 1 and rows.shape[1] >= 4:
        if (rows[:, 0] == rows.shape[1] - 1).all():
            return rows[:, 1:].astype(np.int64)
        rows = rows.tolist()
    polygons = []
    for k, r in enumerate(rows):
        n = int(r[skip]) if len(r) > skip else -1
        face = [int(v) for v in r[skip + 1 : skip + 1 + n]]
        if n < 3 or len(face) != n:
            raise ObjectError(f"a damaged PLY file: face {k} has no polygon of 3 or more corners")
        polygons.append(face)
    return polygons


def _read_ply(data: bytes) -> Surface:
    """A PLY file's vertices (x, y, z) and faces (a vertex_indices list)."""
    fmt, elements, start = _ply_header(data)
    props = {name: p for name, _, p in elements}
    names = [p[-1] for p in props.get("vertex", [])]
    if not all(c in names for c in "xyz"):
        raise ObjectError("a PLY file without vertex x, y and z properties")
    faces = [i for i, p in enumerate(props.get("face", [])) if p[0] == "list"]
    if "face" not in props or not faces:
        raise ObjectError("a PLY file without faces (a 'face' element with a list property)")
    body = data[start:]
    if fmt == "ascii":
        rows = _ply_ascii(body, elements)
    else:
        rows = _ply_binary(body, elements, "<" if fmt == "binary_little_endian" else ">")
    vertex = rows["vertex"]
    if any(len(r) != len(names) for r in vertex):
        raise ObjectError("a damaged PLY file: a vertex row of the wrong length")
    points = np.asarray(vertex, np.float64).reshape(-1, len(names))[
        :, [names.index(c) for c in "xyz"]
    ]
    polygons = _ply_polygons(rows["face"], faces[0], props["face"])
    n = len(points)
    if isinstance(polygons, np.ndarray):
        out = (polygons < 0) | (polygons >= n)
        bad = [(int(k), int(polygons[k][out[k]][0])) for k in np.flatnonzero(out.any(axis=1))[:1]]
    else:
        bad = [(k, v) for k, f in enumerate(polygons) for v in f if not 0 <= v < n][:1]
    if bad:
        k, v = bad[0]
        raise ObjectError(f"face {k} refers to vertex {v}: the file has vertices 0..{n - 1}")
    return points, _fans(polygons)


def read_surface_file(path: Path, prefix: str) -> Surface:
    """The points and triangles of an STL, OBJ or PLY file (polygons fanned into triangles).

    Parameters
    ----------
    path : Path
        A file whose suffix is one of :data:`SURFACE_FORMATS`.
    prefix : str
        Starts every message (``object[0].mesh = '<path>': ``).

    Returns
    -------
    points : ndarray, shape (N, 3)
    triangles : ndarray of int, shape (M, 3)

    Raises
    ------
    ObjectError
        One line: the file cannot be read, or what is wrong with it.
    """
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise ObjectError(f"{prefix}cannot be read ({exc.strerror or exc})") from None
    reader = {".stl": _read_stl, ".obj": _read_obj, ".ply": _read_ply}[path.suffix.lower()]
    try:
        return reader(data)
    except ObjectError as exc:
        raise ObjectError(f"{prefix}{exc}") from None
