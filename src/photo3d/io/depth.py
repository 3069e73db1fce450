"""Read and write depth (or disparity) maps: PNG, NPY, PFM and float TIFF.

:func:`read_depth` returns the values exactly as stored: no normalisation, no unit
conversion, no guess whether the file holds depth or disparity (that is decided by
the caller, see :mod:`photo3d.camera`). Non-finite values stay as they are (PFM and
float files often mark unknown pixels with ``inf``).

Example:
    >>> import pathlib, tempfile
    >>> import numpy as np
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "depth.pfm"
    >>> write_pfm(path, np.array([[1.0, 2.0], [3.0, np.inf]]))
    >>> read_depth(path)
    array([[ 1.,  2.],
           [ 3., inf]], dtype=float32)
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
from PIL import Image, UnidentifiedImageError

from photo3d.errors import InputError, OutputError
from photo3d.files.atomic import open_write, writing
from photo3d.io.decoding import load_pixels, open_image, read_tiff_page
from photo3d.io.images import decoded_shape
from photo3d.io.limits import check_available
from photo3d.io.npy import read_npy

PathLike = str | os.PathLike[str]

SUPPORTED = ".png (8/16-bit grey), .npy, .pfm, .tif/.tiff (float or 16-bit grey)"
"""Human-readable list of the depth formats :func:`read_depth` reads."""

_PFM_HEADER = re.compile(rb"\s*(P[Ff])\s+(\d+)\s+(\d+)\s+(\S+)\s")


def read_depth(path: PathLike, *, working_size: int | None = None) -> np.ndarray:
    """Read a depth or disparity map with its raw stored values.

    The format follows the extension:

    * ``.png``: 8- or 16-bit grey, values 0..255 or 0..65535. An RGB(A) PNG is
      accepted only if its three colour channels are equal (the first is used).
    * ``.npy``: a numeric ``(H, W)``, ``(1, H, W)`` or ``(H, W, 1)`` array, loaded
      with ``allow_pickle=False``.
    * ``.pfm``: ``Pf`` (grey) or ``PF`` (colour, first channel used), either byte
      order; rows are stored bottom-to-top in the file and returned top-to-bottom.
    * ``.tif``/``.tiff``: 32-bit float or 8/16-bit grey through Pillow, anything
      else (float64, several channels) through ``tifffile`` (extra ``photo3d[tiff]``).

    What decoding needs is estimated from the header and checked against the
    available memory first (:func:`photo3d.io.limits.check_available`). Given
    ``working_size``, a map of a photo's size comes back at the size
    :func:`~photo3d.io.images.read_image` decodes that photo to
    (:func:`~photo3d.io.images.decoded_shape`), resampled by nearest neighbour at
    pixel centres (as :func:`photo3d.depth.normalize.match_shape` does) before the
    float conversion; maps at most ``KEEP * working_size`` on the longer side are
    returned whole.

    Args:
        path: the depth file.
        working_size: the longer side the caller resizes the map to (None: whole).

    Returns:
        ``(H, W) float32``, row 0 at the top of the picture, values as stored.

    Raises:
        InputError: the file is missing, has an unsupported extension, cannot be
            decoded, does not hold a single-channel 2-D map, or needs more memory to
            decode than is available. The message names the path and the supported
            formats.

    Example:
        >>> import pathlib, tempfile
        >>> import numpy as np
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "depth.npy"
        >>> np.save(path, np.arange(6, dtype=np.uint16).reshape(1, 2, 3))
        >>> read_depth(path)
        array([[0., 1., 2.],
               [3., 4., 5.]], dtype=float32)
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"depth file not found: {path}; photo3d reads {SUPPORTED}")
    reader = _READERS.get(path.suffix.lower())
    if reader is None:
        raise InputError(
            f"cannot read depth {path}: unsupported extension {path.suffix!r}; "
            f"photo3d reads {SUPPORTED}"
        )
    try:
        values = _checked_map(reader(path, working_size))
        values = _nearest(values, decoded_shape(values.shape, working_size))
        with np.errstate(over="ignore"):  # beyond float32: inf, an unknown value
            depth = np.array(values, dtype=np.float32, order="C")  # always a fresh copy
    except InputError as err:
        raise InputError(f"cannot read depth {path}: {err}; photo3d reads {SUPPORTED}") from err
    return depth


def write_pfm(path: PathLike, depth: np.ndarray) -> None:
    """Write a grey little-endian PFM (``Pf``, scale ``-1.0``, rows bottom-to-top).

    Args:
        path: the file to write (overwritten if it exists; its folder must exist).
        depth: ``(H, W)`` real array; stored as float32, ``inf``/``NaN`` kept.

    Raises:
        InputError: ``depth`` is not a 2-D real array.
        OutputError: the file cannot be written.

    Example:
        >>> import pathlib, tempfile
        >>> import numpy as np
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "d.pfm"
        >>> write_pfm(path, np.zeros((2, 3)))
        >>> path.read_bytes()[:11]
        b'Pf\\n3 2\\n-1.0'
    """
    depth = _as_depth_map(np.asarray(depth))
    height, width = depth.shape
    header = f"Pf\n{width} {height}\n-1.0\n".encode("ascii")
    body = np.ascontiguousarray(depth[::-1], dtype="<f4").tobytes()
    _write_bytes(Path(path), header + body, "depth")


def write_depth_png16(
    path: PathLike,
    depth: np.ndarray,
    *,
    vmin: float | None = None,
    vmax: float | None = None,
) -> tuple[float, float]:
    """Save a depth map as a 16-bit grey PNG for looking at, mapped linearly.

    ``vmin`` becomes 0 and ``vmax`` becomes 65535; values outside are clipped and
    non-finite values (``inf``, ``NaN``) become 0. The mapping is lossy: use
    :func:`write_pfm` to keep the values.

    Args:
        path: a ``.png`` file (overwritten if it exists; its folder must exist).
        depth: ``(H, W)`` real array, any units.
        vmin: value mapped to 0; default the smallest finite value.
        vmax: value mapped to 65535; default the largest finite value.

    Returns:
        ``(vmin, vmax)`` actually used, so that ``value = vmin + png / 65535 *
        (vmax - vmin)`` inverts the mapping. If ``vmax == vmin`` every finite pixel
        is written as 0.

    Raises:
        InputError: ``depth`` is not 2-D and real, or ``vmax < vmin``.
        OutputError: ``path`` is not a ``.png`` or cannot be written.

    Example:
        >>> import pathlib, tempfile
        >>> import numpy as np
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "d.png"
        >>> write_depth_png16(path, np.array([[1.0, 2.0], [3.0, 5.0]]))
        (1.0, 5.0)
        >>> read_depth(path)
        array([[    0., 16384.],
               [32768., 65535.]], dtype=float32)
    """
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise OutputError(f"cannot write depth {path}: write_depth_png16 writes .png files")
    depth = _as_depth_map(np.asarray(depth)).astype(np.float64)
    finite = np.isfinite(depth)
    if vmin is None:
        vmin = float(depth[finite].min()) if finite.any() else 0.0
    if vmax is None:
        vmax = float(depth[finite].max()) if finite.any() else float(vmin)
    vmin, vmax = float(vmin), float(vmax)
    if not vmax >= vmin:
        raise InputError(f"vmax={vmax:g} is smaller than vmin={vmin:g}")
    scale = 65535.0 / (vmax - vmin) if vmax > vmin else 0.0
    mapped = np.clip((np.where(finite, depth, vmin) - vmin) * scale, 0.0, 65535.0)
    try:
        with writing(path) as target:
            Image.fromarray(np.round(mapped).astype(np.uint16)).save(target, format="PNG")
    except OSError as err:
        raise OutputError(f"cannot write depth {path}: {err.strerror or err}") from err
    return vmin, vmax


def _as_depth_map(array: np.ndarray) -> np.ndarray:
    """Check a real ``(H, W)`` (or singleton-3-D) array and return it as float32."""
    return np.array(_checked_map(array), dtype=np.float32, order="C")  # a fresh copy


def _checked_map(array: np.ndarray) -> np.ndarray:
    """Check a real ``(H, W)`` (or singleton-3-D) array; ``(H, W)`` in its own dtype."""
    if array.ndim == 3 and 1 in array.shape:
        array = np.squeeze(array, axis=array.shape.index(1))
    if array.ndim != 2:
        raise InputError(f"depth has shape {array.shape}; expected (H, W)")
    if array.dtype.kind not in "biuf":
        raise InputError(f"depth has dtype {array.dtype}; expected a real number type")
    if array.size == 0:
        raise InputError(f"depth has shape {array.shape}; it holds no pixels")
    return array


def _nearest(array: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """``array`` at ``shape`` by nearest neighbour at pixel centres, in its own dtype
    (the rule of :func:`photo3d.depth.normalize.match_shape`).

    Example:
        >>> _nearest(np.arange(16).reshape(4, 4), (2, 2)).tolist()
        [[5, 7], [13, 15]]
    """
    if array.shape == tuple(shape):
        return array
    (h, w), (big_h, big_w) = shape, array.shape
    ys = np.minimum(((np.arange(h) + 0.5) * big_h / h).astype(int), big_h - 1)
    xs = np.minimum(((np.arange(w) + 0.5) * big_w / w).astype(int), big_w - 1)
    return array[np.ix_(ys, xs)]


def _check_memory(width: int, height: int, per_pixel: int, working_size: int | None) -> None:
    """Refuse a map whose decoding needs ``per_pixel`` bytes per declared pixel, and its
    float32 result (at :func:`~photo3d.io.images.decoded_shape`), beyond the available
    memory."""
    out_h, out_w = decoded_shape((height, width), working_size)
    check_available(per_pixel * width * height + 4 * out_h * out_w,
                    f"its {width}x{height} pixels")


def _first_of_equal_channels(array: np.ndarray) -> np.ndarray:
    """``(H, W)`` from ``(H, W)`` or ``(H, W, C)`` whose colour channels are equal."""
    if array.ndim != 3:
        return array
    colour = array[:, :, :3] if array.shape[2] >= 3 else array[:, :, :1]  # drop alpha
    if not (colour == colour[:, :, :1]).all():
        raise InputError("a depth image must be grey, but its colour channels differ")
    return colour[:, :, 0]


def _read_png(path: Path, working_size: int | None) -> np.ndarray:
    """Raw values of a grey (or grey-looking RGB) PNG, 8 or 16 bit."""
    with path.open("rb") as file:
        head = file.read(26)
    if len(head) < 26:
        raise InputError(f"only {len(head)} bytes: not a complete PNG")
    if head[:8] == b"\x89PNG\r\n\x1a\n" and head[24] == 16 and head[25] != 0:
        raise InputError("16-bit PNGs with colour or alpha are not supported; save 16-bit grey")
    try:
        with open_image(path) as im:
            grey = im.mode in ("1", "L", "I", "I;16", "I;16B", "I;16L", "I;16N")
            stored = 1 if im.mode in ("1", "L") else 2 if im.mode.startswith("I;16") else 4
            # decoded and copied; colour: also converted and its channels compared
            _check_memory(*im.size, 2 * stored if grey else 16, working_size)
            im.load()
            if im.mode in ("1", "LA", "La"):
                im = im.convert("L")  # drops alpha; "1" becomes 0 / 255
            elif im.mode in ("P", "PA"):
                im = im.convert("RGBA")
            return _first_of_equal_channels(np.asarray(im))
    except UnidentifiedImageError as err:
        raise InputError("not a recognised image format") from err
    except (OSError, SyntaxError, ValueError, Image.DecompressionBombError) as err:
        raise InputError(str(err)) from err


def _read_npy(path: Path, working_size: int | None) -> np.ndarray:
    """Array of a ``.npy`` file; pickled (object) arrays, huge shapes and shapes the
    memory cannot hold are refused."""
    try:
        with path.open("rb") as file:
            return read_npy(file, size=path.stat().st_size)
    except OSError as err:
        raise InputError(err.strerror or str(err)) from err


def _read_pfm(path: Path, working_size: int | None) -> np.ndarray:
    """First channel of a PFM file, rows flipped to top-to-bottom."""
    size = path.stat().st_size
    with path.open("rb") as file:
        head = _PFM_HEADER.match(file.read(256))
    out = decoded_shape((int(head.group(3)), int(head.group(2))), working_size) if head else (
        size // 4, 1)
    check_available(size + 4 * out[0] * out[1], f"its {size:,} bytes")  # read, converted
    raw = path.read_bytes()
    match = _PFM_HEADER.match(raw)
    if match is None:
        raise InputError("not a PFM file (expected a 'Pf' or 'PF' header)")
    channels = 3 if match.group(1) == b"PF" else 1
    width, height = int(match.group(2)), int(match.group(3))
    try:
        scale = float(match.group(4))
    except ValueError as err:
        raise InputError(f"PFM scale {match.group(4)!r} is not a number") from err
    if scale == 0.0 or not np.isfinite(scale):
        raise InputError(f"PFM scale is {scale}; expected a non-zero number")
    start = match.end()
    if raw[start - 1 : start + 1] == b"\r\n":
        start += 1
    count = width * height * channels
    if len(raw) - start < 4 * count:
        raise InputError(f"PFM data is truncated: {width}x{height}x{channels} floats expected")
    dtype = "<f4" if scale < 0 else ">f4"
    data = np.frombuffer(raw, dtype=dtype, count=count, offset=start)
    return data.reshape(height, width, channels)[::-1, :, 0]


def _read_tiff(path: Path, working_size: int | None) -> np.ndarray:
    """Float or grey TIFF through Pillow, else through tifffile."""
    pixels = _read_tiff_with_pillow(path, working_size)
    return pixels if pixels is not None else _first_of_equal_channels(read_tiff_page(path)[0])


def _read_tiff_with_pillow(path: Path, working_size: int | None) -> np.ndarray | None:
    """Single-channel TIFF pixels, or None if Pillow cannot decode them exactly."""
    try:
        with open_image(path) as im:
            if im.mode not in ("F", "I", "L", "I;16", "I;16L", "I;16B", "I;16N"):
                return None
            stored = 1 if im.mode == "L" else 2 if im.mode.startswith("I;16") else 4
            _check_memory(*im.size, 2 * stored, working_size)  # decoded and copied
            load_pixels(im)
            return np.asarray(im)
    except UnidentifiedImageError:
        return None  # e.g. float64 or multi-channel float: tifffile reads those
    except (OSError, SyntaxError, ValueError, Image.DecompressionBombError) as err:
        raise InputError(str(err)) from err


_READERS = {
    ".png": _read_png,
    ".npy": _read_npy,
    ".pfm": _read_pfm,
    ".tif": _read_tiff,
    ".tiff": _read_tiff,
}


def _write_bytes(path: Path, data: bytes, what: str) -> None:
    """Write ``data`` to ``path``, turning OS failures into :class:`OutputError`."""
    try:
        with open_write(path) as file:
            file.write(data)
    except OSError as err:
        raise OutputError(f"cannot write {what} {path}: {err.strerror or err}") from err
