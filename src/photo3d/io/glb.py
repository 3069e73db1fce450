"""The GLB container (glTF 2.0 binary): chunks, accessors, the unlit material and the
input camera, shared by the vertex-coloured (:mod:`photo3d.io.gltf`) and textured
(:mod:`photo3d.io.gltf_textured`) meshes.

Example:
    >>> TO_GLTF.tolist()  # OpenCV (x, y, z) -> glTF (x, -y, -z)
    [1.0, -1.0, -1.0]
"""

from __future__ import annotations

import json
import os
import struct

import numpy as np

from photo3d.errors import InputError, OutputError
from photo3d.files.atomic import open_write
from photo3d.io.bounded import loads_json, read_bytes
from photo3d.io.limits import check_available

PathLike = str | os.PathLike[str]

MAGIC, JSON_CHUNK, BIN_CHUNK = 0x46546C67, 0x4E4F534A, 0x004E4942
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963
COMPONENTS = {5120: "i1", 5121: "u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
CODES = {np.dtype(kind).type: code for code, kind in COMPONENTS.items()}
WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
TO_GLTF = np.array([1, -1, -1], np.float32)  # OpenCV (x, y, z) -> glTF (x, -y, -z)
TRIANGLES = 4
UNLIT = "KHR_materials_unlit"
WHITE = [1.0, 1.0, 1.0, 1.0]


FRINGE_MATERIAL = {
    "name": "soft silhouettes (vertex colours and alpha, blended)",
    "pbrMetallicRoughness": {"baseColorFactor": WHITE, "metallicFactor": 0.0,
                             "roughnessFactor": 1.0},
    "extensions": {UNLIT: {}},
    "alphaMode": "BLEND",
    "doubleSided": False,
}
"""Material of the soft silhouettes' primitive: unlit, ``COLOR_0`` RGBA, blended."""


def write_glb_file(path: PathLike, mesh, vertices: np.ndarray, labels: np.ndarray,
                   faces: np.ndarray, attributes: list, primitive: dict, material: dict, *,
                   image: bytes | None = None, fringe=None) -> None:
    """Assemble and write a GLB: POSITION, ``attributes`` (accessor 1), _LABEL,
    indices, one material, optionally one embedded JPEG texture, the camera node.

    ``fringe``: the soft silhouettes (a :class:`~photo3d.structures.mesh.Mesh` with
    ``alpha``, :meth:`~photo3d.structures.mesh.Mesh.split_fringe`), written as a
    second primitive of the same mesh: ``POSITION``, ``COLOR_0`` (linear RGB and the
    alpha, float32 VEC4) and ``_LABEL``, with :data:`FRINGE_MATERIAL` (``alphaMode``
    ``BLEND``); a glTF viewer draws it over the first. When its ``vertices`` are
    ``mesh.vertices`` themselves (the full mesh), it shares the first primitive's
    ``POSITION`` and ``_LABEL``."""
    positions = vertices * TO_GLTF
    strided_labels = np.zeros((len(labels), 4), np.uint8)  # attributes are 4-byte aligned
    strided_labels[:, 0] = labels
    indices = faces.ravel().astype(np.uint16 if len(vertices) <= 0xFFFF else np.uint32)
    arrays = [  # (data, accessor type, bufferView target, byteStride)
        (positions, "VEC3", ARRAY_BUFFER, None),
        *attributes,
        (strided_labels, "SCALAR", ARRAY_BUFFER, 4),
        (indices, "SCALAR", ELEMENT_ARRAY_BUFFER, None),
    ]
    primitives, materials = [primitive], [material]
    shared = fringe is not None and fringe.vertices is mesh.vertices
    if fringe is not None:
        first = len(arrays)
        f_vertices, f_colors, f_labels, f_faces = fringe.checked()
        f_positions = f_vertices * TO_GLTF
        rgba = np.empty((len(f_vertices), 4), np.float32)
        rgba[:, :3] = srgb_to_linear(f_colors)
        rgba[:, 3] = np.clip(np.asarray(fringe.alpha, np.float32), 0.0, 1.0)
        f_strided = np.zeros((len(f_labels), 4), np.uint8)
        f_strided[:, 0] = f_labels
        f_indices = f_faces.ravel().astype(np.uint16 if len(f_vertices) <= 0xFFFF else np.uint32)
        if shared:  # the same vertices: POSITION and _LABEL are the first primitive's
            arrays += [(rgba, "VEC4", ARRAY_BUFFER, None),
                       (f_indices, "SCALAR", ELEMENT_ARRAY_BUFFER, None)]
            attributes = {"POSITION": 0, "COLOR_0": first, "_LABEL": len(attributes) + 1}
            indices = first + 1
        else:
            arrays += [(f_positions, "VEC3", ARRAY_BUFFER, None),
                       (rgba, "VEC4", ARRAY_BUFFER, None),
                       (f_strided, "SCALAR", ARRAY_BUFFER, 4),
                       (f_indices, "SCALAR", ELEMENT_ARRAY_BUFFER, None)]
            attributes = {"POSITION": first, "COLOR_0": first + 1, "_LABEL": first + 2}
            indices = first + 3
        primitives.append({"attributes": attributes, "indices": indices, "material": 1,
                           "mode": TRIANGLES})
        materials.append(FRINGE_MATERIAL)
    views, accessors, chunks = pack_arrays(arrays)
    offset = sum(len(chunk) for chunk in chunks)
    accessors[0].update(min=positions.min(axis=0).tolist(), max=positions.max(axis=0).tolist())
    if fringe is not None and not shared:
        accessors[first].update(min=f_positions.min(axis=0).tolist(),
                                max=f_positions.max(axis=0).tolist())
    document = {
        "asset": {"version": "2.0", "generator": "photo3d"},
        "extensionsUsed": [UNLIT],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "photo3d", "mesh": 0}],
        "meshes": [{"name": "photo3d", "extras": view_extras(mesh), "primitives": primitives}],
        "materials": materials,
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
        add_camera(document, float(mesh.vfov), mesh.width / mesh.height)
    write_container(path, document, chunks)


def srgb_to_linear(colors: np.ndarray) -> np.ndarray:
    """``(N, 3) uint8`` sRGB -> ``(N, 3) float32`` linear (IEC 61966-2-1; glTF vertex
    colours are linear).

    Example:
        >>> [round(float(v), 3) for v in srgb_to_linear(np.array([[0, 255, 188]], np.uint8))[0]]
        [0.0, 1.0, 0.503]
    """
    srgb = np.asarray(colors, np.float64) / 255.0
    linear = np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)
    return linear.astype(np.float32)


def read_fringe(document: dict, binary: bytes, path: PathLike, extras: dict):
    """The soft silhouettes' primitive (the first mesh's second, if there is one) as a
    :class:`~photo3d.structures.mesh.Mesh` with ``alpha``, or None."""
    from photo3d.structures.mesh import Mesh

    primitives = document["meshes"][0]["primitives"]
    if len(primitives) < 2:
        return None
    primitive = primitives[1]
    attributes = primitive["attributes"]
    positions = accessor(document, binary, attributes["POSITION"], path)
    rgba = accessor(document, binary, attributes["COLOR_0"], path)
    labels = accessor(document, binary, attributes["_LABEL"], path, kinds=(5121,))[:, 0]
    count = len(positions)
    faces = triangles(document, binary, primitive["indices"], path, count)
    if positions.shape[1] != 3 or rgba.shape != (count, 4) or len(labels) != count:
        raise InputError(f"glTF {path} has soft silhouette attributes of different lengths")
    if not (np.isfinite(positions).all() and np.isfinite(rgba).all()):
        raise InputError(f"glTF {path} has NaN or infinite soft silhouette attributes")
    value = np.clip(rgba[:, :3].astype(np.float64), 0.0, 1.0)
    srgb = np.where(value <= 0.0031308, value * 12.92, 1.055 * value ** (1 / 2.4) - 0.055)
    return Mesh(vertices=(positions * TO_GLTF).astype(np.float32),
                colors=np.rint(srgb * 255.0).astype(np.uint8), labels=labels.astype(np.uint8),
                faces=faces.astype(np.int32), width=int(extras.get("width", 0)),
                height=int(extras.get("height", 0)), hfov=float(extras.get("hfov", 0.0)),
                vfov=float(extras.get("vfov", 0.0)),
                alpha=np.clip(rgba[:, 3], 0.0, 1.0).astype(np.float32))


def pack_arrays(arrays: list) -> tuple[list[dict], list[dict], list[bytes]]:
    """Buffer views, accessors and binary chunks (each padded to 4 bytes) of
    ``arrays``, one view and one accessor per array, in order.

    ``arrays``: ``(data, accessor type, bufferView target, byteStride or None)``
    tuples, optionally with a fifth item, ``normalized``.

    Example:
        >>> views, accessors, chunks = pack_arrays(
        ...     [(np.zeros((2, 3), np.float32), "VEC3", ARRAY_BUFFER, None),
        ...      (np.zeros(3, np.uint8), "SCALAR", ARRAY_BUFFER, None, True)])
        >>> [v["byteOffset"] for v in views], [len(c) for c in chunks]
        ([0, 24], [24, 4])
        >>> accessors[1]
        {'bufferView': 1, 'componentType': 5121, 'count': 3, 'type': 'SCALAR', 'normalized': True}
    """
    views, accessors, chunks, offset = [], [], [], 0
    for index, (data, kind, target, stride, *normalized) in enumerate(arrays):
        raw = np.ascontiguousarray(data).tobytes()
        view = {"buffer": 0, "byteOffset": offset, "byteLength": len(raw), "target": target}
        views.append(view | ({"byteStride": stride} if stride else {}))
        accessors.append({"bufferView": index, "componentType": CODES[data.dtype.type],
                          "count": len(data), "type": kind}
                         | ({"normalized": True} if any(normalized) else {}))
        chunks.append(raw + bytes(-len(raw) % 4))
        offset += len(chunks[-1])
    return views, accessors, chunks


def add_camera(document: dict, yfov: float, aspect: float) -> None:
    """Add the input view to ``document`` as a perspective camera on a second node of
    the scene (vertical field of view ``yfov`` in radians)."""
    perspective = {"yfov": yfov, "aspectRatio": aspect, "znear": 0.01}
    document["cameras"] = [{"type": "perspective", "perspective": perspective}]
    document["nodes"].append({"name": "input view", "camera": 0})
    document["scenes"][0]["nodes"].append(1)


def write_container(path: PathLike, document: dict, chunks: list[bytes]) -> None:
    """Write the GLB of ``document`` (JSON) and ``chunks`` (its binary buffer, each
    chunk already padded to 4 bytes) to ``path``.

    Raises:
        OutputError: ``path`` cannot be written.
    """
    text = json.dumps(document, separators=(",", ":"), allow_nan=False).encode("utf-8")
    text += b" " * (-len(text) % 4)
    length = sum(len(chunk) for chunk in chunks)
    try:
        with open_write(path) as file:
            file.write(struct.pack("<III", MAGIC, 2, 12 + 8 + len(text) + 8 + length))
            file.write(struct.pack("<II", len(text), JSON_CHUNK) + text)
            file.write(struct.pack("<II", length, BIN_CHUNK))
            for chunk in chunks:
                file.write(chunk)
    except OSError as err:
        raise OutputError(f"cannot write glTF {path}: {err.strerror or err}") from err


def view_extras(mesh) -> dict:
    """The input view's size and field of view, stored exactly in the mesh extras."""
    return {
        "width": int(mesh.width),
        "height": int(mesh.height),
        "hfov": float(mesh.hfov),
        "vfov": float(mesh.vfov),
    }


MAX_GLB_BYTES = 2 << 30
"""The largest GLB photo3d reads (a 4096 px photo's full mesh is about 0.7 GB)."""


def read_chunks(path: PathLike, *, max_bytes: int = MAX_GLB_BYTES) -> tuple[dict, bytes]:
    """The parsed JSON chunk and the BIN chunk (empty when absent) of the GLB file ``path``.

    Bounded before anything is decoded: the file's size (``max_bytes``, and the
    memory available), the chunk lengths against the file's, the JSON's nesting
    (:func:`photo3d.io.bounded.loads_json`). Anything else is one line.

    Raises:
        InputError: the file is missing, too large, not a GLB, or its chunks are
            damaged.

    Example:
        >>> import pathlib, tempfile
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "a.glb"
        >>> write_container(path, {"asset": {"version": "2.0"}}, [bytes(4)])
        >>> document, binary = read_chunks(path)
        >>> document["asset"], len(binary)
        ({'version': '2.0'}, 4)
        >>> _ = path.write_bytes(path.read_bytes()[:16] + b"[" * 5000)
        >>> read_chunks(path)
        Traceback (most recent call last):
        photo3d.errors.InputError: glTF ... has no complete JSON chunk
    """
    data = read_bytes(path, max_bytes=max_bytes, what=f"glTF {path}")
    check_available(2 * len(data), f"glTF {path}")
    if len(data) < 20 or struct.unpack_from("<II", data) != (MAGIC, 2):
        raise InputError(f"{path} is not a binary glTF 2.0 file")
    length, kind = struct.unpack_from("<II", data, 12)
    if kind != JSON_CHUNK or 20 + length > len(data):
        raise InputError(f"glTF {path} has no complete JSON chunk")
    document = loads_json(data[20 : 20 + length], what=f"glTF {path}'s JSON")
    if not isinstance(document, dict):
        raise InputError(f"glTF {path}'s JSON is not an object")
    start = 20 + length
    binary = b""
    if start + 8 <= len(data):
        size, kind = struct.unpack_from("<II", data, start)
        if kind != BIN_CHUNK or start + 8 + size > len(data):
            raise InputError(f"glTF {path} has a truncated BIN chunk")
        binary = data[start + 8 : start + 8 + size]
    return document, binary


def _entry(document: dict, key: str, index, path: PathLike) -> dict:
    """``document[key][index]``, checked to be an object."""
    items = document.get(key)
    if (not isinstance(items, list) or not isinstance(index, int) or isinstance(index, bool)
            or not 0 <= index < len(items) or not isinstance(items[index], dict)):
        raise InputError(f"glTF {path} has no {key}[{index!r}]")
    return items[index]


def _count(value, name: str, path: PathLike, *, low: int = 0) -> int:
    if not isinstance(value, int) or isinstance(value, bool) or value < low:
        raise InputError(f"glTF {path} has an invalid {name} ({value!r})")
    return value


def view_bytes(document: dict, binary: bytes, index, path: PathLike) -> bytes:
    """The bytes of buffer view ``index`` (of the BIN chunk), checked to lie inside it.

    Example:
        >>> view_bytes({"bufferViews": [{"byteOffset": 1, "byteLength": 2}]}, b"abcd", 0, "x")
        b'bc'
    """
    view = _entry(document, "bufferViews", index, path)
    if view.get("buffer", 0) != 0:
        raise InputError(f"glTF {path} buffer view {index} uses external data")
    start = _count(view.get("byteOffset", 0), "byteOffset", path)
    length = _count(view.get("byteLength"), "byteLength", path)
    if start + length > len(binary):
        raise InputError(f"glTF {path} buffer view {index} lies past its buffer")
    return binary[start : start + length]


def accessor(document: dict, binary: bytes, index, path: PathLike, *,
             kinds: tuple[int, ...] | None = None) -> np.ndarray:
    """Accessor ``index`` as a ``(count, components)`` array (normalised -> float).

    Every field is checked before the data is touched: the accessor and its view
    exist, the component type (one of ``kinds`` when given) and type are glTF's,
    the count, offsets and stride are non-negative integers and the elements lie
    inside the view and the BIN chunk, so the array is never larger than the file.

    Raises:
        InputError: one line naming the accessor.

    Example:
        >>> document = {"accessors": [{"bufferView": 0, "componentType": 5121,
        ...                            "count": 2, "type": "VEC2"}],
        ...             "bufferViews": [{"byteLength": 4}]}
        >>> accessor(document, bytes([1, 2, 3, 4]), 0, "x").tolist()
        [[1, 2], [3, 4]]
        >>> document["accessors"][0]["count"] = 10**12
        >>> accessor(document, bytes(4), 0, "x")
        Traceback (most recent call last):
        photo3d.errors.InputError: glTF x accessor 0 reads past its buffer view
    """
    entry = _entry(document, "accessors", index, path)
    if "sparse" in entry:
        raise InputError(f"glTF {path} accessor {index} uses sparse data")
    code, kind = entry.get("componentType"), entry.get("type")
    if code not in COMPONENTS or (kinds is not None and code not in kinds):
        raise InputError(f"glTF {path} accessor {index} has component type {code!r}")
    if kind not in WIDTHS:
        raise InputError(f"glTF {path} accessor {index} has type {kind!r}")
    view_index = entry.get("bufferView")
    view = _entry(document, "bufferViews", view_index, path)
    data = view_bytes(document, binary, view_index, path)
    dtype, width = np.dtype(COMPONENTS[code]), WIDTHS[kind]
    count = _count(entry.get("count"), "count", path)
    stride = _count(view.get("byteStride", dtype.itemsize * width), "byteStride", path,
                    low=dtype.itemsize * width)
    start = _count(entry.get("byteOffset", 0), "byteOffset", path)
    end = start + stride * (count - 1) + dtype.itemsize * width if count else start
    if end > len(data):
        raise InputError(f"glTF {path} accessor {index} reads past its buffer view")
    array = np.ndarray((count, width), dtype, data, start, (stride, dtype.itemsize)).copy()
    if entry.get("normalized", False) is True and dtype.kind in "iu":
        return array / float(np.iinfo(dtype).max)
    return array


def triangles(document: dict, binary: bytes, index, path: PathLike, count: int) -> np.ndarray:
    """``(M, 3) int64`` triangle indices of accessor ``index``, each in ``[0, count)``.

    Raises:
        InputError: not unsigned integer scalars, not a multiple of three, or an
            index outside the vertices.

    Example:
        >>> document = {"accessors": [{"bufferView": 0, "componentType": 5121,
        ...                            "count": 3, "type": "SCALAR"}],
        ...             "bufferViews": [{"byteLength": 3}]}
        >>> triangles(document, bytes([0, 1, 2]), 0, "x", 3).tolist()
        [[0, 1, 2]]
        >>> triangles(document, bytes([0, 1, 5]), 0, "x", 3)
        Traceback (most recent call last):
        photo3d.errors.InputError: glTF x has indices outside [0, 3)
    """
    raw = accessor(document, binary, index, path, kinds=(5121, 5123, 5125))
    if raw.shape[1] != 1 or raw.size % 3:
        raise InputError(f"glTF {path} indices are not triangles")
    faces = raw.reshape(-1, 3).astype(np.int64)
    if faces.size and faces.max() >= count:
        raise InputError(f"glTF {path} has indices outside [0, {count})")
    return faces
