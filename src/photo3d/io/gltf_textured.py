"""Textured binary glTF 2.0 (``.glb``): the light mesh with its texture as JPEG.

:func:`write_textured_glb` writes what :func:`photo3d.io.gltf.write_glb` does
(positions in glTF axes, ``_LABEL``, unlit material, the input camera node) with
``TEXCOORD_0`` and one embedded sRGB JPEG base-colour texture instead of vertex
colours; :func:`read_textured_glb` reads it back, checking what it reads.
"""

from __future__ import annotations

import io
import os
import struct
import warnings
from typing import TYPE_CHECKING

import numpy as np

from photo3d.errors import InputError
from photo3d.io.glb import (
    ARRAY_BUFFER,
    TO_GLTF,
    TRIANGLES,
    UNLIT,
    WHITE,
    accessor,
    read_chunks,
    read_fringe,
    triangles,
    view_bytes,
    write_glb_file,
)
from photo3d.io.limits import check_available

if TYPE_CHECKING:
    from photo3d.structures.mesh import TexturedMesh

PathLike = str | os.PathLike[str]


def write_textured_glb(path: PathLike, mesh: TexturedMesh, *, quality: int = 90) -> None:
    """Write a textured mesh as a binary glTF 2.0 file (texture embedded as JPEG).

    The file holds ``POSITION``, ``TEXCOORD_0`` and ``_LABEL`` as :func:`write_glb`
    does, one sRGB base-colour texture (linear filtering, clamped; no mipmaps, so
    atlas charts do not bleed into each other) on an unlit material, and the input
    camera as a camera node. The mesh's ``overlay`` (soft silhouettes), if any, is a
    second primitive drawn blended (:func:`photo3d.io.glb.write_glb_file`).

    Args:
        path: file to create (overwritten if it exists).
        mesh: :class:`~photo3d.structures.mesh.TexturedMesh` with ``N >= 1``, ``M >= 1``.
        quality: JPEG quality of the texture (1-95).

    Raises:
        InputError: the mesh is empty or inconsistent.
        OutputError: ``path`` cannot be written.

    Example:
        >>> import numpy as np, tempfile, pathlib
        >>> from photo3d.mesh.light import TexturedMesh
        >>> mesh = TexturedMesh(np.eye(3, dtype=np.float32) + [0, 0, 1],
        ...                     np.array([[0, 0], [1, 0], [0, 1]], np.float32),
        ...                     np.zeros((4, 4, 3), np.uint8), np.ones(3, np.uint8),
        ...                     np.array([[0, 2, 1]], np.int32), 1, 4, 3, 0.5, 0.4)
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "mesh.glb"
        >>> write_textured_glb(path, mesh)
        >>> read_textured_glb(path).texture.shape
        (4, 4, 3)
    """
    vertices, uv, labels, faces = mesh.checked()
    if len(vertices) == 0 or len(faces) == 0:
        raise InputError("mesh has no vertices or no faces; glTF cannot store it")
    if not np.isfinite(vertices).all() or not np.isfinite(uv).all():
        raise InputError("mesh.vertices or mesh.uv has NaN or infinite values")
    image = encode_jpeg(np.asarray(mesh.texture), quality=quality)
    arrays = [(uv, "VEC2", ARRAY_BUFFER, None)]
    primitive = {"attributes": {"POSITION": 0, "TEXCOORD_0": 1, "_LABEL": 2}, "indices": 3,
                 "material": 0, "mode": TRIANGLES}
    material = {
        "name": "unlit photo texture",
        "pbrMetallicRoughness": {"baseColorFactor": WHITE, "baseColorTexture": {"index": 0},
                                 "metallicFactor": 0.0, "roughnessFactor": 1.0},
        "extensions": {UNLIT: {}},
        "doubleSided": False,
    }
    write_glb_file(path, mesh, vertices, labels, faces, arrays, primitive, material, image=image,
                   fringe=mesh.overlay)


def read_textured_glb(path: PathLike, *, max_pixels: int | None = None) -> TexturedMesh:
    """Read a ``.glb`` written by :func:`write_textured_glb` (tests, tools).

    Everything is checked before it is decoded (:func:`photo3d.io.glb.read_chunks`,
    :func:`~photo3d.io.glb.accessor`); the texture's size is read from its header and
    refused above ``max_pixels`` (default: Pillow's ``MAX_IMAGE_PIXELS``) or what
    the available memory holds, before it is decoded.

    Returns:
        :class:`~photo3d.structures.mesh.TexturedMesh` (texture decoded from its JPEG).

    Raises:
        InputError: the file is not such a GLB (or is inconsistent: attribute
            lengths, indices out of range).
    """
    from photo3d.structures.mesh import TexturedMesh

    document, binary = read_chunks(path)
    try:
        mesh = document["meshes"][0]
        primitive = mesh["primitives"][0]
        attributes = primitive["attributes"]
        positions = accessor(document, binary, attributes["POSITION"], path)
        uv = accessor(document, binary, attributes["TEXCOORD_0"], path)
        labels = accessor(document, binary, attributes["_LABEL"], path,
                              kinds=(5121,))[:, 0]
        faces = triangles(document, binary, primitive["indices"], path, len(positions))
        image = document["images"][0]
        jpeg = view_bytes(document, binary, image["bufferView"], path)
        extras = mesh.get("extras", {})
        view = {k: float(extras.get(k, 0)) for k in ("width", "height", "hfov", "vfov")}
        overlay = read_fringe(document, binary, path, extras)
    except InputError:
        raise
    except (KeyError, IndexError, TypeError, ValueError, AttributeError, OverflowError) as err:
        raise InputError(f"glTF {path} is not a photo3d textured mesh ({err!r})"[:300]
                         ) from None
    count = len(positions)
    if positions.shape[1] != 3 or uv.shape[1] != 2:
        raise InputError(f"glTF {path} has positions or texture coordinates of another shape")
    if len(uv) != count or len(labels) != count:
        raise InputError(f"glTF {path} has attributes of different lengths")
    if not (np.isfinite(positions).all() and np.isfinite(uv).all()):
        raise InputError(f"glTF {path} has NaN or infinite positions or texture coordinates")
    if not all(np.isfinite(v) and 0 <= v < 2**31 for v in view.values()):
        raise InputError(f"glTF {path} has an invalid view in its extras")
    texture = decode_jpeg(jpeg, max_pixels=max_pixels, what=f"glTF {path}'s texture")
    return TexturedMesh(
        vertices=(positions * TO_GLTF).astype(np.float32), uv=uv.astype(np.float32),
        texture=texture, labels=labels.astype(np.uint8), faces=faces.astype(np.int32),
        n_input=0, width=int(view["width"]), height=int(view["height"]),
        hfov=view["hfov"], vfov=view["vfov"], overlay=overlay,
    )


def encode_jpeg(image: np.ndarray, *, quality: int = 90) -> bytes:
    """``(H, W, 3) uint8`` sRGB -> baseline JPEG bytes (4:2:0, optimised tables).

    Example:
        >>> decode_jpeg(encode_jpeg(np.full((8, 8, 3), 200, np.uint8))).shape
        (8, 8, 3)
    """
    from PIL import Image

    if not 1 <= quality <= 95:
        raise InputError(f"JPEG quality must be in [1, 95], got {quality}")
    buffer = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(image, np.uint8)).save(
        buffer, format="JPEG", quality=int(quality), optimize=True)
    return buffer.getvalue()


def decode_jpeg(data: bytes, *, max_pixels: int | None = None,
                what: str = "the texture") -> np.ndarray:
    """JPEG (or PNG) bytes -> ``(H, W, 3) uint8``.

    The size is read from the header first: more than ``max_pixels`` (default:
    Pillow's ``MAX_IMAGE_PIXELS``) or more than the available memory holds is
    refused before anything is decoded; anything Pillow cannot read is one line.

    Raises:
        InputError: ``cannot read WHAT: REASON``.

    Example:
        >>> decode_jpeg(encode_jpeg(np.zeros((16, 8, 3), np.uint8))).shape
        (16, 8, 3)
        >>> decode_jpeg(encode_jpeg(np.zeros((16, 8, 3), np.uint8)), max_pixels=100)
        Traceback (most recent call last):
        photo3d.errors.InputError: cannot read the texture: it is 8x16 pixels, more than the 100 expected
        >>> decode_jpeg(b"not an image")
        Traceback (most recent call last):
        photo3d.errors.InputError: cannot read the texture: not a JPEG or PNG image
    """  # noqa: E501
    from PIL import Image, UnidentifiedImageError

    limit = Image.MAX_IMAGE_PIXELS if max_pixels is None else max_pixels
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            with Image.open(io.BytesIO(data)) as im:
                if im.format not in ("JPEG", "PNG"):
                    raise UnidentifiedImageError(im.format)
                w, h = im.size
                if limit is not None and w * h > limit:
                    raise InputError(f"cannot read {what}: it is {w}x{h} pixels, more than "
                                     f"the {limit} expected")
                check_available(6 * w * h, f"{what}'s {w}x{h} pixels")
                return np.asarray(im.convert("RGB"))
    except InputError:
        raise
    except UnidentifiedImageError:
        raise InputError(f"cannot read {what}: not a JPEG or PNG image") from None
    except (OSError, ValueError, SyntaxError, EOFError, struct.error, Image.DecompressionBombError,
            ZeroDivisionError) as err:
        reason = str(err).splitlines()[0][:200] if str(err) else type(err).__name__
        raise InputError(f"cannot read {what}: {reason}") from None
