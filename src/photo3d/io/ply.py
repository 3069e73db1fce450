"""Read and write PLY meshes in the layout of the authors' 3D-photo output.

The header follows the authors' files line for line (their reader looks for these
comments)::

    ply
    format binary_little_endian 1.0      (or: format ascii 1.0)
    comment H <height>
    comment W <width>
    comment hFov <hfov, radians>
    comment vFov <vfov, radians>
    element vertex <N>
    property float x / y / z             (Mesh.vertices, OpenCV camera axes)
    property uchar red / green / blue    (Mesh.colors, sRGB)
    property uchar alpha                 (Mesh.labels, the authors' vertex label)
    element face <M>
    property list uchar int vertex_index
    end_header

ASCII bodies use single spaces and ``\\n`` (the authors' reader splits on ``' '``);
floats are written with 9 significant digits, which restores every float32 exactly.
The reader accepts any PLY with that vertex data (extra scalar properties and
elements are allowed, big-endian too) and triangle faces only. A missing ``alpha``
reads as label 1 ("original"), missing comments as 0.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass
from typing import BinaryIO

import numpy as np

from photo3d.errors import InputError, OutputError
from photo3d.files.atomic import open_write
from photo3d.structures.mesh import Mesh

PathLike = str | os.PathLike[str]

_VERTEX_DTYPE = np.dtype(
    [("x", "<f4"), ("y", "<f4"), ("z", "<f4")]
    + [(name, "u1") for name in ("red", "green", "blue", "alpha")]
)
_FACE_DTYPE = np.dtype([("count", "u1"), ("index", "<i4", (3,))])
_CODES = "i1 u1 i2 u2 i4 u4 f4 f8".split()
_TYPES = dict(zip("char uchar short ushort int uint float double".split(), _CODES, strict=True))
_TYPES |= dict(
    zip("int8 uint8 int16 uint16 int32 uint32 float32 float64".split(), _CODES, strict=True)
)
_VERTEX_PROPERTIES = "".join(
    f"property {'float' if name in 'xyz' else 'uchar'} {name}\n" for name in _VERTEX_DTYPE.names
)
_BYTE_ORDERS = {"ascii": "", "binary_little_endian": "<", "binary_big_endian": ">"}
_INT_COMMENTS = ("H", "W")
_FLOAT_COMMENTS = ("hFov", "vFov")
_ASCII_CHUNK = 1 << 16
_DEFAULT_LABEL = 1


def write_ply(path: PathLike, mesh: Mesh, *, binary: bool = True) -> None:
    """Write ``mesh`` as a PLY file with the authors' header.

    Args:
        path: file to create (overwritten if it exists).
        mesh: vertices ``(N, 3) float32``, colors ``(N, 3) uint8`` sRGB, labels
            ``(N,) uint8`` (written as ``alpha``), faces ``(M, 3) int32``.
        binary: little-endian binary body (default) or ASCII.

    Raises:
        InputError: the mesh arrays have wrong shapes or out-of-range face indices.
        OutputError: ``path`` cannot be written.

    Example:
        >>> import numpy as np, tempfile, pathlib
        >>> from photo3d.mesh.full import Mesh
        >>> mesh = Mesh(np.zeros((3, 3), np.float32), np.zeros((3, 3), np.uint8),
        ...             np.ones(3, np.uint8), np.array([[0, 2, 1]], np.int32),
        ...             4, 3, 0.5, 0.4)
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "mesh.ply"
        >>> write_ply(path, mesh, binary=False)
        >>> path.read_text().splitlines()[2:6]
        ['comment H 3', 'comment W 4', 'comment hFov 0.5', 'comment vFov 0.4']
    """
    vertices, colors, labels, faces = mesh.checked()
    fmt = "binary_little_endian" if binary else "ascii"
    header = (
        f"ply\nformat {fmt} 1.0\ncomment H {int(mesh.height)}\ncomment W {int(mesh.width)}\n"
        f"comment hFov {float(mesh.hfov)!r}\ncomment vFov {float(mesh.vfov)!r}\n"
        f"element vertex {len(vertices)}\n{_VERTEX_PROPERTIES}"
        f"element face {len(faces)}\nproperty list uchar int vertex_index\nend_header\n"
    )
    try:
        with open_write(path) as file:
            file.write(header.encode("ascii"))
            if binary:
                records = np.empty(len(vertices), _VERTEX_DTYPE)
                for axis, name in enumerate("xyz"):
                    records[name] = vertices[:, axis]
                for channel, name in enumerate(("red", "green", "blue")):
                    records[name] = colors[:, channel]
                records["alpha"] = labels
                records.tofile(file)
                triangles = np.empty(len(faces), _FACE_DTYPE)
                triangles["count"] = 3
                triangles["index"] = faces
                triangles.tofile(file)
            else:
                rows = np.concatenate([vertices, colors, labels[:, None]], axis=1, dtype=float)
                _write_rows(file, "%.9g %.9g %.9g %d %d %d %d\n", rows)
                _write_rows(file, "3 %d %d %d\n", faces)
    except OSError as err:
        raise OutputError(f"cannot write PLY {path}: {err.strerror or err}") from err


def read_ply(path: PathLike) -> Mesh:
    """Read a triangle PLY mesh (ours or the authors'), binary or ASCII.

    Args:
        path: a PLY file whose ``vertex`` element has ``x, y, z, red, green, blue``
            (``alpha`` optional) and whose ``face`` element holds triangles.

    Returns:
        The :class:`Mesh`: vertices ``(N, 3) float32``, colors ``(N, 3) uint8``,
        labels ``(N,) uint8``, faces ``(M, 3) int32``; width, height, hfov, vfov
        from the header comments (0 when absent).

    Raises:
        InputError: the file is missing, malformed, truncated or has non-triangles.

    Example:
        >>> import numpy as np, tempfile, pathlib
        >>> from photo3d.mesh.full import Mesh
        >>> mesh = Mesh(np.eye(3, dtype=np.float32), np.zeros((3, 3), np.uint8),
        ...             np.full(3, 5, np.uint8), np.array([[0, 2, 1]], np.int32),
        ...             4, 3, 0.5, 0.4)
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "mesh.ply"
        >>> write_ply(path, mesh)
        >>> back = read_ply(path)
        >>> back.faces.tolist(), back.labels.tolist(), (back.width, back.height)
        ([[0, 2, 1]], [5, 5, 5], (4, 3))
    """
    try:
        with open(path, "rb") as file:
            data = file.read()
    except OSError as err:
        raise InputError(f"cannot read PLY {path}: {err.strerror or err}") from err
    header, offset = _parse_header(data, path)
    if header.byte_order:
        arrays = _read_binary(data, offset, header, path)
    else:
        arrays = _read_ascii(data[offset:], header, path)
    vertex = arrays.get("vertex")
    if vertex is None:
        raise InputError(f"PLY {path} has no vertex element")
    missing = [name for name in ("x", "y", "z", "red", "green", "blue") if name not in vertex]
    if missing:
        raise InputError(f"PLY {path} vertex element lacks properties {missing}")
    count = len(vertex["x"])
    faces = arrays.get("face", {}).get("index", np.zeros((0, 3), np.int64))
    if faces.size and (faces.min() < 0 or faces.max() >= count):
        raise InputError(f"PLY {path} has face indices outside [0, {count})")
    labels = vertex.get("alpha", np.full(count, _DEFAULT_LABEL))
    return Mesh(
        vertices=np.stack([vertex[name] for name in "xyz"], axis=1).astype(np.float32),
        colors=np.stack([vertex[name] for name in ("red", "green", "blue")], 1).astype(np.uint8),
        labels=labels.astype(np.uint8),
        faces=faces.astype(np.int32),
        width=header.comments.get("W", 0),
        height=header.comments.get("H", 0),
        hfov=header.comments.get("hFov", 0.0),
        vfov=header.comments.get("vFov", 0.0),
    )


@dataclass
class _Element:
    name: str
    count: int
    properties: list[tuple[str, str]]  # (name, numpy type code) of scalar properties
    list_types: tuple[str, str] | None = None  # (count, index) types of the face list


@dataclass
class _Header:
    byte_order: str  # "" for ASCII
    comments: dict[str, int | float]
    elements: list[_Element]


def _parse_header(data: bytes, path: PathLike) -> tuple[_Header, int]:
    end = data.find(b"end_header")
    newline = data.find(b"\n", end)
    if not data.startswith(b"ply") or end < 0 or newline < 0:
        raise InputError(f"{path} is not a PLY file (no 'ply' ... 'end_header' header)")
    header = _Header("", {}, [])
    fmt = None
    for raw in data[:end].decode("latin-1").splitlines()[1:]:
        words = raw.split()
        try:
            if words[:1] == ["format"]:
                fmt = words[1]
                header.byte_order = _BYTE_ORDERS[fmt]
            elif words[:1] == ["comment"] and len(words) == 3 and words[1] in _INT_COMMENTS:
                header.comments[words[1]] = int(words[2])
            elif words[:1] == ["comment"] and len(words) == 3 and words[1] in _FLOAT_COMMENTS:
                header.comments[words[1]] = float(words[2])
            elif words[:1] == ["element"]:
                header.elements.append(_Element(words[1], int(words[2]), []))
            elif words[:2] == ["property", "list"]:
                element = header.elements[-1]
                if element.name != "face" or words[4] not in ("vertex_index", "vertex_indices"):
                    raise ValueError("list properties are only supported for face indices")
                element.list_types = (_TYPES[words[2]], _TYPES[words[3]])
            elif words[:1] == ["property"]:
                header.elements[-1].properties.append((words[2], _TYPES[words[1]]))
        except (IndexError, KeyError, ValueError) as err:
            raise InputError(f"PLY {path} has a bad header line {raw!r} ({err})") from err
    if fmt is None:
        raise InputError(f"PLY {path} has no 'format' line")
    if any(e.list_types and e.properties for e in header.elements):
        raise InputError(f"PLY {path} face element must hold only the vertex index list")
    return header, newline + 1


def _read_binary(data: bytes, offset: int, header: _Header, path: PathLike) -> dict:
    order, arrays = header.byte_order, {}
    for element in header.elements:
        if element.list_types:
            count_type, index_type = element.list_types
            dtype = np.dtype([("count", order + count_type), ("index", order + index_type, (3,))])
        else:
            dtype = np.dtype([(name, order + kind) for name, kind in element.properties])
        size = element.count * dtype.itemsize
        if offset + size > len(data):
            raise InputError(
                f"PLY {path} is truncated: element {element.name!r} needs {size} bytes, "
                f"{len(data) - offset} remain"
            )
        records = np.frombuffer(data, dtype, element.count, offset)
        offset += size
        if element.list_types and np.any(records["count"] != 3):
            raise InputError(f"PLY {path} has faces that are not triangles")
        arrays[element.name] = {name: records[name] for name in dtype.names}
    return arrays


def _read_ascii(body: bytes, header: _Header, path: PathLike) -> dict:
    """Parse each element's lines in one call (integers as int64: 6x faster)."""
    line_ends = np.flatnonzero(np.frombuffer(body, np.uint8) == ord("\n")) + 1
    if not body.endswith(b"\n"):
        line_ends = np.append(line_ends, len(body))
    begin, line, arrays = 0, 0, {}
    for element in header.elements:
        if line + element.count > len(line_ends):
            raise InputError(f"PLY {path} is truncated in element {element.name!r}")
        line += element.count
        end = int(line_ends[line - 1]) if element.count else begin
        width = 4 if element.list_types else len(element.properties)
        integer = bool(element.list_types) or all(k[0] in "iu" for _, k in element.properties)
        values = _parse_numbers(body[begin:end], np.int64 if integer else np.float64, path)
        begin = end
        if values.size != element.count * width:
            shape = "3 indices per line" if element.list_types else f"{width} values per line"
            raise InputError(f"PLY {path} element {element.name!r} does not have {shape}")
        block = values.reshape(element.count, width)
        if element.list_types:
            if np.any(block[:, 0] != 3):
                raise InputError(f"PLY {path} has faces that are not triangles")
            arrays[element.name] = {"index": block[:, 1:]}
        else:
            arrays[element.name] = {n: block[:, i] for i, (n, _) in enumerate(element.properties)}
    if body[begin:].strip():
        raise InputError(f"PLY {path} has more data than its header says")
    return arrays


def _parse_numbers(text: bytes, dtype: type, path: PathLike) -> np.ndarray:
    """Whitespace-separated numbers of ``text`` as a flat array of ``dtype``."""
    if not text.strip():
        return np.zeros(0, dtype)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", DeprecationWarning)  # numpy < 2.3 only warns
            return np.fromstring(text.decode("latin-1"), dtype=dtype, sep=" ")
    except (ValueError, DeprecationWarning) as err:
        raise InputError(f"PLY {path} has a non-numeric value in its ASCII body") from err


def _write_rows(file: BinaryIO, row_format: str, rows: np.ndarray) -> None:
    """Write ``(K, C)`` numbers with ``row_format`` in bulk, a chunk at a time."""
    for begin in range(0, len(rows), _ASCII_CHUNK):
        chunk = rows[begin : begin + _ASCII_CHUNK]
        file.write(((row_format * len(chunk)) % tuple(chunk.ravel().tolist())).encode("ascii"))
