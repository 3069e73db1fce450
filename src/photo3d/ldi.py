"""The layered depth image: flat arrays with explicit 4-neighbour links.

An LDI holds any number of pixels per lattice position. Pixel ``i`` has a lattice
position ``(y[i], x[i])`` (it may lie outside the input image in the extrapolated
border), a colour, a normalised disparity, a label, and at most one neighbour per
direction in ``links[i]`` (order left, right, up, down; -1 = none). Links are always
symmetric: ``links[i, d] == j`` iff ``links[j, d ^ 1] == i``. The first ``H * W``
pixels are the input image in raster order.
"""

from __future__ import annotations

import json
import zipfile
import zlib
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from photo3d.camera import DepthMapping, Intrinsics
from photo3d.errors import InputError

LABEL_ORIGINAL = 1
LABEL_BORDER = 5
FORMAT_VERSION = 2
"""Version 2 stores ``links`` relative to the pixel (``links[i] - i``, 0 = none):
mostly the same few offsets, so deflate packs them 7 times smaller and 3.5 times
faster than absolute indices (version 1, still read)."""


@dataclass(frozen=True)
class LDI:
    """Layered depth image (structure of arrays).

    Attributes:
        y, x: ``(N,) int32`` lattice row / column (border pixels lie outside
            ``[0, H) x [0, W)`` by at most ``border``).
        color: ``(N, 3) float32`` sRGB in [0, 1].
        disparity: ``(N,) float32`` normalised disparity (larger = nearer).
        links: ``(N, 4) int32`` neighbour index per direction L, R, U, D; -1 = none.
        label: ``(N,) uint8`` 1 original, 2-3 inpainted (pass 1, later passes),
            5 extrapolated border.
        intrinsics: camera of the input view (image size ``W x H``).
        mapping: normalised disparity -> depth z.
        border: width of the extrapolated frame in pixels.
    """

    y: np.ndarray
    x: np.ndarray
    color: np.ndarray
    disparity: np.ndarray
    links: np.ndarray
    label: np.ndarray
    intrinsics: Intrinsics
    mapping: DepthMapping
    border: int = 0

    @property
    def size(self) -> int:
        """Number of LDI pixels."""
        return int(self.y.shape[0])

    @property
    def height(self) -> int:
        return self.intrinsics.height

    @property
    def width(self) -> int:
        return self.intrinsics.width

    @property
    def lattice_shape(self) -> tuple[int, int]:
        """``(rows, cols)`` of the lattice including the border."""
        return self.height + 2 * self.border, self.width + 2 * self.border

    def positions(self) -> np.ndarray:
        """``(N,) int64`` flat lattice index ``(y + b) * cols + (x + b)``."""
        cols = self.width + 2 * self.border
        return (self.y.astype(np.int64) + self.border) * cols + (self.x + self.border)

    def position_index(self) -> tuple[np.ndarray, np.ndarray]:
        """CSR lookup of the pixels at each lattice position.

        Returns:
            ``starts (P + 1,) int64`` and ``order (N,) int64``: the pixels at flat
            position ``p`` are ``order[starts[p]:starts[p + 1]]``.
        """
        pos = self.positions()
        rows, cols = self.lattice_shape
        order = np.argsort(pos, kind="stable")
        starts = np.zeros(rows * cols + 1, np.int64)
        np.cumsum(np.bincount(pos, minlength=rows * cols), out=starts[1:])
        return starts, order

    def layers(self) -> np.ndarray:
        """``(rows, cols) int32`` number of pixels at each lattice position."""
        rows, cols = self.lattice_shape
        return np.bincount(self.positions(), minlength=rows * cols).reshape(rows, cols)

    def depth(self) -> np.ndarray:
        """``(N,) float32`` camera z of every pixel."""
        return self.mapping.depth(self.disparity)

    def check(self) -> None:
        """Raise ``AssertionError`` if links are not symmetric 4-neighbour links."""
        src, d = np.nonzero(self.links >= 0)
        dst = self.links[src, d]
        assert np.all(self.links[dst, d ^ 1] == src), "links are not symmetric"
        dy = np.array([0, 0, -1, 1])[d]
        dx = np.array([-1, 1, 0, 0])[d]
        assert np.all(self.y[dst] == self.y[src] + dy), "link joins wrong rows"
        assert np.all(self.x[dst] == self.x[src] + dx), "link joins wrong columns"


def from_image(
    image: np.ndarray,
    disparity: np.ndarray,
    *,
    intrinsics: Intrinsics | None = None,
    mapping: DepthMapping | None = None,
) -> LDI:
    """The trivial LDI: one fully 4-connected layer.

    Args:
        image: ``(H, W, 3) float32`` in [0, 1].
        disparity: ``(H, W) float32`` normalised disparity.
        intrinsics: defaults to :meth:`Intrinsics.default`.
        mapping: defaults to the authors' mapping (:class:`DepthMapping`).

    Example:
        >>> ldi = from_image(np.zeros((2, 3, 3), np.float32), np.zeros((2, 3), np.float32))
        >>> ldi.size, ldi.links[0].tolist()
        (6, [-1, 1, -1, 3])
    """
    h, w = disparity.shape
    idx = np.arange(h * w, dtype=np.int32).reshape(h, w)
    links = np.full((h, w, 4), -1, np.int32)
    links[:, 1:, 0] = idx[:, :-1]
    links[:, :-1, 1] = idx[:, 1:]
    links[1:, :, 2] = idx[:-1, :]
    links[:-1, :, 3] = idx[1:, :]
    yy, xx = np.divmod(np.arange(h * w, dtype=np.int32), np.int32(w))
    return LDI(
        y=yy.astype(np.int32),
        x=xx.astype(np.int32),
        color=np.ascontiguousarray(image.reshape(-1, 3), np.float32),
        disparity=np.ascontiguousarray(disparity.reshape(-1), np.float32),
        links=links.reshape(-1, 4),
        label=np.full(h * w, LABEL_ORIGINAL, np.uint8),
        intrinsics=intrinsics or Intrinsics.default(w, h),
        mapping=mapping or DepthMapping(),
    )


def cut(ldi: LDI, cuts: np.ndarray) -> LDI:
    """Remove the links marked in a cut mask (both directions).

    Args:
        ldi: an LDI whose first ``H * W`` pixels are the input image.
        cuts: ``(H, W) uint8`` direction bit set per input pixel.

    Example:
        >>> ldi = from_image(np.zeros((1, 2, 3), np.float32), np.zeros((1, 2), np.float32))
        >>> cut(ldi, np.array([[2, 0]], np.uint8)).links.tolist()
        [[-1, -1, -1, -1], [-1, -1, -1, -1]]
    """
    links = ldi.links.copy()
    flat = cuts.reshape(-1)
    for d in range(4):
        src = np.nonzero(flat & (1 << d))[0]
        dst = links[src, d]
        ok = dst >= 0
        links[dst[ok], d ^ 1] = -1
        links[src, d] = -1
    return replace(ldi, links=links)


def save_npz(ldi: LDI, path: str | Path, *, meta: dict | None = None) -> None:
    """Save losslessly as a NumPy ``.npz`` (no pickle inside).

    ``meta`` is any JSON-able dictionary stored beside the arrays.
    """
    header = {
        "format": "photo3d-ldi",
        "version": FORMAT_VERSION,
        "intrinsics": [ldi.intrinsics.fx, ldi.intrinsics.fy, ldi.intrinsics.cx,
                       ldi.intrinsics.cy, ldi.intrinsics.width, ldi.intrinsics.height],
        "mapping": [ldi.mapping.scale, ldi.mapping.offset, ldi.mapping.floor],
        "border": ldi.border,
        "meta": meta or {},
    }
    arrays = {
        "y": ldi.y, "x": ldi.x, "color": ldi.color, "disparity": ldi.disparity,
        "links": _relative_links(ldi.links), "label": ldi.label,
        "header": np.frombuffer(json.dumps(header).encode(), np.uint8),
    }
    # A regular .npz (np.load reads it) with fast deflate: np.savez_compressed's
    # default level is several times slower for a few percent smaller files. The
    # colours are stored: deflate shrinks float32 colours by only a quarter (18.7 to
    # 14 MB for a 1024 px photo) in half the time of the whole file.
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED, compresslevel=1) as zf:
        for name, array in arrays.items():
            zf.compression = zipfile.ZIP_STORED if name == "color" else zipfile.ZIP_DEFLATED
            with zf.open(f"{name}.npy", "w", force_zip64=True) as f:
                np.lib.format.write_array(f, np.ascontiguousarray(array), allow_pickle=False)


def load_npz(path: str | Path) -> tuple[LDI, dict]:
    """Inverse of :func:`save_npz`: returns ``(ldi, meta)``.

    Everything read is checked before use (the file may come from anywhere): a zip
    holding the six arrays and the header, sizes within limits before allocating,
    dtypes and shapes, link indices in range and symmetric, lattice positions inside
    the image plus border, finite and plausible intrinsics.

    Raises:
        InputError: one line; the file is missing, not a photo3d file (any other zip,
            a text file, pickled data: nothing is unpickled), truncated or inconsistent.

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
        arrays = _read_arrays(path)
        header = json.loads(arrays.pop("header").tobytes().decode())
        if not isinstance(header, dict) or header.get("format") != "photo3d-ldi":
            raise InputError("not a photo3d file (its header is not a photo3d LDI header)")
        ldi = _checked_ldi(arrays, header)
        meta = header.get("meta", {})
    except (OSError, ValueError, KeyError, TypeError, EOFError, RuntimeError,
            NotImplementedError, zipfile.BadZipFile, zlib.error) as err:
        raise InputError(f"cannot read 3D photo {path}: {_reason(err)}") from None
    return ldi, meta if isinstance(meta, dict) else {}


_ARRAYS = ("y", "x", "color", "disparity", "links", "label")
_LIMIT = 1 << 26  # LDI pixels (a 1024 px photo has ~1.5M)


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
    rel = relative.astype(np.int64)
    return np.where(rel != 0, rel + np.arange(len(rel), dtype=np.int64)[:, None], -1)


def _reason(err: BaseException) -> str:
    if isinstance(err, InputError):
        return str(err)
    if isinstance(err, KeyError):
        return f"not a photo3d file (no {err.args[0]})"
    if isinstance(err, zipfile.BadZipFile | zlib.error | EOFError):
        return f"damaged or truncated file ({err})"
    return f"not a valid photo3d file ({type(err).__name__}: {err})"


def _read_arrays(path: Path) -> dict[str, np.ndarray]:
    from photo3d.io.npy import read_npy

    arrays = {}
    with zipfile.ZipFile(path) as zf:
        for name in (*_ARRAYS, "header"):
            info = zf.getinfo(f"{name}.npy")
            with zf.open(info) as f:
                try:
                    arrays[name] = read_npy(f, max_items=4 * _LIMIT, size=info.file_size)
                except InputError as err:
                    raise InputError(f"{name}: {err}") from None
    return arrays


def _checked_ldi(arrays: dict[str, np.ndarray], header: dict) -> LDI:
    """An LDI from untrusted arrays and header, or InputError naming what is wrong."""
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
    if not (isinstance(border, int) and 0 <= border <= max(w, h)):
        raise InputError(f"border {border!r} is not between 0 and the image size")
    n = arrays["y"].shape[0] if arrays["y"].ndim == 1 else -1
    shapes = {"y": (n,), "x": (n,), "color": (n, 3), "disparity": (n,), "links": (n, 4),
              "label": (n,)}
    for name, shape in shapes.items():
        a = arrays[name]
        kind = "f" if name in ("color", "disparity") else "iu"
        if a.shape != shape or a.dtype.kind not in kind:
            raise InputError(f"{name} has shape {a.shape} and dtype {a.dtype}; expected "
                             f"{shape} {'float' if kind == 'f' else 'integer'}")
    if n < w * h:
        raise InputError(f"{n} pixels for a {w}x{h} image (the first H * W are the image)")
    y, x, links = arrays["y"], arrays["x"], arrays["links"]
    version = header.get("version", 1)
    if version not in (1, FORMAT_VERSION):
        raise InputError(f"format version {version!r} is not one this photo3d reads "
                         f"(1 to {FORMAT_VERSION}); a newer photo3d wrote it")
    if version >= 2:
        links = _absolute_links(links)
    if n and (y.min() < -border or y.max() >= h + border or x.min() < -border
              or x.max() >= w + border):
        raise InputError("pixel positions lie outside the image and its border")
    if n and (links.min() < -1 or links.max() >= n):
        raise InputError(f"links point outside the {n} pixels")
    if not (np.isfinite(arrays["color"]).all() and np.isfinite(arrays["disparity"]).all()):
        raise InputError("colours or disparities are not finite")
    ldi = LDI(y=y.astype(np.int32), x=x.astype(np.int32),
              color=arrays["color"].astype(np.float32),
              disparity=arrays["disparity"].astype(np.float32),
              links=links.astype(np.int32), label=arrays["label"].astype(np.uint8),
              intrinsics=Intrinsics(fx, fy, cx, cy, w, h), mapping=DepthMapping(*mapping),
              border=border)
    try:
        ldi.check()
    except AssertionError as err:
        raise InputError(f"inconsistent links ({err})") from None
    return ldi
