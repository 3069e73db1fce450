"""Read and write photos: JPEG, PNG, TIFF and WebP through Pillow.

Every image inside photo3d is ``(H, W, 3) float32`` in [0, 1]. The rules that turn a
file or an in-memory array into that form live here, in :func:`to_float_image`:

* 8-bit values are divided by 255, 16-bit values by 65535; float values must
  already lie in [0, 1].
* Grey images are replicated to 3 equal channels.
* Transparent images (RGBA, LA, palette with transparency) are composited over
  **white**: ``rgb * alpha + 1 * (1 - alpha)``.
* Files are turned upright by their EXIF orientation before anything else.

Example:
    >>> import numpy as np
    >>> to_float_image(np.full((8, 8), 255, np.uint8))[0, 0]
    array([1., 1., 1.], dtype=float32)
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
from PIL import Image, ImageOps, UnidentifiedImageError

from photo3d.errors import InputError, OutputError, install_hint, require

PathLike = str | os.PathLike[str]

MIN_SIDE = 8
"""Smallest width and height, in pixels, of a photo photo3d accepts."""

WRITE_FORMATS = {".png": "PNG", ".jpg": "JPEG", ".jpeg": "JPEG"}
"""Extensions :func:`write_image` writes, mapped to the Pillow format name."""

_TIFF_EXTENSIONS = (".tif", ".tiff")
_ALPHA_MODES = ("RGBA", "LA", "PA", "RGBa", "La")
_UINT16_MODES = ("I;16", "I;16L", "I;16B", "I;16N")


def to_float_image(array: np.ndarray) -> np.ndarray:
    """Normalise an in-memory picture to photo3d's image form.

    Args:
        array: ``(H, W)`` grey, ``(H, W, 3)`` RGB or ``(H, W, 4)`` RGBA; dtype
            ``uint8`` (0..255), ``uint16`` (0..65535) or float (values in [0, 1]).

    Returns:
        ``(H, W, 3) float32`` in [0, 1], a new C-contiguous array. Grey is replicated
        to 3 channels; RGBA is composited over white.

    Raises:
        InputError: wrong shape, unsupported dtype, or float values that are not
            finite or lie outside [0, 1].

    Example:
        >>> import numpy as np
        >>> rgba = np.zeros((8, 8, 4), np.uint8)  # black, fully transparent
        >>> to_float_image(rgba)[0, 0]
        array([1., 1., 1.], dtype=float32)
        >>> to_float_image(np.full((8, 8, 3), 32768, np.uint16))[0, 0, 0].round(3)
        np.float32(0.5)
    """
    array = np.asarray(array)
    shape_ok = array.ndim == 2 or (array.ndim == 3 and array.shape[2] in (3, 4))
    if not shape_ok:
        raise InputError(f"image has shape {array.shape}; expected (H, W), (H, W, 3) or (H, W, 4)")
    if array.shape[0] == 0 or array.shape[1] == 0:
        raise InputError(f"image has shape {array.shape}; it holds no pixels")
    image = _scale_to_unit(array)
    if image.ndim == 2:
        image = np.repeat(image[:, :, None], 3, axis=2)
    elif image.shape[2] == 4:
        alpha = image[:, :, 3:]
        image = image[:, :, :3] * alpha + (1.0 - alpha)
    return np.ascontiguousarray(image, dtype=np.float32)


def read_image(path: PathLike) -> np.ndarray:
    """Read a photo and return it upright, as ``(H, W, 3) float32`` in [0, 1].

    Reads JPEG, PNG, TIFF and WebP with Pillow (anything else Pillow opens works
    too). The EXIF orientation is applied, so a phone photo taken in portrait comes
    back portrait. Conversions follow :func:`to_float_image`: grey (``L``, ``I;16``,
    ``I``, ``F``) is replicated to 3 channels, transparency (``RGBA``, ``LA``,
    palette) is composited over white, 16-bit values are divided by 65535. 16-bit
    RGB TIFFs are read with ``tifffile`` (extra ``photo3d[tiff]``), 16-bit colour
    PNGs with OpenCV (extra ``photo3d[stereo]``; without it they are read at 8 bits,
    with a warning). Only the first frame of a multi-frame file is read.

    Args:
        path: the image file.

    Returns:
        ``(H, W, 3) float32`` in [0, 1], at least ``MIN_SIDE`` pixels on each side.

    Raises:
        InputError: the file is missing, is not a readable image, needs ``tifffile``
            which is not installed, or is smaller than 8x8 pixels.

    Example:
        >>> import pathlib, tempfile
        >>> import numpy as np
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "grey.png"
        >>> write_image(path, np.full((8, 10, 3), 0.5, np.float32))
        >>> image = read_image(path)
        >>> image.shape, image.dtype, round(float(image[0, 0, 0]) * 255)
        ((8, 10, 3), dtype('float32'), 128)
    """
    path = Path(path)
    if not path.is_file():
        if path.is_dir():
            raise InputError(f"cannot read image {path}: it is a folder, not a file")
        raise InputError(f"image file not found: {path}")
    try:
        array = _read_pixels(path)
        image = to_float_image(array)
    except InputError as err:
        raise InputError(f"cannot read image {path}: {err}") from err
    height, width = image.shape[:2]
    if height < MIN_SIDE or width < MIN_SIDE:
        raise InputError(
            f"image {path} is {width}x{height} pixels; photo3d needs at least {MIN_SIDE}x{MIN_SIDE}"
        )
    return image


def write_image(path: PathLike, image: np.ndarray, *, quality: int = 95) -> None:
    """Write an 8-bit PNG or JPEG (chosen by the extension), overwriting ``path``.

    Args:
        path: ``.png``, ``.jpg`` or ``.jpeg`` file; its folder must exist.
        image: ``(H, W, 3)`` or ``(H, W)`` array, either float in [0, 1] (clipped to
            [0, 1], then ``round(255 * v)``) or ``uint8`` (written as is).
        quality: JPEG quality 1..95 (ignored for PNG).

    Raises:
        InputError: ``image`` has the wrong shape or dtype, or holds NaN.
        OutputError: unsupported extension, or the file cannot be written.

    Example:
        >>> import pathlib, tempfile
        >>> import numpy as np
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "red.png"
        >>> red = np.zeros((8, 8, 3), np.float32)
        >>> red[..., 0] = 1.0
        >>> write_image(path, red)
        >>> read_image(path)[0, 0]
        array([1., 0., 0.], dtype=float32)
    """
    path = Path(path)
    fmt = WRITE_FORMATS.get(path.suffix.lower())
    if fmt is None:
        raise OutputError(
            f"cannot write image {path}: unsupported extension {path.suffix!r}; "
            "use .png, .jpg or .jpeg"
        )
    pixels = _to_uint8(image)
    try:
        options = {"quality": int(quality)} if fmt == "JPEG" else {}
        Image.fromarray(pixels).save(path, format=fmt, **options)
    except OSError as err:
        raise OutputError(f"cannot write image {path}: {err.strerror or err}") from err


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


def _scale_to_unit(array: np.ndarray) -> np.ndarray:
    """Map uint8 / uint16 / float values to float32 in [0, 1] (shape unchanged)."""
    if array.dtype == np.uint8:
        return array.astype(np.float32) / np.float32(255.0)
    if array.dtype == np.uint16:
        return array.astype(np.float32) / np.float32(65535.0)
    if not np.issubdtype(array.dtype, np.floating):
        raise InputError(f"image has dtype {array.dtype}; expected uint8, uint16 or float")
    image = array.astype(np.float32)
    if not np.isfinite(image).all():
        raise InputError("image holds NaN or infinite values")
    low, high = float(image.min()), float(image.max())
    if low < 0.0 or high > 1.0:
        raise InputError(f"float image values span [{low:g}, {high:g}]; expected [0, 1]")
    return image


def _to_uint8(image: np.ndarray) -> np.ndarray:
    """Validate a picture for writing and return ``(H, W[, 3]) uint8``."""
    image = np.asarray(image)
    if not (image.ndim == 2 or (image.ndim == 3 and image.shape[2] == 3)):
        raise InputError(f"image has shape {image.shape}; expected (H, W, 3) or (H, W)")
    if image.dtype == np.uint8:
        return np.ascontiguousarray(image)
    if not np.issubdtype(image.dtype, np.floating):
        raise InputError(f"image has dtype {image.dtype}; expected float in [0, 1] or uint8")
    if np.isnan(image).any():
        raise InputError("image holds NaN values")
    return np.round(np.clip(image, 0.0, 1.0) * 255.0).astype(np.uint8)


def _read_pixels(path: Path) -> np.ndarray:
    """Decode ``path`` to an upright array that :func:`to_float_image` accepts."""
    try:
        with open_image(path) as im:
            if _is_wide_colour_tiff(im):
                return _read_tiff_with_tifffile(path)
            orientation = orientation_of(im.getexif().get(0x0112))
            if im.format == "PNG" and _is_wide_colour_png(path):
                wide = _read_png16_colour(path, orientation)
                if wide is not None:
                    return wide
            load_pixels(im)
            im = ImageOps.exif_transpose(im)
            return _pixels_of(im)
    except UnidentifiedImageError as err:
        if path.suffix.lower() in _TIFF_EXTENSIONS:
            return _read_tiff_with_tifffile(path)
        raise InputError("not a recognised image format") from err
    except (OSError, SyntaxError, Image.DecompressionBombError) as err:
        raise InputError(str(err)) from err


@contextlib.contextmanager
def open_image(path: Path) -> Iterator[Image.Image]:
    """``Image.open(path)``, with a TIFF orientation tag that Pillow warns holds
    several values (``(1, 6)``) refused rather than half read; Pillow's other
    warnings pass through.

    Raises:
        InputError: such a tag (one line).
        UnidentifiedImageError, OSError: as ``Image.open``.
    """
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        im = Image.open(path)
    with im:
        for warning in caught:
            text = str(warning.message)
            if text.startswith("Metadata Warning") and "tag 274 " in text:  # orientation
                raise InputError("the orientation tag is damaged "
                                 f"({text.removeprefix('Metadata Warning, ')})")
            warnings.warn_explicit(warning.message, warning.category, warning.filename,
                                   warning.lineno)
        yield im


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


def load_pixels(im: Image.Image) -> None:
    """``im.load()``, keeping what libtiff writes on file descriptor 2 off the terminal:
    replayed there if the image loads, the reason of the :class:`InputError` if not
    (so a damaged compressed TIFF gives one line).

    Raises:
        InputError: the pixels cannot be decoded.
    """
    if im.format != "TIFF":
        im.load()
        return
    said: list[bytes] = []
    try:
        with _stderr_into(said):
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


def _pixels_of(im: Image.Image) -> np.ndarray:
    """Array of a loaded Pillow image in a dtype/shape :func:`to_float_image` takes."""
    mode = im.mode
    if mode in _UINT16_MODES:
        return np.asarray(im).astype(np.uint16)
    if mode == "I":
        values = np.asarray(im)
        if values.size and (values.min() < 0 or values.max() > 65535):
            raise InputError("32-bit integer pixels outside 0..65535 are not supported")
        return values.astype(np.uint16)
    if mode == "F":
        return np.asarray(im, dtype=np.float32)
    if mode == "L":
        return np.asarray(im)
    transparent = mode in _ALPHA_MODES or "transparency" in im.info
    return np.asarray(im.convert("RGBA" if transparent else "RGB"))


def _is_wide_colour_png(path: Path) -> bool:
    """True for a 16-bit RGB or RGBA PNG (Pillow reduces those to 8 bits)."""
    with path.open("rb") as file:
        head = file.read(26)
    return len(head) == 26 and head[24] == 16 and head[25] in (2, 6)


def _read_png16_colour(path: Path, orientation: int) -> np.ndarray | None:
    """``(H, W, 3|4) uint16`` of a 16-bit colour PNG through OpenCV, or None without it."""
    try:
        import cv2
    except ImportError:
        warnings.warn(f"{path.name}: 16-bit colour PNG read at 8 bits (full precision needs "
                      f"OpenCV: {install_hint('stereo')})", stacklevel=3)
        return None
    array = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if array is None or array.dtype != np.uint16 or array.ndim != 3:
        return None  # let Pillow decode it (or say why it cannot)
    order = [2, 1, 0, 3][: array.shape[2]]  # BGR(A) -> RGB(A)
    return _apply_orientation(np.ascontiguousarray(array[:, :, order]), int(orientation))


def _is_wide_colour_tiff(im: Image.Image) -> bool:
    """True for a TIFF with more than 8 bits per colour sample (Pillow truncates)."""
    if im.format != "TIFF":
        return False
    bits = im.tag_v2.get(258, (8,))
    bits = bits if isinstance(bits, tuple) else (bits,)
    return len(bits) >= 3 and max(bits) > 8


def read_tiff_page(path: Path) -> tuple[np.ndarray, int]:
    """The first page of a TIFF through tifffile (extra ``photo3d[tiff]``), for the
    files Pillow cannot decode exactly (more than 8 bits per colour sample, float64,
    multi-channel float). Shared by :mod:`photo3d.io.depth`.

    Returns:
        ``(pixels, orientation)``: ``(H, W)`` or ``(H, W, C)`` samples as stored (any
        dtype; separate colour planes are moved last) and the TIFF orientation 1..8
        (1 without the tag), not applied.

    Raises:
        MissingExtra: tifffile is not installed.
        InputError: not a readable TIFF (also damaged compressed data), too many
            pixels (:func:`check_pixel_count`), or an orientation tag that is not one
            number (:func:`orientation_of`).

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
            array = page.asarray()
            if page.planarconfig == tifffile.PLANARCONFIG.SEPARATE and array.ndim == 3:
                array = np.moveaxis(array, 0, -1)  # (C, H, W) planes -> (H, W, C)
            tag = page.tags.get("Orientation")
    except (OSError, ValueError, IndexError, KeyError, RuntimeError, zlib.error,
            tifffile.TiffFileError) as err:  # RuntimeError: imagecodecs' decoder errors
        text = " ".join(str(err).split())[:200]
        raise InputError(f"damaged or unreadable TIFF ({text or type(err).__name__})") from err
    return array, orientation_of(tag.value if tag is not None else None)


def _read_tiff_with_tifffile(path: Path) -> np.ndarray:
    """Read the first page of a TIFF Pillow cannot decode, applying its orientation."""
    array, orientation = read_tiff_page(path)
    if array.ndim == 3 and array.shape[2] > 4:
        raise InputError(f"TIFF has {array.shape[2]} channels; expected 1, 3 or 4")
    if array.dtype.kind in "iu" and array.dtype.itemsize > 2:
        raise InputError(f"TIFF samples of dtype {array.dtype} are not supported")
    if array.ndim == 3 and array.shape[2] == 1:
        array = array[:, :, 0]
    return _apply_orientation(array, orientation)


def _apply_orientation(array: np.ndarray, orientation: int) -> np.ndarray:
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
