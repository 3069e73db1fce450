"""Write and read glTF 2.0 binary (``.glb``) meshes, with ``json``, ``struct`` and numpy.

What :func:`write_glb` puts in the file:

* ``POSITION``: float32 ``(x, -y, -z)`` of the OpenCV camera coordinates, i.e. a
  180 degree rotation about x into glTF's y-up, camera-looks-down--z axes. A rotation
  keeps the counter-clockwise winding, so faces stay front-facing towards the camera.
* ``COLOR_0``: float32 RGB in *linear* light (glTF vertex colours are linear; sRGB
  stored as-is looks washed out), decoded back to the same sRGB uint8 on reading.
* ``_LABEL``: the authors' vertex labels, uint8 scalar (application attribute; the
  spec forbids only unsigned int for those), one per 4-byte stride as vertex
  attributes must be 4-byte aligned.
* indices: uint16 when every index is below 65535 (the restart value), else uint32.
* an unlit material (``KHR_materials_unlit``; white base colour, metallic 0,
  roughness 1 as fallback), single-sided.
* the input view as a perspective camera node at the origin (identity transform,
  ``yfov = vfov``, ``aspectRatio = width / height``, ``znear = 0.01``); exact
  width, height, hfov, vfov in the mesh's ``extras``.

The textured variant (the light mesh) is in :mod:`photo3d.io.gltf_textured`; its
functions can still be imported from here.
"""

from __future__ import annotations

import json
import os
import struct

import numpy as np

from photo3d.errors import InputError, OutputError
from photo3d.mesh import Mesh

PathLike = str | os.PathLike[str]

_MAGIC, _JSON, _BIN = 0x46546C67, 0x4E4F534A, 0x004E4942
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963
_COMPONENTS = {5120: "i1", 5121: "u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
_CODES = {np.dtype(kind).type: code for code, kind in _COMPONENTS.items()}
_WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
_TO_GLTF = np.array([1, -1, -1], np.float32)  # OpenCV (x, y, z) -> glTF (x, -y, -z)
_TRIANGLES = 4
_UNLIT = "KHR_materials_unlit"
_DEFAULT_LABEL = 1
_PRIMITIVE = {
    "attributes": {"POSITION": 0, "COLOR_0": 1, "_LABEL": 2},
    "indices": 3,
    "material": 0,
    "mode": _TRIANGLES,
}
_WHITE = [1.0, 1.0, 1.0, 1.0]
_MATERIAL = {
    "name": "unlit vertex colours",
    "pbrMetallicRoughness": {
        "baseColorFactor": _WHITE,
        "metallicFactor": 0.0,
        "roughnessFactor": 1.0,
    },
    "extensions": {_UNLIT: {}},
    "doubleSided": False,
}


def write_glb(path: PathLike, mesh: Mesh) -> None:
    """Write ``mesh`` as a binary glTF 2.0 file for Blender, three.js and web viewers.

    Args:
        path: file to create (overwritten if it exists).
        mesh: vertices ``(N, 3) float32`` finite OpenCV camera coordinates, colors
            ``(N, 3) uint8`` sRGB, labels ``(N,) uint8``, faces ``(M, 3) int32``;
            ``N >= 1`` and ``M >= 1`` (glTF has no empty accessors).

    Raises:
        InputError: the mesh is empty, has wrong shapes, non-finite vertices or
            out-of-range face indices.
        OutputError: ``path`` cannot be written.

    Example:
        >>> import numpy as np, tempfile, pathlib
        >>> from photo3d.mesh import Mesh

        >>> mesh = Mesh(np.eye(3, dtype=np.float32), np.zeros((3, 3), np.uint8),
        ...             np.ones(3, np.uint8), np.array([[0, 2, 1]], np.int32),
        ...             4, 3, 0.5, 0.4)
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "mesh.glb"
        >>> write_glb(path, mesh)
        >>> path.read_bytes()[:4]
        b'glTF'
    """
    vertices, colors, labels, faces = _checked_arrays(mesh)
    arrays = [(_SRGB_TO_LINEAR[colors], "VEC3", _ARRAY_BUFFER, None)]
    _write(path, mesh, vertices, labels, faces, arrays, _PRIMITIVE, _MATERIAL)


def _write(path: PathLike, mesh, vertices: np.ndarray, labels: np.ndarray, faces: np.ndarray,
           attributes: list, primitive: dict, material: dict, *, image: bytes | None = None
           ) -> None:
    """Assemble and write a GLB: POSITION, ``attributes`` (accessor 1), _LABEL,
    indices, one material, optionally one embedded JPEG texture, the camera node."""
    positions = vertices * _TO_GLTF
    strided_labels = np.zeros((len(labels), 4), np.uint8)  # attributes are 4-byte aligned
    strided_labels[:, 0] = labels
    indices = faces.ravel().astype(np.uint16 if len(vertices) <= 0xFFFF else np.uint32)
    arrays = [  # (data, accessor type, bufferView target, byteStride)
        (positions, "VEC3", _ARRAY_BUFFER, None),
        *attributes,
        (strided_labels, "SCALAR", _ARRAY_BUFFER, 4),
        (indices, "SCALAR", _ELEMENT_ARRAY_BUFFER, None),
    ]
    views, accessors, chunks, offset = [], [], [], 0
    for index, (data, kind, target, stride) in enumerate(arrays):
        raw = data.tobytes()
        view = {"buffer": 0, "byteOffset": offset, "byteLength": len(raw), "target": target}
        views.append(view | ({"byteStride": stride} if stride else {}))
        code = _CODES[data.dtype.type]
        accessors.append(
            {"bufferView": index, "componentType": code, "count": len(data), "type": kind}
        )
        chunks.append(raw + bytes(-len(raw) % 4))
        offset += len(chunks[-1])
    accessors[0].update(min=positions.min(axis=0).tolist(), max=positions.max(axis=0).tolist())
    document = {
        "asset": {"version": "2.0", "generator": "photo3d"},
        "extensionsUsed": [_UNLIT],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "photo3d", "mesh": 0}],
        "meshes": [{"name": "photo3d", "extras": _view_extras(mesh), "primitives": [primitive]}],
        "materials": [material],
        "accessors": accessors,
        "bufferViews": views,
    }
    if image is not None:
        views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(image)})
        chunks.append(image + bytes(-len(image) % 4))
        offset += len(chunks[-1])
        document["images"] = [{"bufferView": len(views) - 1, "mimeType": "image/jpeg"}]
        document["samplers"] = [{"magFilter": 9729, "minFilter": 9729,  # LINEAR
                                 "wrapS": 33071, "wrapT": 33071}]  # CLAMP_TO_EDGE
        document["textures"] = [{"sampler": 0, "source": 0}]
    document["buffers"] = [{"byteLength": offset}]
    if mesh.vfov > 0 and mesh.width > 0 and mesh.height > 0:
        aspect = mesh.width / mesh.height
        perspective = {"yfov": float(mesh.vfov), "aspectRatio": aspect, "znear": 0.01}
        document["cameras"] = [{"type": "perspective", "perspective": perspective}]
        document["nodes"].append({"name": "input view", "camera": 0})
        document["scenes"][0]["nodes"].append(1)
    text = json.dumps(document, separators=(",", ":"), allow_nan=False).encode("utf-8")
    text += b" " * (-len(text) % 4)
    total = 12 + 8 + len(text) + 8 + offset
    try:
        with open(path, "wb") as file:
            file.write(struct.pack("<III", _MAGIC, 2, total))
            file.write(struct.pack("<II", len(text), _JSON) + text)
            file.write(struct.pack("<II", offset, _BIN))
            for chunk in chunks:
                file.write(chunk)
    except OSError as err:
        raise OutputError(f"cannot write glTF {path}: {err.strerror or err}") from err


def read_glb(path: PathLike) -> Mesh:
    """Read a ``.glb`` written by :func:`write_glb` back into a :class:`Mesh`.

    Reads the first primitive of the first mesh (triangles; ``POSITION``, ``COLOR_0``
    linear RGB(A) as float or normalised integers, optional ``_LABEL``); undoes the
    axis and colour conversions. Node transforms are not applied.

    Args:
        path: a binary glTF 2.0 file.

    Returns:
        The mesh: vertices ``(N, 3) float32`` OpenCV camera coordinates, colors
        ``(N, 3) uint8`` sRGB (white without ``COLOR_0``), labels ``(N,) uint8``
        (1 without ``_LABEL``), faces ``(M, 3) int32``; width, height, hfov, vfov
        from the mesh extras (0 when absent).

    Raises:
        InputError: the file is missing, not a GLB, or uses unsupported features.

    Example:
        >>> import numpy as np, tempfile, pathlib
        >>> from photo3d.mesh import Mesh

        >>> colors = np.array([[0, 1, 2], [128, 200, 255], [7, 7, 7]], np.uint8)
        >>> mesh = Mesh(np.eye(3, dtype=np.float32), colors, np.full(3, 4, np.uint8),
        ...             np.array([[0, 2, 1]], np.int32), 4, 3, 0.5, 0.4)
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "mesh.glb"
        >>> write_glb(path, mesh)
        >>> back = read_glb(path)
        >>> back.colors.tolist() == colors.tolist(), back.labels.tolist()
        (True, [4, 4, 4])
    """
    document, binary = _read_chunks(path)
    try:
        primitive = document["meshes"][0]["primitives"][0]
        if primitive.get("mode", _TRIANGLES) != _TRIANGLES or "indices" not in primitive:
            raise InputError(f"glTF {path} primitive is not indexed triangles")
        attributes = primitive["attributes"]
        positions = _accessor(document, binary, attributes["POSITION"], path)
        count = len(positions)
        faces = _accessor(document, binary, primitive["indices"], path).reshape(-1, 3)
        colors = np.full((count, 3), 255, np.uint8)
        if "COLOR_0" in attributes:
            colors = _linear_to_srgb(_accessor(document, binary, attributes["COLOR_0"], path))
        labels = np.full(count, _DEFAULT_LABEL, np.uint8)
        if "_LABEL" in attributes:
            labels = _accessor(document, binary, attributes["_LABEL"], path)[:, 0]
        extras = document["meshes"][0].get("extras", {})
        if any(
            node.get("mesh") == 0 and {"matrix", "translation", "rotation", "scale"} & set(node)
            for node in document.get("nodes", [])
        ):
            raise InputError(f"glTF {path} places its mesh with a node transform (unsupported)")
    except InputError:
        raise
    except (KeyError, IndexError, TypeError, ValueError) as err:
        raise InputError(f"glTF {path} has an unexpected structure ({err!r})") from err
    if faces.size and faces.max() >= count:
        raise InputError(f"glTF {path} has indices outside [0, {count})")
    return Mesh(
        vertices=(positions * _TO_GLTF).astype(np.float32),
        colors=colors,
        labels=labels.astype(np.uint8),
        faces=faces.astype(np.int32),
        width=int(extras.get("width", 0)),
        height=int(extras.get("height", 0)),
        hfov=float(extras.get("hfov", 0.0)),
        vfov=float(extras.get("vfov", 0.0)),
    )


def _view_extras(mesh: Mesh) -> dict:
    """The input view's size and field of view, stored exactly in the mesh extras."""
    return {
        "width": int(mesh.width),
        "height": int(mesh.height),
        "hfov": float(mesh.hfov),
        "vfov": float(mesh.vfov),
    }


def _read_chunks(path: PathLike) -> tuple[dict, bytes]:
    """The parsed JSON chunk and the BIN chunk (empty when absent) of the GLB file ``path``."""
    try:
        with open(path, "rb") as file:
            data = file.read()
    except OSError as err:
        raise InputError(f"cannot read glTF {path}: {err.strerror or err}") from err
    if len(data) < 20 or struct.unpack_from("<II", data) != (_MAGIC, 2):
        raise InputError(f"{path} is not a binary glTF 2.0 file")
    length, kind = struct.unpack_from("<II", data, 12)
    if kind != _JSON or 20 + length > len(data):
        raise InputError(f"glTF {path} has no complete JSON chunk")
    try:
        document = json.loads(data[20 : 20 + length])
    except ValueError as err:
        raise InputError(f"glTF {path} has invalid JSON ({err})") from err
    start = 20 + length
    binary = b""
    if start + 8 <= len(data):
        size, kind = struct.unpack_from("<II", data, start)
        if kind != _BIN or start + 8 + size > len(data):
            raise InputError(f"glTF {path} has a truncated BIN chunk")
        binary = data[start + 8 : start + 8 + size]
    return document, binary


def _accessor(document: dict, binary: bytes, index: int, path: PathLike) -> np.ndarray:
    """Accessor ``index`` as a ``(count, components)`` array (normalised -> float)."""
    accessor = document["accessors"][index]
    view = document["bufferViews"][accessor["bufferView"]]
    if view.get("buffer", 0) != 0 or "sparse" in accessor:
        raise InputError(f"glTF {path} accessor {index} uses external or sparse data")
    dtype = np.dtype(_COMPONENTS[accessor["componentType"]])
    count, width = accessor["count"], _WIDTHS[accessor["type"]]
    stride = view.get("byteStride", dtype.itemsize * width)
    start = view.get("byteOffset", 0) + accessor.get("byteOffset", 0)
    end = start + stride * (count - 1) + dtype.itemsize * width if count else start
    if end > min(len(binary), view.get("byteOffset", 0) + view["byteLength"]):
        raise InputError(f"glTF {path} accessor {index} reads past its buffer view")
    array = np.ndarray((count, width), dtype, binary, start, (stride, dtype.itemsize)).copy()
    if accessor.get("normalized", False):
        return array / float(np.iinfo(dtype).max)
    return array


def _srgb_to_linear_table() -> np.ndarray:
    """``(256,) float32`` linear value of each sRGB uint8 level (IEC 61966-2-1)."""
    srgb = np.arange(256) / 255.0
    linear = np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)
    return linear.astype(np.float32)


_SRGB_TO_LINEAR = _srgb_to_linear_table()


def _linear_to_srgb(linear: np.ndarray) -> np.ndarray:
    """``(N, C >= 3)`` linear float colours -> ``(N, 3) uint8`` sRGB, rounded."""
    value = np.clip(linear[:, :3].astype(np.float64), 0.0, 1.0)
    srgb = np.where(value <= 0.0031308, value * 12.92, 1.055 * value ** (1 / 2.4) - 0.055)
    return np.rint(srgb * 255.0).astype(np.uint8)


def _checked_arrays(mesh: Mesh) -> tuple[np.ndarray, ...]:
    """:meth:`Mesh.checked` plus what glTF cannot store (empty or non-finite data)."""
    arrays = mesh.checked()
    if len(arrays[0]) == 0 or len(arrays[3]) == 0:
        raise InputError("mesh has no vertices or no faces; glTF cannot store it")
    if not np.isfinite(arrays[0]).all():
        raise InputError("mesh.vertices has NaN or infinite values")
    return arrays


_TEXTURED = ("write_textured_glb", "read_textured_glb", "encode_jpeg", "decode_jpeg")


def __getattr__(name: str):
    """The textured GLB and JPEG functions, now in :mod:`photo3d.io.gltf_textured`
    (imported from here lazily so old imports keep working)."""
    if name in _TEXTURED:
        from photo3d.io import gltf_textured

        return getattr(gltf_textured, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
