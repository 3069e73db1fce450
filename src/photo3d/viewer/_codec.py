"""Compact binary form of a :class:`~photo3d.structures.mesh.Mesh` for the HTML viewer.

The viewer page (``viewer.js``) decodes exactly this layout; keep both in step and
bump :data:`VERSION` on any change.

The payload is one zlib stream (``DecompressionStream("deflate")`` in browsers) of
four sections, each starting at a multiple of 4 bytes (offsets in the header):

* ``position``: three planes of ``N`` uint16, little-endian: ``x / z``, ``y / z``
  and ``1 / z`` of every vertex in the input camera (OpenCV axes), each quantised
  linearly between ``lo`` and ``hi`` of the header: ``value = lo + q / 65535 *
  (hi - lo)``. Quantising the image-plane direction and the inverse depth, rather
  than x, y, z, keeps the error uniform on screen: about ``(hi - lo) * f / 131070``
  pixels (0.01 px for the 1024 px sample) and a parallax error of ``f * shift *
  (hi - lo) / 131070`` (under 0.001 px for the authors' shifts).
* ``color``: ``(N, 3)`` uint8 sRGB, interleaved (vertex-coloured meshes), or
* ``uv`` and ``texture`` (textured meshes, :class:`~photo3d.structures.mesh.TexturedMesh`):
  two planes of ``N`` uint16, ``u * 65535`` and ``v * 65535`` (glTF texture
  coordinates, origin top-left), and the texture as JPEG bytes; the header's
  ``texture`` gives its ``width``, ``height`` and ``mime``.
* ``label``: ``(N,)`` uint8, the authors' labels (unused by the page; kept so the
  file is a faithful copy of the mesh).
* ``faces``: each face rotated so that its largest index ``m`` comes last (a
  rotation keeps the winding), then per face three uint32: zigzag(``m -
  m_previous``), ``m - a`` and ``m - b`` for the face ``(a, b, m)``, where
  zigzag(d) = 2 d for d >= 0 and -2 d - 1 below. The ``3 M`` numbers are stored as
  4 byte planes (all lowest bytes, then all second bytes, ...). photo3d meshes list
  faces in order of their largest vertex and join lattice neighbours, so the
  numbers are mostly 0 or 2, 1 and the row length: the high planes are zero and
  deflate brings the 12 bytes of a face down to about 0.3.
"""

from __future__ import annotations

import zlib

import numpy as np

from photo3d.errors import InputError
from photo3d.io.gltf_textured import decode_jpeg, encode_jpeg
from photo3d.structures.mesh import Mesh, TexturedMesh

VERSION = 2
SECTIONS = ("position", "color", "label", "faces")
TEXTURED_SECTIONS = ("position", "uv", "label", "faces", "texture")
TEXTURE_QUALITY = 85
"""JPEG quality of the viewer's texture."""
_LEVELS = 65535.0


def encode_mesh(mesh: Mesh | TexturedMesh, *, level: int = 6) -> tuple[dict, bytes]:
    """Encode ``mesh`` for the viewer.

    Args:
        mesh: vertices ``(N, 3) float32`` with ``z > 0`` (in front of the input
            camera, as every photo3d mesh), colors ``(N, 3) uint8`` (or uv and a
            texture: :class:`~photo3d.structures.mesh.TexturedMesh`), labels ``(N,)``, faces
            ``(M, 3) int32``; ``N, M >= 1``.
        level: zlib compression level (1 fastest .. 9 smallest).

    Returns:
        ``(header, payload)``: the JSON-able header (sizes, fields of view,
        quantisation bounds, section offsets) and the zlib-compressed payload.

    Raises:
        InputError: empty mesh, wrong shapes, non-finite vertices or ``z <= 0``.

    Example:
        >>> m = Mesh(np.array([[0, 0, 1], [1, 0, 2], [0, 1, 4]], np.float32),
        ...          np.zeros((3, 3), np.uint8), np.ones(3, np.uint8),
        ...          np.array([[0, 2, 1]], np.int32), 4, 4, 1.0, 1.0)
        >>> header, payload = encode_mesh(m)
        >>> header["vertices"], header["faces"], header["position"]["hi"][2]
        (3, 1, 1.0)
    """
    textured = isinstance(mesh, TexturedMesh)
    vertices, colors, labels, faces = mesh.checked()
    if len(vertices) == 0 or len(faces) == 0:
        raise InputError("mesh has no vertices or no faces; the viewer needs both")
    if not np.isfinite(vertices).all():
        raise InputError("mesh.vertices has NaN or infinite values")
    z = vertices[:, 2].astype(np.float64)
    if z.min() <= 0:
        raise InputError(f"mesh.vertices need z > 0 (in front of the input camera), "
                         f"min z is {z.min():g}")
    planes = (vertices[:, 0] / z, vertices[:, 1] / z, 1.0 / z)
    lo = [float(p.min()) for p in planes]
    hi = [float(p.max()) for p in planes]
    quantised = [
        np.rint((p - a) * (_LEVELS / (b - a) if b > a else 0.0)).astype("<u2")
        for p, a, b in zip(planes, lo, hi, strict=True)
    ]
    blobs = {
        "position": np.concatenate(quantised).tobytes(),
        "label": labels.tobytes(),
        "faces": _encode_faces(faces),
    }
    if textured:
        uv = np.rint(np.clip(colors, 0.0, 1.0) * _LEVELS).astype("<u2")
        blobs["uv"] = np.ascontiguousarray(uv.T).tobytes()
        blobs["texture"] = encode_jpeg(np.asarray(mesh.texture), quality=TEXTURE_QUALITY)
    else:
        blobs["color"] = colors.tobytes()
    raw, sections, offset = [], {}, 0
    for name in TEXTURED_SECTIONS if textured else SECTIONS:
        data = blobs[name]
        sections[name] = [offset, len(data)]
        raw.append(data + bytes(-len(data) % 4))
        offset += len(raw[-1])
    header = {
        "format": "photo3d-viewer", "version": VERSION,
        "width": int(mesh.width), "height": int(mesh.height),
        "hfov": float(mesh.hfov), "vfov": float(mesh.vfov),
        "vertices": len(vertices), "faces": len(faces),
        "position": {"lo": lo, "hi": hi}, "sections": sections,
        "compression": "deflate", "size": offset,
    }
    if textured:
        t = np.asarray(mesh.texture)
        header["texture"] = {"width": int(t.shape[1]), "height": int(t.shape[0]),
                             "mime": "image/jpeg"}
    return header, zlib.compress(b"".join(raw), level)


def decode_mesh(header: dict, payload: bytes) -> Mesh | TexturedMesh:
    """Inverse of :func:`encode_mesh` (positions within the quantisation error).

    Faces come back rotated so that their largest index is last (same winding).

    Example:
        >>> m = Mesh(np.array([[0, 0, 1], [1, 0, 2], [0, 1, 4]], np.float32),
        ...          np.zeros((3, 3), np.uint8), np.ones(3, np.uint8),
        ...          np.array([[0, 2, 1]], np.int32), 4, 4, 1.0, 1.0)
        >>> back = decode_mesh(*encode_mesh(m))
        >>> back.faces.tolist(), bool(np.abs(back.vertices - m.vertices).max() < 1e-4)
        ([[1, 0, 2]], True)
    """
    if header.get("format") != "photo3d-viewer" or header.get("version") != VERSION:
        raise InputError(f"not a photo3d viewer payload of version {VERSION}")
    raw = zlib.decompress(payload)
    n, count = int(header["vertices"]), int(header["faces"])

    def section(name: str) -> bytes:
        offset, length = header["sections"][name]
        return raw[offset:offset + length]

    q = np.frombuffer(section("position"), "<u2").reshape(3, n).astype(np.float64)
    lo = np.asarray(header["position"]["lo"], np.float64)[:, None]
    hi = np.asarray(header["position"]["hi"], np.float64)[:, None]
    a, b, d = lo + q / _LEVELS * (hi - lo)
    vertices = np.stack([a / d, b / d, 1.0 / d], axis=1).astype(np.float32)
    if "texture" in header:
        from photo3d.structures.mesh import TexturedMesh

        uv = np.frombuffer(section("uv"), "<u2").reshape(2, n).T / _LEVELS
        return TexturedMesh(
            vertices=vertices, uv=uv.astype(np.float32), texture=decode_jpeg(section("texture")),
            labels=np.frombuffer(section("label"), np.uint8).copy(),
            faces=_decode_faces(section("faces"), count), n_input=0,
            width=int(header["width"]), height=int(header["height"]),
            hfov=float(header["hfov"]), vfov=float(header["vfov"]),
        )
    return Mesh(
        vertices=vertices,
        colors=np.frombuffer(section("color"), np.uint8).reshape(n, 3).copy(),
        labels=np.frombuffer(section("label"), np.uint8).copy(),
        faces=_decode_faces(section("faces"), count),
        width=int(header["width"]), height=int(header["height"]),
        hfov=float(header["hfov"]), vfov=float(header["vfov"]),
    )


def _encode_faces(faces: np.ndarray) -> bytes:
    """``(M, 3)`` int indices -> 4 byte planes of ``(M, 3)`` uint32 (module docstring)."""
    f0, f1, f2 = faces[:, 0], faces[:, 1], faces[:, 2]
    # rotate each face (a, b, m) so that its largest index m comes last
    k = np.where(f0 >= f1, np.where(f0 >= f2, 0, 2), np.where(f1 >= f2, 1, 2))
    m = np.choose(k, (f0, f1, f2))
    a = np.choose(k, (f1, f2, f0))
    b = np.choose(k, (f2, f0, f1))
    dm = np.diff(m.astype(np.int64), prepend=0)
    zigzag = (dm << 1) ^ (dm >> 63)
    values = np.stack([zigzag.astype(np.uint32), m - a, m - b], axis=1).astype("<u4")
    return byte_planes(values.ravel())


def _decode_faces(data: bytes, count: int) -> np.ndarray:
    if len(data) != 12 * count:
        raise InputError(f"viewer payload holds {len(data)} bytes of faces, expected {12 * count}")
    planes = np.frombuffer(data, np.uint8).reshape(4, 3 * count).astype(np.uint32)
    values = planes[0] | planes[1] << 8 | planes[2] << 16 | planes[3] << 24
    zigzag, da, db = values.reshape(count, 3).T.astype(np.int64)
    m = np.cumsum((zigzag >> 1) ^ -(zigzag & 1))
    return np.stack([m - da, m - db, m], axis=1).astype(np.int32)


def byte_planes(values: np.ndarray) -> bytes:
    """``(K,) uint32`` -> 4 planes of K bytes: all lowest bytes first, then the next...

    Small numbers leave the high planes zero, which deflate compresses to almost
    nothing (the "byte shuffle" of Blosc).

    Example:
        >>> byte_planes(np.array([1, 258], np.uint32)).hex()
        '0102000100000000'
    """
    return np.ascontiguousarray(values.astype("<u4").view(np.uint8).reshape(-1, 4).T).tobytes()
