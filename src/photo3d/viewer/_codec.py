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

Version 3 adds the soft silhouettes (the faces that touch a vertex of ``alpha < 1``,
:meth:`~photo3d.structures.mesh.Mesh.split_fringe`, or a textured mesh's
``overlay``), drawn blended over the rest: the header's ``overlay`` gives their
``vertices`` and ``faces``, and three more sections hold them: ``overlay_position``
(as ``position``, same bounds), ``overlay_color`` (``(K, 4)`` uint8 sRGB and alpha)
and ``overlay_faces`` (as ``faces``). Version 2 payloads (no overlay) still decode.
"""

from __future__ import annotations

import zlib

import numpy as np

from photo3d.errors import InputError
from photo3d.io.gltf_textured import decode_jpeg, encode_jpeg
from photo3d.io.limits import check_available
from photo3d.structures.mesh import Mesh, TexturedMesh

VERSION = 3
OVERLAY_SECTIONS = ("overlay_position", "overlay_color", "overlay_faces")
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
    if textured:
        overlay = mesh.overlay
    else:
        mesh, overlay = mesh.split_fringe()
    vertices, colors, labels, faces = mesh.checked()
    if len(vertices) == 0 or len(faces) == 0:
        raise InputError("mesh has no vertices or no faces; the viewer needs both")
    if not np.isfinite(vertices).all():
        raise InputError("mesh.vertices has NaN or infinite values")
    z = vertices[:, 2].astype(np.float64)
    if z.min() <= 0:
        raise InputError(f"mesh.vertices need z > 0 (in front of the input camera), "
                         f"min z is {z.min():g}")
    extra = np.zeros((0, 3), np.float32)
    if overlay is not None:
        extra = overlay.checked()[0]
        if not np.isfinite(extra).all() or (len(extra) and extra[:, 2].min() <= 0):
            raise InputError("the soft silhouettes' vertices need finite values and z > 0")
    every = np.concatenate([vertices, extra]).astype(np.float64)
    planes = (every[:, 0] / every[:, 2], every[:, 1] / every[:, 2], 1.0 / every[:, 2])
    lo = [float(p.min()) for p in planes]
    hi = [float(p.max()) for p in planes]
    quantised = [
        np.rint((p - a) * (_LEVELS / (b - a) if b > a else 0.0)).astype("<u2")
        for p, a, b in zip(planes, lo, hi, strict=True)
    ]
    n = len(vertices)
    blobs = {
        "position": np.concatenate([q[:n] for q in quantised]).tobytes(),
        "label": labels.tobytes(),
        "faces": _encode_faces(faces),
    }
    if textured:
        uv = np.rint(np.clip(colors, 0.0, 1.0) * _LEVELS).astype("<u2")
        blobs["uv"] = np.ascontiguousarray(uv.T).tobytes()
        blobs["texture"] = encode_jpeg(np.asarray(mesh.texture), quality=TEXTURE_QUALITY)
    else:
        blobs["color"] = colors.tobytes()
    names = TEXTURED_SECTIONS if textured else SECTIONS
    if overlay is not None:
        _, o_colors, _, o_faces = overlay.checked()
        rgba = np.empty((len(o_colors), 4), np.uint8)
        rgba[:, :3] = o_colors
        rgba[:, 3] = np.rint(np.clip(overlay.alpha, 0.0, 1.0) * 255.0)
        blobs["overlay_position"] = np.concatenate([q[n:] for q in quantised]).tobytes()
        blobs["overlay_color"] = rgba.tobytes()
        blobs["overlay_faces"] = _encode_faces(o_faces)
        names = names + OVERLAY_SECTIONS
    raw, sections, offset = [], {}, 0
    for name in names:
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
    if overlay is not None:
        header["overlay"] = {"vertices": len(overlay.vertices), "faces": len(overlay.faces)}
    if textured:
        t = np.asarray(mesh.texture)
        header["texture"] = {"width": int(t.shape[1]), "height": int(t.shape[0]),
                             "mime": "image/jpeg"}
    return header, zlib.compress(b"".join(raw), level)


def decode_mesh(header: dict, payload: bytes) -> Mesh | TexturedMesh:
    """Inverse of :func:`encode_mesh` (positions within the quantisation error).

    Faces come back rotated so that their largest index is last (same winding).

    Raises:
        InputError: one line; ``header`` or ``payload`` is not photo3d's or is damaged
            (a missing or mistyped field, a section of the wrong size, a payload that
            is not deflate or not the size the header declares, which bounds the
            decompression; positions that are not finite, faces outside the vertices).

    Example:
        >>> m = Mesh(np.array([[0, 0, 1], [1, 0, 2], [0, 1, 4]], np.float32),
        ...          np.zeros((3, 3), np.uint8), np.ones(3, np.uint8),
        ...          np.array([[0, 2, 1]], np.int32), 4, 4, 1.0, 1.0)
        >>> back = decode_mesh(*encode_mesh(m))
        >>> back.faces.tolist(), bool(np.abs(back.vertices - m.vertices).max() < 1e-4)
        ([[1, 0, 2]], True)
    """
    if not isinstance(header, dict) or header.get("format") != "photo3d-viewer" or (
            header.get("version") not in (2, VERSION)):
        raise InputError(f"not a photo3d viewer payload of version 2 to {VERSION}")
    try:
        mesh = _decode(header, _inflate(payload, header["size"]))
        mesh.checked()  # faces within the vertices (the overlay's: merged, or below)
        if getattr(mesh, "overlay", None) is not None:
            mesh.overlay.checked()
    except InputError:
        raise
    except _DAMAGED as err:
        raise InputError(f"the header has no {err.args[0]}" if isinstance(err, KeyError)
                         else f"{type(err).__name__}: {err}") from None
    return mesh


_DAMAGED = (KeyError, TypeError, ValueError, AttributeError, IndexError, OverflowError,
            zlib.error)
"""What a hostile header or payload raises in :func:`_decode` (a missing or mistyped
field, a section of the wrong size, data that is not deflate)."""


def _inflate(payload: bytes, size: int) -> bytes:
    """``payload`` decompressed, refused unless it is the ``size`` bytes the header
    declares (a deflate bomb stops at ``size + 1`` bytes)."""
    size = int(size)
    if size < 0:  # a max_length of 0 would mean no limit
        raise InputError(f"the header declares a payload of {size} bytes")
    check_available(size, f"a viewer payload of {size:,} bytes")
    inflate = zlib.decompressobj()
    raw = inflate.decompress(payload, size + 1)
    if len(raw) != size or not inflate.eof:
        raise InputError(f"the payload is not the {size:,} bytes its header declares")
    return raw


def _decode(header: dict, raw: bytes) -> Mesh | TexturedMesh:
    """The mesh of a checked header and its decompressed payload (:func:`decode_mesh`)."""
    n, count = int(header["vertices"]), int(header["faces"])

    def section(name: str) -> bytes:
        offset, length = header["sections"][name]
        return raw[offset:offset + length]

    lo = np.asarray(header["position"]["lo"], np.float64)[:, None]
    hi = np.asarray(header["position"]["hi"], np.float64)[:, None]

    def positions(name: str, count: int) -> np.ndarray:
        q = np.frombuffer(section(name), "<u2").reshape(3, count).astype(np.float64)
        a, b, d = lo + q / _LEVELS * (hi - lo)
        with np.errstate(divide="ignore", invalid="ignore"):
            points = np.stack([a / d, b / d, 1.0 / d], axis=1).astype(np.float32)
        if not np.isfinite(points).all():
            raise InputError("positions are not finite numbers")
        return points

    vertices = positions("position", n)
    overlay = None
    if "overlay" in header:
        k, m = int(header["overlay"]["vertices"]), int(header["overlay"]["faces"])
        rgba = np.frombuffer(section("overlay_color"), np.uint8).reshape(k, 4)
        overlay = Mesh(vertices=positions("overlay_position", k), colors=rgba[:, :3].copy(),
                       labels=np.ones(k, np.uint8),
                       faces=_decode_faces(section("overlay_faces"), m),
                       width=int(header["width"]), height=int(header["height"]),
                       hfov=float(header["hfov"]), vfov=float(header["vfov"]),
                       alpha=(rgba[:, 3] / 255.0).astype(np.float32))
    if "texture" in header:
        from photo3d.structures.mesh import TexturedMesh

        uv = np.frombuffer(section("uv"), "<u2").reshape(2, n).T / _LEVELS
        return TexturedMesh(
            vertices=vertices, uv=uv.astype(np.float32), texture=decode_jpeg(section("texture")),
            labels=np.frombuffer(section("label"), np.uint8).copy(),
            faces=_decode_faces(section("faces"), count), n_input=0,
            width=int(header["width"]), height=int(header["height"]),
            hfov=float(header["hfov"]), vfov=float(header["vfov"]), overlay=overlay,
        )
    mesh = Mesh(
        vertices=vertices,
        colors=np.frombuffer(section("color"), np.uint8).reshape(n, 3).copy(),
        labels=np.frombuffer(section("label"), np.uint8).copy(),
        faces=_decode_faces(section("faces"), count),
        width=int(header["width"]), height=int(header["height"]),
        hfov=float(header["hfov"]), vfov=float(header["vfov"]),
    )
    if overlay is None:
        return mesh
    return Mesh(  # the soft silhouettes' vertices after the others, with their alpha
        vertices=np.concatenate([mesh.vertices, overlay.vertices]),
        colors=np.concatenate([mesh.colors, overlay.colors]),
        labels=np.concatenate([mesh.labels, overlay.labels]),
        faces=np.concatenate([mesh.faces, overlay.faces + n]), width=mesh.width,
        height=mesh.height, hfov=mesh.hfov, vfov=mesh.vfov,
        alpha=np.concatenate([np.ones(n, np.float32), overlay.alpha]))


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
