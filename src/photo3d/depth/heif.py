"""Depth images inside HEIF/HEIC photos (iPhone and Android portraits), via pillow-heif.

A HEIF image item may carry an auxiliary *depth image* (``auxC`` type
``urn:mpeg:hevc:2015:auxid:2``), optionally with MPEG depth representation info
(representation type, ``z_near``/``z_far`` or ``d_min``/``d_max``). pillow-heif
(extra ``photo3d[heif]``) exposes it as ``HeifImage.info["depth_images"]``; it
cannot write depth images.

Limits: HEIF rotation/mirror boxes are applied by libheif to the primary image but
not necessarily to its depth image; photos with such boxes may need the depth map
rotated by hand.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from photo3d.depth.embedded import EmbeddedDepth
from photo3d.errors import InputError, require
from photo3d.io.images import check_size, to_float_image

PathLike = str | os.PathLike[str]

HEIF_BRANDS = frozenset({b"heic", b"heix", b"heim", b"heis", b"hevc", b"hevx", b"mif1",
                         b"msf1"})
"""``ftyp`` brands of HEIF (HEVC) files, which pillow-heif reads."""
AVIF_BRANDS = frozenset({b"avif", b"avis"})
"""``ftyp`` brands of AVIF files (also ``mif1``), which Pillow reads, not pillow-heif."""


def is_heif(path: PathLike) -> bool:
    """True if ``path`` is a HEIF file by its content, whatever its extension: it starts
    with an ISO-BMFF ``ftyp`` box whose major or compatible brands include one of
    :data:`HEIF_BRANDS` and none of :data:`AVIF_BRANDS`. Reads at most 256 bytes;
    False for anything else, a missing file or a folder (the image reader says why).

    Example:
        >>> import pathlib, tempfile
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "photo.jpg"
        >>> _ = path.write_bytes(b"\\x00\\x00\\x00\\x18ftypheic\\x00\\x00\\x00\\x00mif1heic")
        >>> is_heif(path), is_heif(path.parent), is_heif(path.with_name("x.heic"))
        (True, False, False)
    """
    path = Path(path)
    try:
        if not path.is_file():  # a FIFO would block
            return False
        with open(path, "rb") as f:
            head = f.read(256)
    except OSError:
        return False
    if head[4:8] != b"ftyp":
        return False
    end = min(len(head), max(16, int.from_bytes(head[:4], "big")))
    brands = {head[8:12]} | {head[i:i + 4] for i in range(16, end - 3, 4)}
    return bool(brands & HEIF_BRANDS) and not brands & AVIF_BRANDS


def read_heif_depth(path: PathLike) -> EmbeddedDepth | None:
    """The auxiliary depth image of a HEIF/HEIC's primary image, or None.

    Decoding follows the depth representation info when the file has one
    (uniform inverse z / z with ``z_near``, ``z_far`` -> depth; uniform disparity
    with ``d_min``, ``d_max`` -> disparity); otherwise the map is normalised
    disparity in [0, 1] (bright = near, as iPhone portraits store it).

    Example:
        >>> read_heif_depth("missing.heic")  # doctest: +IGNORE_EXCEPTION_DETAIL
        Traceback (most recent call last):
        photo3d.errors.InputError: image file not found: missing.heic
    """
    file = _open(path, convert_hdr_to_8bit=False)
    try:
        primary = file[file.primary_index]
    except (ValueError, RuntimeError, OSError) as err:
        raise _unreadable(path, err) from err
    images = primary.info.get("depth_images") or []
    if not images:
        return None
    depth_image = images[0]
    arr = np.asarray(depth_image.to_pillow())
    if arr.ndim == 3:
        arr = arr[..., 0]
    bits = 16 if arr.dtype == np.uint16 else 8
    v = arr.astype(np.float64) / (2**bits - 1)
    meta = depth_image.info.get("metadata") or {}
    kind_code = meta.get("representation_type")
    z_near, z_far = meta.get("z_near"), meta.get("z_far")
    d_min, d_max = meta.get("d_min"), meta.get("d_max")
    if kind_code == 0 and z_near and z_far:  # uniform inverse z
        inv = 1.0 / z_far + v * (1.0 / z_near - 1.0 / z_far)
        return EmbeddedDepth((1.0 / inv).astype(np.float32), "depth",
                             f"embedded HEIF depth image (uniform inverse z, near {z_near:g}, "
                             f"far {z_far:g})")
    if kind_code == 2 and z_near and z_far:  # uniform z
        return EmbeddedDepth((z_near + v * (z_far - z_near)).astype(np.float32), "depth",
                             f"embedded HEIF depth image (uniform z, near {z_near:g}, "
                             f"far {z_far:g})")
    if kind_code == 1 and d_min is not None and d_max is not None:
        return EmbeddedDepth((d_min + v * (d_max - d_min)).astype(np.float32), "disparity",
                             f"embedded HEIF depth image (uniform disparity {d_min:g}..{d_max:g})")
    return EmbeddedDepth(v.astype(np.float32), "disparity",
                         f"embedded HEIF depth image ({bits}-bit, taken as disparity: bright = "
                         "near)")


def read_heif_image(path: PathLike) -> np.ndarray:
    """The primary image of a HEIF/HEIC file as ``(H, W, 3) float32`` in [0, 1], at
    least ``MIN_SIDE`` pixels on each side (:func:`~photo3d.io.images.check_size`).

    Example:
        >>> read_heif_image("missing.heic")  # doctest: +IGNORE_EXCEPTION_DETAIL
        Traceback (most recent call last):
        photo3d.errors.InputError: image file not found: missing.heic
    """
    file = _open(path)
    try:
        im = file.to_pillow()  # the primary image
    except (ValueError, RuntimeError, OSError) as err:
        raise _unreadable(path, err) from err
    return check_size(to_float_image(np.asarray(im.convert("RGB"))), path)


def _open(path: PathLike, **options):
    """``pillow_heif.open_heif(path)`` with photo3d's errors for missing or bad files."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"image file not found: {path}")
    pillow_heif = _pillow_heif(path)
    try:
        return pillow_heif.open_heif(path, **options)
    except (ValueError, RuntimeError, OSError) as err:
        raise _unreadable(path, err) from err


def _unreadable(path: PathLike, err: Exception) -> InputError:
    """One line for a HEIF libheif cannot read (its messages may end in a newline)."""
    return InputError(f"cannot read HEIF {path}: {' '.join(str(err).split())}")


def _pillow_heif(path: Path):
    """pillow-heif, or :class:`~photo3d.errors.MissingExtra` naming ``path`` and the extra."""
    return require("pillow_heif", "heif", purpose=f"reading the HEIF/HEIC file {path}",
                   package="pillow-heif")
