"""Read and write photos: JPEG, PNG, TIFF and WebP through Pillow.

Every image inside photo3d is ``(H, W, 3) float32`` in [0, 1]. The rules that turn a
file or an in-memory array into that form live here, in :func:`to_float_image`:

* 8-bit values are divided by 255, 16-bit values by 65535; float values must
  already lie in [0, 1].
* Grey images are replicated to 3 equal channels.
* Transparent images (RGBA, LA, palette with transparency) are composited over
  **white**: ``rgb * alpha + 1 * (1 - alpha)``.
* Files are turned upright by their EXIF orientation before anything else.
* A photo read for a working size (``read_image(path, working_size=1024)``) that is
  much larger is decoded reduced (:func:`decoded_shape`), and what decoding needs is
  checked against the available memory before any pixel is decoded.

What Pillow needs help with to decode a file (its warnings, libtiff's messages,
orientation tags, more than 8 bits per colour sample through OpenCV or tifffile) is
in :mod:`photo3d.io.decoding`.

Example:
    >>> import numpy as np
    >>> to_float_image(np.full((8, 8), 255, np.uint8))[0, 0]
    array([1., 1., 1.], dtype=float32)
"""

from __future__ import annotations

import math
import os
import struct
import warnings
from pathlib import Path

import numpy as np
from PIL import Image, UnidentifiedImageError

from photo3d.config import working_shape
from photo3d.errors import InputError, OutputError
from photo3d.files.atomic import writing
from photo3d.io.decoding import (
    apply_orientation,
    is_wide_colour_png,
    is_wide_colour_tiff,
    load_pixels,
    open_image,
    orientation_of,
    read_png16,
    read_tiff_page,
)
from photo3d.io.limits import check_available

PathLike = str | os.PathLike[str]

MIN_SIDE = 8
"""Smallest width and height, in pixels, of a photo photo3d accepts."""

WRITE_FORMATS = {".png": "PNG", ".jpg": "JPEG", ".jpeg": "JPEG"}
"""Extensions :func:`write_image` writes, mapped to the Pillow format name."""

KEEP = 2
"""A photo read for a working size and more than ``KEEP`` times larger is decoded at
``KEEP`` times that size (:func:`decoded_shape`), so that the pipeline's own resize to
the working size gives what it gives from the whole photo: on natural photos (PNG and
JPEG, decoded 1.1 to 10 times smaller) the working image differs by 0.1-0.3 / 255 on
average, at most 10 / 255 at sharp edges."""

_TIFF_EXTENSIONS = (".tif", ".tiff")
_ALPHA_MODES = ("RGBA", "LA", "PA", "RGBa", "La")
_UINT16_MODES = ("I;16", "I;16L", "I;16B", "I;16N")
_RESIZABLE = ("L", "LA", "RGB", "RGBA", "CMYK", "YCbCr", "RGBX")
"""8-bit modes Pillow resizes as they are (a palette index or a 1-bit pixel it would
not average; 16- and 32-bit grey is resized as float32, :func:`_resize_array`)."""
_GAP = 3.0  # Pillow's reducing_gap: a box reduction first, to 3 times the size at least
_ASPECT = 1e-3  # the largest change of aspect ratio a reduction may make
_FLOAT_BYTES = 48  # per returned pixel: the float32 image and the temporaries making it
_BAND = 256  # rows converted to float32 at a time by _resize_array


def to_float_image(array: np.ndarray) -> np.ndarray:
    """Normalise an in-memory picture to photo3d's image form.

    Args:
        array: ``(H, W)`` grey, ``(H, W, 3)`` RGB or ``(H, W, 4)`` RGBA; dtype
            ``uint8`` (0..255), ``uint16`` (0..65535) or float (values in [0, 1]).

    Returns:
        ``(H, W, 3) float32`` in [0, 1], a new C-contiguous array. Grey is replicated
        to 3 channels; RGBA is composited over white.

    Raises:
        InputError: wrong shape, unsupported dtype, float values that are not
            finite or lie outside [0, 1], or more pixels than the available memory
            holds as float32 (:func:`photo3d.io.limits.check_available`).

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
    check_available(_FLOAT_BYTES * array.shape[0] * array.shape[1],
                    f"the image's {array.shape[1]}x{array.shape[0]} pixels")
    image = _scale_to_unit(array)
    if image.ndim == 2:
        image = np.repeat(image[:, :, None], 3, axis=2)
    elif image.shape[2] == 4:
        alpha = image[:, :, 3:]
        image = image[:, :, :3] * alpha + (1.0 - alpha)
    return np.ascontiguousarray(image, dtype=np.float32)


def read_image(path: PathLike, *, working_size: int | None = None) -> np.ndarray:
    """Read a photo and return it upright, as ``(H, W, 3) float32`` in [0, 1].

    Reads JPEG, PNG, TIFF and WebP with Pillow (anything else Pillow opens works
    too). The EXIF orientation is applied, so a phone photo taken in portrait comes
    back portrait. Conversions follow :func:`to_float_image`: grey (``L``, ``I;16``,
    ``I``, ``F``) is replicated to 3 channels, transparency (``RGBA``, ``LA``,
    palette) is composited over white, 16-bit values are divided by 65535. 16-bit
    RGB TIFFs are read with ``tifffile`` (extra ``photo3d[tiff]``), 16-bit colour
    PNGs with OpenCV (extra ``photo3d[stereo]``; without it they are read at 8 bits,
    with a warning). Only the first frame of a multi-frame file (an animated GIF,
    WebP or PNG, a multi-page TIFF) is read, with a warning that says so.

    Given ``working_size``, a photo more than ``KEEP`` times larger is decoded at
    :func:`decoded_shape` (a JPEG first scaled by its decoder, then Lanczos as the
    pipeline resizes, before the float conversion), so that a small file of many
    pixels never exists as float32; smaller photos are decoded exactly. Before any
    pixel is decoded, what decoding needs (estimated from the header) is checked
    against the available memory (:func:`photo3d.io.limits.check_available`).

    Args:
        path: the image file.
        working_size: the longer side the caller resizes the photo to (None: the
            photo is wanted whole).

    Returns:
        ``(H, W, 3) float32`` in [0, 1], at least ``MIN_SIDE`` pixels on each side;
        its shape is :func:`decoded_shape` of the upright file's.

    Raises:
        InputError: the file is missing, is not a readable image, needs ``tifffile``
            which is not installed, is smaller than 8x8 pixels, or needs more memory
            to decode than is available.

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
        array = _read_pixels(path, working_size)
        image = to_float_image(array)
    except InputError as err:
        raise InputError(f"cannot read image {path}: {err}") from err
    return check_size(image, path)


def check_size(image: np.ndarray, path: PathLike) -> np.ndarray:
    """``image`` (``(H, W, ...)``, read from ``path``) if it is at least ``MIN_SIDE``
    pixels on each side; every photo reader ends with this check.

    Raises:
        InputError: a smaller image, naming ``path``, its size and the minimum.

    Example:
        >>> check_size(np.zeros((4, 4, 3), np.float32), "tiny.heic")
        Traceback (most recent call last):
        ...
        photo3d.errors.InputError: image tiny.heic is 4x4 pixels; photo3d needs at least 8x8
    """
    height, width = image.shape[:2]
    if height < MIN_SIDE or width < MIN_SIDE:
        raise InputError(
            f"image {path} is {width}x{height} pixels; photo3d needs at least {MIN_SIDE}x{MIN_SIDE}"
        )
    return image


def image_shape(path: PathLike) -> tuple[int, int] | None:
    """The upright ``(height, width)`` of an image file from its header, without
    decoding a pixel (so that the memory a photo needs can be checked before it is
    read); None if the header cannot be read (the reader then says why).

    Example:
        >>> import pathlib, tempfile
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "wide.png"
        >>> write_image(path, np.zeros((8, 20, 3), np.float32))
        >>> image_shape(path)
        (8, 20)
    """
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the reader reports what it finds
            with open_image(Path(path)) as im:
                w, h = im.size
                try:
                    turned = orientation_of(im.getexif().get(0x0112)) >= 5
                except InputError:
                    turned = False
    except (OSError, SyntaxError, ValueError, InputError, Image.DecompressionBombError,
            UnidentifiedImageError):
        return None
    return (w, h) if turned else (h, w)


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
        with writing(path) as target:
            Image.fromarray(pixels).save(target, format=fmt, **options)
    except OSError as err:
        raise OutputError(f"cannot write image {path}: {err.strerror or err}") from err


def decoded_shape(shape: tuple[int, int], working_size: int | None) -> tuple[int, int]:
    """``(H, W)`` of what :func:`read_image` returns for a photo of ``shape`` read for
    ``working_size``: ``shape`` itself up to ``KEEP * working_size`` on the longer side
    (or without a working size), else about that: the first longer side from there
    whose shape keeps the aspect ratio within 0.1 %, the pipeline's working shape
    (:func:`photo3d.config.working_shape`) of ``shape`` and ``KEEP`` times
    its shorter side, at least ``MIN_SIDE`` (``shape`` itself if none below twice
    ``KEEP * working_size`` does: a very elongated photo).

    Example:
        >>> decoded_shape((9750, 13000), 512), decoded_shape((3000, 4000), 2048)
        ((768, 1024), (3000, 4000))
    """
    h, w = shape
    longer = max(h, w)
    if working_size is None or longer <= KEEP * working_size:
        return h, w
    working = working_shape(shape, working_size)
    for side in range(KEEP * working_size, min(longer, 2 * KEEP * working_size)):
        reduced = max(1, round(h * side / longer)), max(1, round(w * side / longer))
        if (min(reduced) >= max(MIN_SIDE, KEEP * min(working))
                and abs(math.log(reduced[1] * h / (reduced[0] * w))) <= _ASPECT  # either way up
                and working_shape(reduced, working_size) == working):
            return reduced
    return h, w


def _scale_to_unit(array: np.ndarray) -> np.ndarray:
    """Map uint8 / uint16 / float values to float32 in [0, 1] (shape unchanged)."""
    if array.dtype in (np.uint8, np.uint16):
        image = array.astype(np.float32)
        image /= np.float32(255.0 if array.dtype == np.uint8 else 65535.0)  # in place
        return image
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


def _read_pixels(path: Path, working_size: int | None) -> np.ndarray:
    """Decode ``path`` (at :func:`decoded_shape` for ``working_size``) to an upright
    array that :func:`to_float_image` accepts, after checking the memory it needs."""
    try:
        with open_image(path) as im:
            _note_frames(path, im)
            if is_wide_colour_tiff(im):
                return _read_tiff_with_tifffile(path, working_size)
            orientation = orientation_of(im.getexif().get(0x0112))
            w, h = im.size
            rh, rw = decoded_shape((h, w), working_size)
            returned = rh * rw * _FLOAT_BYTES
            what = f"its {w}x{h} pixels"
            if im.format == "PNG" and is_wide_colour_png(path):
                check_available(16 * w * h + returned, what)  # OpenCV's, one plane
                wide = _read_png16_colour(path, orientation, (rh, rw))
                if wide is not None:
                    return wide
            box = (0, 0, w, h)
            if (rh, rw) != (h, w) and im.format in ("JPEG", "MPO"):
                scaled = im.draft(None, (int(rw * _GAP), int(rh * _GAP)))  # by the decoder
                box = scaled[1] if scaled else box
            check_available(_decode_bytes(im) * im.size[0] * im.size[1] + returned, what)
            load_pixels(im)
            return apply_orientation(_resized(im, (rh, rw), box), orientation)
    except InputError:
        raise
    except UnidentifiedImageError as err:
        if path.suffix.lower() in _TIFF_EXTENSIONS:
            return _read_tiff_with_tifffile(path, working_size)
        raise InputError("not a recognised image format") from err
    except (OSError, SyntaxError, EOFError, ValueError, struct.error,
            Image.DecompressionBombError) as err:  # Pillow's words for a damaged file
        raise InputError(str(err).splitlines()[0] if str(err) else type(err).__name__
                         ) from err


def _note_frames(path: Path, im: Image.Image) -> None:
    """Warn that only the first frame of an animated or multi-page file is read (not
    for a phone's MPO JPEG, whose further frames are its own previews and maps)."""
    frames = getattr(im, "n_frames", 1)
    if im.format != "MPO" and isinstance(frames, int) and frames > 1:
        kind = "pages" if im.format == "TIFF" else "frames"
        warnings.warn(f"{path.name} has {frames} {kind}; photo3d uses the first",
                      stacklevel=4)


def _decode_bytes(im: Image.Image) -> int:
    """Bytes per pixel of ``im`` decoded by Pillow, and of the copy :func:`_resized`
    makes first in some modes (premultiplied alpha, a palette's colours, grey of more
    than 8 bits as an array)."""
    stored = 1 if im.mode in ("1", "L", "P") else 2 if im.mode in _UINT16_MODES else 4
    as_is = im.mode in ("L", "RGB", "CMYK", "YCbCr", "RGBX") and "transparency" not in im.info
    return stored if as_is else stored + 6


def _resized(im: Image.Image, shape: tuple[int, int], box: tuple[float, ...]) -> np.ndarray:
    """The pixels of ``im`` (loaded) within ``box``, resized to ``shape`` by Lanczos (as
    the pipeline resizes) unless it is that size already: an array
    :func:`to_float_image` takes. Transparency becomes alpha first, a palette colours;
    16- and 32-bit grey is resized as float32 (:func:`_resize_array`)."""
    h, w = shape
    if im.size == (w, h):
        return _pixels_of(im)
    if im.mode in ("I", "F") or im.mode in _UINT16_MODES:
        return _resize_array(_pixels_of(im), shape)
    if "transparency" in im.info or im.mode == "PA":
        mode = "RGBA"
    elif im.mode == "1":
        mode = "L"
    else:
        mode = im.mode if im.mode in _RESIZABLE else "RGB"
    im = im if mode == im.mode else im.convert(mode)
    return _pixels_of(im.resize((w, h), Image.Resampling.LANCZOS, box=box, reducing_gap=_GAP))


def _resize_array(array: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """``(H, W[, C])`` pixels :func:`to_float_image` takes, resized to ``shape`` by
    Lanczos and converted :data:`_BAND` rows at a time (rows first, then columns):
    ``(h, w, 3) float32`` in [0, 1].

    Example:
        >>> _resize_array(np.full((40, 60), 65535, np.uint16), (4, 6))[0, 0]
        array([1., 1., 1.], dtype=float32)
    """
    h, w = shape
    rows = np.empty((3, array.shape[0], w), np.float32)
    for y in range(0, array.shape[0], _BAND):
        band = to_float_image(array[y:y + _BAND])
        for c in range(3):
            rows[c, y:y + len(band)] = _lanczos(band[:, :, c], (len(band), w))
    planes = [np.clip(_lanczos(rows[c], shape), 0.0, 1.0) for c in range(3)]
    return np.stack(planes, axis=2)


def _lanczos(plane: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """``(H, W) float32`` resized to ``shape`` by Pillow (Lanczos, reducing gap 3)."""
    h, w = shape
    image = Image.fromarray(np.ascontiguousarray(plane, np.float32), mode="F")
    return np.asarray(image.resize((w, h), Image.Resampling.LANCZOS, reducing_gap=_GAP))


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
    target = "RGBA" if transparent else "RGB"
    return np.asarray(im if mode == target else im.convert(target))  # no needless copy


def _read_png16_colour(path: Path, orientation: int, shape: tuple[int, int]
                       ) -> np.ndarray | None:
    """``(H, W, 3|4) uint16`` of a 16-bit colour PNG through OpenCV (:func:`read_png16`;
    at another stored ``shape``: ``(h, w, 3) float32``, :func:`_resize_array`),
    upright, or None without OpenCV."""
    array = read_png16(path)
    if array is None:
        return None
    if array.shape[:2] != shape:  # resized first (alpha composited), then reordered
        return apply_orientation(_resize_array(array, shape)[:, :, ::-1], int(orientation))
    order = [2, 1, 0, 3][: array.shape[2]]  # BGR(A) -> RGB(A)
    return apply_orientation(np.ascontiguousarray(array[:, :, order]), int(orientation))


def _read_tiff_with_tifffile(path: Path, working_size: int | None) -> np.ndarray:
    """Read the first page of a TIFF Pillow cannot decode (reduced for
    ``working_size``), applying its orientation."""
    array, orientation = read_tiff_page(path)
    if array.ndim == 3 and array.shape[2] > 4:
        raise InputError(f"TIFF has {array.shape[2]} channels; expected 1, 3 or 4")
    if array.dtype.kind in "iu" and array.dtype.itemsize > 2:
        raise InputError(f"TIFF samples of dtype {array.dtype} are not supported")
    if array.ndim == 3 and array.shape[2] == 1:
        array = array[:, :, 0]
    shape = decoded_shape(array.shape[:2], working_size)
    if shape != array.shape[:2]:
        array = _resize_array(array, shape)
    return apply_orientation(array, orientation)
