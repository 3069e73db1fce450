"""The LDI file format, ``photo3d.npz``: a zip of ``.npy`` arrays read without pickle.

:func:`save_npz` writes an :class:`~photo3d.structures.ldi.LDI` with its metadata,
:func:`load_npz` reads one back and checks it (sizes, links, labels) so a hostile
file gives an :class:`~photo3d.errors.InputError`, never a crash.
"""

from __future__ import annotations

import json
import zipfile
import zlib
from pathlib import Path

import numpy as np

from photo3d.camera import DepthMapping, Intrinsics
from photo3d.errors import InputError
from photo3d.files.atomic import open_write
from photo3d.io.bounded import loads_json
from photo3d.io.limits import check_available
from photo3d.io.npy import read_npy, read_npy_header
from photo3d.structures.ldi import LDI

FORMAT_VERSION = 3
"""Version 3 adds ``alpha`` (``(N,) float32``, the soft silhouettes' coverage,
:attr:`~photo3d.structures.ldi.LDI.alpha`; versions 1 and 2 are still read, with
alpha 1 everywhere). Version 2 stores ``links`` relative to the pixel (``links[i] -
i``, 0 = none): mostly the same few offsets, so deflate packs them 7 times smaller
and 3.5 times faster than absolute indices (version 1). A 3D photo without soft
silhouettes (every alpha 1) is saved as version 2, which photo3d before version 3
reads too."""


def save_npz(ldi: LDI, path: str | Path, *, meta: dict | None = None) -> None:
    """Save losslessly as a NumPy ``.npz`` (no pickle inside): format
    :data:`FORMAT_VERSION` with the soft silhouettes' ``alpha`` when the LDI has any
    (``ldi.soft``), else version 2 (what older photo3d reads).

    ``meta`` is any JSON-able dictionary stored beside the arrays.
    """
    header = {
        "format": "photo3d-ldi",
        "version": FORMAT_VERSION if ldi.soft else 2,
        "intrinsics": [ldi.intrinsics.fx, ldi.intrinsics.fy, ldi.intrinsics.cx,
                       ldi.intrinsics.cy, ldi.intrinsics.width, ldi.intrinsics.height],
        "mapping": [ldi.mapping.scale, ldi.mapping.offset, ldi.mapping.floor],
        "border": ldi.border,
        "meta": meta or {},
    }
    arrays = {
        "y": ldi.y, "x": ldi.x, "color": ldi.color, "disparity": ldi.disparity,
        "links": _relative_links(ldi.links), "label": ldi.label,
        **({"alpha": np.asarray(ldi.alpha, np.float32)} if ldi.soft else {}),
        "header": np.frombuffer(json.dumps(header).encode(), np.uint8),
    }
    # A regular .npz (np.load reads it) with fast deflate: np.savez_compressed's
    # default level is several times slower for a few percent smaller files. The
    # colours are stored: deflate shrinks float32 colours by only a quarter (18.7 to
    # 14 MB for a 1024 px photo) in half the time of the whole file.
    with (open_write(path) as file,
          zipfile.ZipFile(file, "w", zipfile.ZIP_DEFLATED, compresslevel=1) as zf):
        for name, array in arrays.items():
            zf.compression = zipfile.ZIP_STORED if name == "color" else zipfile.ZIP_DEFLATED
            with zf.open(f"{name}.npy", "w", force_zip64=True) as f:
                np.lib.format.write_array(f, np.ascontiguousarray(array), allow_pickle=False)


def load_npz(path: str | Path) -> tuple[LDI, dict]:
    """Inverse of :func:`save_npz`: returns ``(ldi, meta)``.

    Everything read is checked before use (the file may come from anywhere): a zip
    holding the six arrays (seven from version 3: ``alpha``, in [0, 1]) and the header,
    sizes within limits before allocating (the pixel count within :data:`MAX_LAYERS`
    of the image size, and what reading it needs, :data:`LOAD_BYTES` per pixel, within
    the available memory:
    :func:`photo3d.io.limits.check_available`), dtypes and shapes, link indices in
    range and symmetric, lattice positions inside the image plus border, finite and
    plausible intrinsics, finite positive depths.

    Raises:
        InputError: one line; the file is missing, not a photo3d file (any other zip,
            a text file, pickled data: nothing is unpickled), truncated, inconsistent,
            or larger than the available memory holds.

    Example:
        >>> import tempfile
        >>> path = Path(tempfile.mkdtemp()) / "notes.npz"
        >>> _ = path.write_text("not an LDI")
        >>> try:
        ...     load_npz(path)
        ... except InputError as err:
        ...     print(str(err).split(": ")[1])
        not a photo3d file (a photo3d.npz written by photo3d make)
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"3D photo file not found: {path}")
    if not zipfile.is_zipfile(path):
        raise InputError(f"cannot read 3D photo {path}: not a photo3d file "
                         "(a photo3d.npz written by photo3d make)")
    try:
        arrays, header = _read_arrays(path)
        ldi = _checked_ldi(arrays, header)
        meta = header.get("meta", {})
    except _READ_ERRORS as err:
        raise InputError(f"cannot read 3D photo {path}: {_reason(err)}") from None
    return ldi, meta if isinstance(meta, dict) else {}


_READ_ERRORS = (OSError, ValueError, KeyError, TypeError, EOFError, RuntimeError,
                NotImplementedError, OverflowError, zipfile.BadZipFile, zlib.error)
"""What reading a hostile zip raises besides InputError: damaged deflate data
(``zlib.error``), an unknown compression method (``NotImplementedError``), an
encrypted member (``RuntimeError``), a header number of hundreds of digits that
``float()`` refuses (``OverflowError``), ..."""
_ARRAYS = ("y", "x", "color", "disparity", "links", "label")
_COLUMNS = {"y": (), "x": (), "color": (3,), "disparity": (), "links": (4,), "label": (),
            "alpha": ()}
MAX_LAYERS = 16
"""Most LDI pixels a file may declare per position of the image plus its border:
``n <= MAX_LAYERS * (H + 2 * border) * (W + 2 * border)``. photo3d writes about two
(the image and the inpainted layers behind its depth edges), so 16 is generous; the
bound is checked on the declared ``.npy`` shapes before any data is decompressed."""
_HEADER_BYTES = 1 << 24  # the JSON header and its metadata
LOAD_BYTES = 400
"""Peak bytes per LDI pixel of :func:`load_npz`, rounded up: the arrays are 41 bytes a
pixel (45 with version 3's alpha), the link checks need the rest (peak resident memory
measured 295 bytes a pixel above the interpreter's on a 1.47M pixel LDI, version 2)."""


def _relative_links(links: np.ndarray) -> np.ndarray:
    """``links`` as offsets from their own pixel, 0 where there is no link (a pixel
    never links to itself).

    Example:
        >>> _relative_links(np.array([[-1, 1], [0, -1]], np.int32)).tolist()
        [[0, 1], [-1, 0]]
    """
    own = np.arange(len(links), dtype=links.dtype)[:, None]
    return np.where(links >= 0, links - own, 0).astype(np.int32)


def _absolute_links(relative: np.ndarray) -> np.ndarray:
    """Inverse of :func:`_relative_links`, in int64 (a hostile file's offsets may
    overflow int32; the caller checks the range).

    Example:
        >>> _absolute_links(np.array([[0, 1], [-1, 0]])).tolist()
        [[-1, 1], [0, -1]]
    """
    links = relative.astype(np.int64)
    absent = links == 0
    links += np.arange(len(links), dtype=np.int64)[:, None]  # in place: one int64 copy
    links[absent] = -1
    return links


def _reason(err: BaseException) -> str:
    if isinstance(err, InputError):
        return str(err)
    if isinstance(err, KeyError):
        return f"not a photo3d file (no {err.args[0]})"
    if isinstance(err, zipfile.BadZipFile | zlib.error | EOFError):
        return f"damaged or truncated file ({err})"
    return f"not a valid photo3d file ({type(err).__name__}: {err})"


def ldi_pixels(path: str | Path) -> int:
    """The number of LDI pixels a ``photo3d.npz`` declares, read from its header only
    (what the memory checks of ``export`` need before the file is loaded).

    Raises:
        InputError: not a readable photo3d file.

    Example:
        >>> import numpy as np, pathlib, tempfile
        >>> from photo3d.stages.ldi import from_image
        >>> ldi = from_image(np.zeros((4, 6, 3), np.float32), np.ones((4, 6), np.float32))
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "photo3d.npz"
        >>> save_npz(ldi, path)
        >>> ldi_pixels(path)
        24
    """
    try:
        with zipfile.ZipFile(path) as zf, zf.open("y.npy") as f:
            shape, _, _ = read_npy_header(f)
    except _READ_ERRORS as err:
        raise InputError(f"cannot read {path}: {_reason(err)}") from None
    if len(shape) != 1:
        raise InputError(f"{path}: y has shape {shape}, expected one dimension")
    return int(shape[0])


def _read_arrays(path: Path) -> tuple[dict[str, np.ndarray], dict]:
    """The six arrays and the header of a photo3d zip; the header and every declared
    shape are checked (the pixel count within :data:`MAX_LAYERS`) before the arrays'
    data is read."""
    with zipfile.ZipFile(path) as zf:
        header = loads_json(_read_member(zf, "header", _HEADER_BYTES).tobytes(),
                            what="its header")
        if not isinstance(header, dict) or header.get("format") != "photo3d-ldi":
            raise InputError("not a photo3d file (its header is not a photo3d LDI header)")
        version = header.get("version", 1)
        if not _is_int(version):
            raise InputError(f"format version {version!r} is not an integer")
        if version not in range(1, FORMAT_VERSION + 1):
            raise InputError(f"format version {version!r} is not one this photo3d reads "
                             f"(1 to {FORMAT_VERSION}); a newer photo3d wrote it")
        w, h, border = _checked_frame(header)
        limit = MAX_LAYERS * (h + 2 * border) * (w + 2 * border)
        declared = {}
        names = _ARRAYS + (("alpha",) if version >= 3 else ())
        for name in names:
            with zf.open(f"{name}.npy") as f:
                try:
                    shape, _, dtype = read_npy_header(f)
                except InputError as err:
                    raise InputError(f"{name}: {err}") from None
            declared[name] = shape, dtype
        n = declared["y"][0][0] if len(declared["y"][0]) == 1 else -1
        for name, (shape, dtype) in declared.items():
            expected = (n, *_COLUMNS[name])
            kind = "f" if name in ("color", "disparity", "alpha") else "iu"
            if shape != expected or dtype.kind not in kind:
                raise InputError(f"{name} has shape {shape} and dtype {dtype}; expected "
                                 f"{expected} {'float' if kind == 'f' else 'integer'}")
            if name == "y" and not w * h <= n <= limit:  # y comes first
                raise InputError(f"{n} pixels declared for a {w}x{h} image with a {border} "
                                 f"px border; expected {w * h} to {limit:,} "
                                 f"({MAX_LAYERS} layers)")
        check_available(LOAD_BYTES * n, f"its {n:,} LDI pixels")
        arrays = {name: _read_member(zf, name, int(np.prod(shape)))
                  for name, (shape, _) in declared.items()}
    return arrays, header


def _read_member(zf: zipfile.ZipFile, name: str, max_items: int) -> np.ndarray:
    info = zf.getinfo(f"{name}.npy")
    with zf.open(info) as f:
        try:
            return read_npy(f, max_items=max_items, size=info.file_size)
        except InputError as err:
            raise InputError(f"{name}: {err}") from None


def _checked_frame(header: dict) -> tuple[int, int, int]:
    """``(width, height, border)`` of an untrusted header, after checking its
    intrinsics, depth mapping and border."""
    for name in ("intrinsics", "mapping"):  # float() would take true, "2" and ["2"]
        if not (isinstance(header[name], list) and all(
                isinstance(v, int | float) and not isinstance(v, bool) for v in header[name])):
            raise InputError(f"{name} is not a list of numbers")
    values = [float(v) for v in header["intrinsics"]]
    mapping = [float(v) for v in header["mapping"]]
    if len(values) != 6 or len(mapping) != 3 or not np.all(np.isfinite(values + mapping)):
        raise InputError("intrinsics or depth mapping are not finite numbers")
    fx, fy, cx, cy, w, h = values
    border = header["border"]
    if not (w == int(w) and h == int(h) and 1 <= w <= 65536 and 1 <= h <= 65536):
        raise InputError(f"image size {w}x{h} is not between 1 and 65536 pixels")
    w, h = int(w), int(h)
    if not (0 < fx < 1e6 * max(w, h) and 0 < fy < 1e6 * max(w, h)):
        raise InputError(f"focal lengths fx={fx:g}, fy={fy:g} are not plausible")
    if not (abs(cx) < 100 * w and abs(cy) < 100 * h):
        raise InputError(f"principal point ({cx:g}, {cy:g}) lies far outside the image")
    if not (_is_int(border) and 0 <= border <= max(w, h)):
        raise InputError(f"border {border!r} is not an integer between 0 and the image size")
    return w, h, border


def _is_int(value: object) -> bool:
    """True for a JSON integer; False for anything else, ``true`` and ``false`` too
    (Python's bool is an int).

    Example:
        >>> _is_int(2), _is_int(True), _is_int(2.0)
        (True, False, False)
    """
    return isinstance(value, int) and not isinstance(value, bool)


def _checked_ldi(arrays: dict[str, np.ndarray], header: dict) -> LDI:
    """An LDI from untrusted arrays and header (both checked by :func:`_read_arrays`:
    header values, shapes, dtypes, pixel count), or InputError naming what is wrong."""
    fx, fy, cx, cy, w, h = [float(v) for v in header["intrinsics"]]
    w, h, border = int(w), int(h), header["border"]
    mapping = [float(v) for v in header["mapping"]]
    n = len(arrays["y"])
    y, x, links = arrays["y"], arrays["x"], arrays["links"]
    version = header.get("version", 1)  # checked by _read_arrays
    if version >= 2:
        links = _absolute_links(links)
    if n and (y.min() < -border or y.max() >= h + border or x.min() < -border
              or x.max() >= w + border):
        raise InputError("pixel positions lie outside the image and its border")
    if n and (links.min() < -1 or links.max() >= n):
        raise InputError(f"links point outside the {n} pixels")
    if not (np.isfinite(arrays["color"]).all() and np.isfinite(arrays["disparity"]).all()):
        raise InputError("colours or disparities are not finite")
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        z = DepthMapping(*mapping).depth(arrays["disparity"])
    if n and not (np.isfinite(z).all() and z.min() > 0):  # every mesh and view divides by z
        raise InputError(f"disparities and depth mapping {mapping} do not give finite "
                         "positive depths")
    alpha = arrays.get("alpha")
    if alpha is not None:
        alpha = alpha.astype(np.float32, copy=False)
        if n and not (alpha.min() >= 0.0 and alpha.max() <= 1.0):  # NaN fails too
            raise InputError("alpha is not in [0, 1]")
    ldi = LDI(y=y.astype(np.int32, copy=False), x=x.astype(np.int32, copy=False),
              color=arrays["color"].astype(np.float32, copy=False),
              disparity=arrays["disparity"].astype(np.float32, copy=False),
              links=links.astype(np.int32, copy=False),
              label=arrays["label"].astype(np.uint8, copy=False),
              intrinsics=Intrinsics(fx, fy, cx, cy, w, h), mapping=DepthMapping(*mapping),
              border=border, alpha=alpha)
    try:
        ldi.check()
    except ValueError as err:
        raise InputError(f"inconsistent links ({err})") from None
    return ldi
