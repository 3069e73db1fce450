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
    labels = accessor(document, binary, attributes["_LABEL"], path)[:, 0]
    faces = accessor(document, binary, primitive["indices"], path).reshape(-1, 3)
    count = len(positions)
    if rgba.shape != (count, 4) or len(labels) != count:
        raise InputError(f"glTF {path} has soft silhouette attributes of different lengths")
    if faces.size and faces.max() >= count:
        raise InputError(f"glTF {path} has indices outside [0, {count})")
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
        with open(path, "wb") as file:
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


def read_chunks(path: PathLike) -> tuple[dict, bytes]:
    """The parsed JSON chunk and the BIN chunk (empty when absent) of the GLB file ``path``."""
    try:
        with open(path, "rb") as file:
            data = file.read()
    except OSError as err:
        raise InputError(f"cannot read glTF {path}: {err.strerror or err}") from err
    if len(data) < 20 or struct.unpack_from("<II", data) != (MAGIC, 2):
        raise InputError(f"{path} is not a binary glTF 2.0 file")
    length, kind = struct.unpack_from("<II", data, 12)
    if kind != JSON_CHUNK or 20 + length > len(data):
        raise InputError(f"glTF {path} has no complete JSON chunk")
    try:
        document = json.loads(data[20 : 20 + length])
    except ValueError as err:
        raise InputError(f"glTF {path} has invalid JSON ({err})") from err
    start = 20 + length
    binary = b""
    if start + 8 <= len(data):
        size, kind = struct.unpack_from("<II", data, start)
        if kind != BIN_CHUNK or start + 8 + size > len(data):
            raise InputError(f"glTF {path} has a truncated BIN chunk")
        binary = data[start + 8 : start + 8 + size]
    return document, binary


def accessor(document: dict, binary: bytes, index: int, path: PathLike) -> np.ndarray:
    """Accessor ``index`` as a ``(count, components)`` array (normalised -> float)."""
    accessor = document["accessors"][index]
    view = document["bufferViews"][accessor["bufferView"]]
    if view.get("buffer", 0) != 0 or "sparse" in accessor:
        raise InputError(f"glTF {path} accessor {index} uses external or sparse data")
    dtype = np.dtype(COMPONENTS[accessor["componentType"]])
    count, width = accessor["count"], WIDTHS[accessor["type"]]
    stride = view.get("byteStride", dtype.itemsize * width)
    start = view.get("byteOffset", 0) + accessor.get("byteOffset", 0)
    end = start + stride * (count - 1) + dtype.itemsize * width if count else start
    if end > min(len(binary), view.get("byteOffset", 0) + view["byteLength"]):
        raise InputError(f"glTF {path} accessor {index} reads past its buffer view")
    array = np.ndarray((count, width), dtype, binary, start, (stride, dtype.itemsize)).copy()
    if accessor.get("normalized", False):
        return array / float(np.iinfo(dtype).max)
    return array
