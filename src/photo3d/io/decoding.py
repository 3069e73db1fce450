"""Decoding image files where Pillow alone falls short, for the readers of photos
(:mod:`photo3d.io.images`) and depth maps (:mod:`photo3d.io.depth`).

* Pillow's warnings (:func:`open_image`: a damaged orientation tag refused, its
  decompression-bomb warning dropped: the readers check memory themselves) and what
  libtiff prints on file descriptor 2 (:func:`load_pixels`: one line when it fails).
* EXIF/TIFF orientation tags (:func:`orientation_of`, :func:`apply_orientation`).
* More than 8 bits per colour sample, which Pillow truncates: 16-bit colour PNGs
  through OpenCV (:func:`read_png16`, extra ``photo3d[stereo]``) and TIFF pages
  through tifffile (:func:`read_tiff_page`, extra ``photo3d[tiff]``; a declared size
  beyond Pillow's limit refused first, :func:`check_pixel_count`), as stored: the
  readers resize them and turn them upright.

Example:
    >>> orientation_of((6,))
    6
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
import warnings
import zlib
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from PIL import Image

from photo3d.errors import InputError, install_hint, require
from photo3d.io.limits import check_available


@contextlib.contextmanager
def open_image(path: Path) -> Iterator[Image.Image]:
    """``Image.open(path)``, with a TIFF orientation tag that Pillow warns holds
    several values (``(1, 6)``) refused rather than half read; Pillow's
    ``DecompressionBombWarning`` dropped (the readers check the memory decoding needs
    themselves, and refuse what does not fit); its other warnings pass through.

    Raises:
        InputError: such a tag (one line).
        UnidentifiedImageError, OSError: as ``Image.open``.
    """
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        im = Image.open(path)
    with im:
        for warning in caught:
            if issubclass(warning.category, Image.DecompressionBombWarning):
                continue  # the readers check what decoding needs against the memory
            text = str(warning.message)
            if text.startswith("Metadata Warning") and "tag 274 " in text:  # orientation
                raise InputError("the orientation tag is damaged "
                                 f"({text.removeprefix('Metadata Warning, ')})")
            warnings.warn_explicit(warning.message, warning.category, warning.filename,
                                   warning.lineno)
        yield im


def load_pixels(im: Image.Image) -> None:
    """``im.load()``, keeping what libtiff writes on file descriptor 2 off the terminal:
    replayed there if the image loads, the reason of the :class:`InputError` if not
    (so a damaged compressed TIFF gives one line). Pillow's
    ``DecompressionBombWarning`` (a TIFF warns again here) is dropped, as by
    :func:`open_image`.

    Raises:
        InputError: the pixels cannot be decoded.
    """
    if im.format != "TIFF":
        im.load()
        return
    said: list[bytes] = []
    try:
        with _stderr_into(said), warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            im.load()
    except (OSError, SyntaxError, ValueError, zlib.error) as err:
        lines = [t for t in b"".join(said).decode(errors="replace").splitlines() if t.strip()]
        detail = f" ({' '.join(lines[-1].split())[:160]})" if lines else ""
        raise InputError(f"damaged image data: {err}{detail}") from None
    if said and said[0]:
        os.write(2, said[0])


@contextlib.contextmanager
def _stderr_into(said: list[bytes]) -> Iterator[None]:
    """Redirect file descriptor 2 (where C libraries print) into ``said`` meanwhile."""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError, AttributeError):
        yield  # no descriptor 2 to redirect
        return
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            said.append(tmp.read())


def orientation_of(value) -> int:
    """The EXIF/TIFF orientation 1..8 of a tag ``value`` (None: no tag, 1).

    Numbers outside 1..8 (some cameras write 0) mean upright, as in Pillow.

    Raises:
        InputError: the tag holds text or several values.

    Example:
        >>> orientation_of(6), orientation_of((3,)), orientation_of(None), orientation_of(0)
        (6, 3, 1, 1)
        >>> orientation_of("six")
        Traceback (most recent call last):
        photo3d.errors.InputError: the orientation tag holds 'six'; expected one number 1 to 8
    """
    if value is None:
        return 1
    if isinstance(value, tuple) and len(value) == 1:
        value = value[0]
    if isinstance(value, int | np.integer) and not isinstance(value, bool):
        return int(value) if 1 <= value <= 8 else 1
    if isinstance(value, tuple) and all(isinstance(v, int) for v in value):
        value = tuple(int(v) for v in value)  # tifffile's enums, shown as numbers
    shown = repr(value) if len(repr(value)) <= 40 else repr(value)[:37] + "..."
    raise InputError(f"the orientation tag holds {shown}; expected one number 1 to 8")


def apply_orientation(array: np.ndarray, orientation: int) -> np.ndarray:
    """Turn ``(H, W, ...)`` upright for EXIF/TIFF orientation 1..8 (as Pillow does)."""
    # t = transpose rows/columns, h = mirror columns, v = mirror rows; in this order.
    steps = {2: "h", 3: "hv", 4: "v", 5: "t", 6: "th", 7: "thv", 8: "tv"}.get(orientation, "")
    if "t" in steps:
        array = np.swapaxes(array, 0, 1)
    if "h" in steps:
        array = array[:, ::-1]
    if "v" in steps:
        array = array[::-1]
    return array


def check_pixel_count(shape: tuple[int, ...]) -> None:
    """Refuse a declared size above Pillow's decompression-bomb limit, before decoding.

    Args:
        shape: the declared array shape (pixels and samples).

    Raises:
        InputError: more values than twice ``PIL.Image.MAX_IMAGE_PIXELS`` (Pillow's
            own error limit; no limit if that is None).

    Example:
        >>> check_pixel_count((1000, 1000, 3))
        >>> try:
        ...     check_pixel_count((100000, 100000))
        ... except InputError as err:
        ...     print(str(err)[:50])
        declared size 100000x100000 (10,000,000,000 values
    """
    count = int(np.prod(shape, dtype=np.float64))
    limit = Image.MAX_IMAGE_PIXELS
    if limit and count > 2 * limit:
        raise InputError(f"declared size {'x'.join(map(str, shape))} ({count:,} values) is "
                         f"more than the {2 * limit:,} photo3d accepts (decompression bomb?)")


def is_wide_colour_tiff(im: Image.Image) -> bool:
    """True for a TIFF with more than 8 bits per colour sample (Pillow truncates)."""
    if im.format != "TIFF":
        return False
    bits = im.tag_v2.get(258, (8,))
    bits = bits if isinstance(bits, tuple) else (bits,)
    return len(bits) >= 3 and max(bits) > 8


def read_tiff_page(path: Path) -> tuple[np.ndarray, int]:
    """The first page of a TIFF through tifffile (extra ``photo3d[tiff]``), for the
    files Pillow cannot decode exactly (more than 8 bits per colour sample, float64,
    multi-channel float), for :mod:`photo3d.io.images` and :mod:`photo3d.io.depth`.

    Returns:
        ``(pixels, orientation)``: ``(H, W)`` or ``(H, W, C)`` samples as stored (any
        dtype; separate colour planes are moved last) and the TIFF orientation 1..8
        (1 without the tag), not applied.

    Raises:
        MissingExtra: tifffile is not installed.
        InputError: not a readable TIFF (also damaged compressed data), too many
            pixels (:func:`check_pixel_count`) or more than the available memory
            holds (:func:`photo3d.io.limits.check_available`: twice the page's bytes
            plus 16 bytes per pixel), or an orientation tag that is not one number
            (:func:`orientation_of`).

    Example:
        >>> import pathlib, tempfile
        >>> import tifffile
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "depth.tif"
        >>> tifffile.imwrite(path, np.ones((2, 3), np.float64))
        >>> pixels, orientation = read_tiff_page(path)
        >>> pixels.shape, pixels.dtype, orientation
        ((2, 3), dtype('float64'), 1)
    """
    tifffile = require("tifffile", "tiff", purpose="this TIFF", package="the tifffile package")
    try:
        with tifffile.TiffFile(path) as tif:
            page = tif.pages[0]
            check_pixel_count(page.shape)
            pixels = int(page.imagewidth) * int(page.imagelength)
            check_available(2 * page.nbytes + 16 * pixels,
                            f"its {'x'.join(map(str, page.shape))} samples")
            array = page.asarray()
            if page.planarconfig == tifffile.PLANARCONFIG.SEPARATE and array.ndim == 3:
                array = np.moveaxis(array, 0, -1)  # (C, H, W) planes -> (H, W, C)
            tag = page.tags.get("Orientation")
    except (OSError, ValueError, IndexError, KeyError, RuntimeError, zlib.error,
            tifffile.TiffFileError) as err:  # RuntimeError: imagecodecs' decoder errors
        text = " ".join(str(err).split())[:200]
        raise InputError(f"damaged or unreadable TIFF ({text or type(err).__name__})") from err
    return array, orientation_of(tag.value if tag is not None else None)


def is_wide_colour_png(path: Path) -> bool:
    """True for a 16-bit RGB or RGBA PNG (Pillow reduces those to 8 bits)."""
    with path.open("rb") as file:
        head = file.read(26)
    return len(head) == 26 and head[24] == 16 and head[25] in (2, 6)


def read_png16(path: Path) -> np.ndarray | None:
    """A 16-bit colour PNG (:func:`is_wide_colour_png`) through OpenCV, as stored:
    ``(H, W, 3|4) uint16`` in OpenCV's BGR(A) channel order, not turned upright. None
    without OpenCV (with a warning: Pillow then reads it at 8 bits) or when OpenCV
    does not decode it to that (Pillow then decodes it, or says why it cannot)."""
    try:
        import cv2
    except ImportError:
        warnings.warn(f"{path.name}: 16-bit colour PNG read at 8 bits (full precision needs "
                      f"OpenCV: {install_hint('stereo')})", stacklevel=4)
        return None
    array = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if array is None or array.dtype != np.uint16 or array.ndim != 3:
        return None  # let Pillow decode it (or say why it cannot)
    return array
