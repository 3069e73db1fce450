"""Read and write Niantic's SPZ Gaussian splat files (``.spz``), versions 2, 3 and 4.

The layout follows Niantic's published format (github.com/nianticlabs/spz, README).
Versions 2 and 3 are one gzip stream (zlib) holding a 16-byte header and then the
attributes, each for all splats in turn. Version 4 is a 32-byte plain header, a
table of contents and one zstd stream per attribute:

=========  ===========================================================================
bytes      version 4
=========  ===========================================================================
0-15       ``magic``, ``version`` 4, ``numPoints`` (uint32 each), ``shDegree``,
           ``fractionalBits``, ``flags`` (uint8 each) and ``numStreams`` (uint8: 5
           here, the five attributes below; a sixth holds the SH of degree > 0)
16-19      ``tocByteOffset`` (uint32): 32 without extensions (``flags & 2``)
20-31      zero
32-        the table: per stream its compressed and uncompressed byte counts
           (uint64 each), then the streams, one zstd frame each, in this order;
           a stream that would be empty is left out
=========  ===========================================================================

zstd comes from the standard library's ``compression.zstd`` (Python 3.14) or its
backport ``backports.zstd`` (``pip install 'photo3d[spz4]'``), needed for version 4
only.

Versions 2 and 3 start with the header (little endian): ``magic 0x5053474e``
(uint32), ``version`` (uint32), ``numPoints`` (uint32), ``shDegree`` (uint8, 0
here), ``fractionalBits`` (uint8), ``flags`` (uint8, 0), reserved (uint8, 0).
Then, per splat, in every version:

============  =====================================================================
positions     3 x 24-bit signed fixed point, ``round(v * 2**fractionalBits)``
alphas        uint8 ``round(opacity * 255)``
colors        3 x uint8 ``round(f_dc * 0.15 * 255 + 127.5)`` (``f_dc`` the SH DC term)
scales        3 x uint8 ``round((log(scale) + 10) * 16)``
rotations     version 2: 3 x uint8 ``round(q * 127.5 + 127.5)`` of x, y, z with
              ``w >= 0``; versions 3, 4: the smallest three components, 10 bits each
              (9 bits of magnitude over ``1 / sqrt(2)`` and a sign) below the index
              of the largest in the top 2 bits of a uint32
============  =====================================================================

SPZ stores right-up-back axes (OpenGL, three.js): the OpenCV camera coordinates of
:class:`~photo3d.structures.splats.Splats` are turned 180 degrees about x on writing
(``(x, -y, -z)``, quaternion ``(w, x, -y, -z)``) and back on reading, as the
reference library does when told the source is RDF.

``fractionalBits`` is chosen per file: the finest step with which the largest
coordinate still fits in 24 bits, but no finer than the smallest splat's standard
deviation (finer steps only cost size: a centre is off by at most half of it; the
reference writer always uses 12 bits, 2**-12 units, what this gives on the bundled
sample).
"""

from __future__ import annotations

import gzip
import os
import struct
import zlib

import numpy as np

from photo3d.errors import InputError, require
from photo3d.files.atomic import open_write
from photo3d.structures.splats import SH_C0, Splats

PathLike = str | os.PathLike[str]

MAGIC = 0x5053474E
VERSIONS = (2, 3, 4)
"""The versions written and read."""
DEFAULT_VERSION = 3
"""The version photo3d writes unless told (docs/outputs.md says why)."""
COLOR_SCALE = 0.15
"""SPZ's colour byte is ``f_dc * COLOR_SCALE * 255 + 127.5``."""
_FLIP = np.array([1, -1, -1], np.float32)  # OpenCV (RDF) <-> SPZ (RUB)
_HEADER = struct.Struct("<IIIBBBB")
_HEADER_V4 = struct.Struct("<IIIBBBBI12x")
_TOC_ENTRY = struct.Struct("<QQ")  # compressed, uncompressed bytes of a stream
GZIP_LEVEL = 6
"""gzip level of versions 2 and 3 (zlib's default; level 1 makes the bundled
sample's adaptive splats 4 % larger in half the time)."""
ZSTD_LEVEL = 6
"""zstd level of version 4 (Niantic's library uses 12: 1 % smaller than 6 on the
bundled sample's adaptive splats, in over twice the time)."""
_MAX_BITS = 24
_MAX_POINTS = 10_000_000  # the reference reader's limit


def write_spz(path: PathLike, splats: Splats, *, version: int = DEFAULT_VERSION,
              level: int | None = None) -> None:
    """Write ``splats`` as an SPZ file (see the module doc).

    Args:
        path: file to create.
        splats: the Gaussians (OpenCV axes).
        version: 3 (gzip: Spark 2, three.js, SuperSplat, Niantic's library), 4 (zstd
            streams: three.js, SuperSplat, PlayCanvas, Niantic's library since
            2026; needs zstd, see the module doc) or 2 (the oldest readers; 8-bit
            rotations).
        level: compression level (None: :data:`GZIP_LEVEL` for versions 2 and 3,
            :data:`ZSTD_LEVEL` for version 4).

    Raises:
        InputError: the splats are inconsistent, too many (over 10 million, the
            reference reader's limit) or too far apart for 24-bit positions; an
            unknown version.
        MissingExtra: version 4 without a zstd module.

    Example:
        >>> import pathlib, tempfile
        >>> s = Splats(np.array([[0.1, -0.2, 2.0]]), np.array([[0.2, 0.5, 0.8]]),
        ...            np.array([0.9]), np.full((1, 3), 0.004), np.array([[1.0, 0, 0, 0]]))
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "splats.spz"
        >>> write_spz(path, s)
        >>> path.read_bytes()[:2]  # gzip
        b'\\x1f\\x8b'
        >>> back = read_spz(path)
        >>> bool(np.abs(back.positions - s.positions).max() <= 0.004 / 2)  # half a step
        True
        >>> back.colors.astype(float).round(2).tolist()
        [[0.2, 0.5, 0.8]]
        >>> write_spz(path, s, version=4)
        >>> path.read_bytes()[:4], read_spz(path).colors.astype(float).round(2).tolist()
        (b'NGSP', [[0.2, 0.5, 0.8]])
    """
    if version not in VERSIONS:
        raise InputError(f"SPZ version must be one of {', '.join(map(str, VERSIONS))}, "
                         f"got {version}")
    if version == 4:
        data = _encode_v4(splats, level=ZSTD_LEVEL if level is None else level)
    else:
        stream = zlib.compressobj(GZIP_LEVEL if level is None else level, zlib.DEFLATED,
                                  16 + zlib.MAX_WBITS)  # gzip
        data = stream.compress(encode(splats, version=version)) + stream.flush()
    with open_write(path) as file:
        file.write(data)


def encode(splats: Splats, *, version: int = DEFAULT_VERSION) -> bytes:
    """The uncompressed payload of SPZ version 2 or 3 (header and attributes) of
    ``splats``: what the file's gzip stream holds."""
    bits, streams = _streams(splats, version=version)
    return b"".join([_HEADER.pack(MAGIC, version, len(splats), 0, bits, 0, 0), *streams])


def _streams(splats: Splats, *, version: int) -> tuple[int, list[bytes]]:
    """``(fractionalBits, [positions, alphas, colors, scales, rotations])``: the
    attribute streams of ``splats`` (SH degree 0), uncompressed."""
    positions, colors, opacity, scales, rotations = splats.checked()
    count = len(positions)
    if count > _MAX_POINTS:
        raise InputError(f"SPZ readers take at most {_MAX_POINTS:,} splats, got {count:,}")
    bits = _fractional_bits(positions, scales)
    # exact in float32: a power of two and a sign change do not round, and the
    # rounded values (below 2**23) are integers float32 holds
    fixed = np.rint(positions * (_FLIP * np.float32(2.0**bits))).astype("<i4")
    position_bytes = fixed.view(np.uint8).reshape(count, 3, 4)[:, :, :3]
    rotation = rotations / np.linalg.norm(rotations, axis=1, keepdims=True)
    rotation = rotation * np.array([1, 1, -1, -1], np.float32)  # (w, x, -y, -z)
    return bits, [
        position_bytes.tobytes(),
        _to_byte(opacity * 255.0).tobytes(),
        _to_byte((colors - 0.5) / SH_C0 * (COLOR_SCALE * 255.0) + 127.5).tobytes(),
        _to_byte((np.log(scales) + 10.0) * 16.0).tobytes(),
        (_rotations_v2(rotation) if version == 2 else _rotations_v3(rotation)).tobytes(),
    ]


def _encode_v4(splats: Splats, *, level: int) -> bytes:
    """The bytes of an SPZ version 4 file of ``splats`` (see the module doc)."""
    zstd = zstd_module()
    bits, streams = _streams(splats, version=4)
    packed = [zstd.compress(stream, level=level) for stream in streams]
    header = _HEADER_V4.pack(MAGIC, 4, len(splats), 0, bits, 0, len(packed),
                             _HEADER_V4.size)
    table = b"".join(_TOC_ENTRY.pack(len(p), len(u)) for p, u in
                     zip(packed, streams, strict=True))
    return b"".join([header, table, *packed])


def zstd_module():
    """The zstd module: the standard library's ``compression.zstd`` (Python 3.14) or
    ``backports.zstd``.

    Raises:
        MissingExtra: neither is installed (names the extra to install).
    """
    try:
        from compression import zstd  # Python >= 3.14
    except ImportError:
        return require("backports.zstd", "spz4", purpose="SPZ version 4",
                       package="backports-zstd")
    return zstd


def read_spz(path: PathLike) -> Splats:
    """Read an SPZ file (version 2, 3 or 4, any SH degree; SH beyond DC are
    skipped) into :class:`Splats` in OpenCV axes.

    Raises:
        InputError: the file is missing, not SPZ, of another version, uses
            extensions or is truncated or corrupt.
        MissingExtra: version 4 without a zstd module.
    """
    try:
        with open(path, "rb") as file:
            raw = file.read()
    except OSError as err:
        raise InputError(f"cannot read SPZ {path}: {err.strerror or err}") from None
    if raw[:4] == _HEADER.pack(MAGIC, 0, 0, 0, 0, 0, 0)[:4]:
        version, count, degree, bits, streams = _decode_v4(raw, path)
    else:
        version, count, degree, bits, streams = _decode_gzip(raw, path)
    raw_pos, alpha, color, scale, rotation = streams
    fixed = np.zeros((count, 3, 4), np.uint8)
    fixed[:, :, :3] = raw_pos.reshape(count, 3, 3)
    fixed[:, :, 3] = np.where(raw_pos.reshape(count, 3, 3)[:, :, 2] >= 128, 255, 0)
    positions = fixed.view("<i4")[..., 0] * np.float32(2.0**-bits) * _FLIP
    rotations = _unpack_v2(rotation) if version == 2 else _unpack_v3(rotation)
    return Splats(
        positions=positions.astype(np.float32),
        colors=(0.5 + SH_C0 * ((color / 255.0 - 0.5) / COLOR_SCALE)).astype(np.float32),
        opacity=(alpha[:, 0] / 255.0).astype(np.float32),
        scales=np.exp(scale / 16.0 - 10.0).astype(np.float32),
        rotations=(rotations * np.array([1, 1, -1, -1], np.float32)).astype(np.float32),
    )


def _sizes(version: int) -> list[int]:
    """Bytes per splat of the five attribute streams."""
    return [9, 1, 3, 3, 3 if version == 2 else 4]


def _decode_gzip(raw: bytes, path: PathLike) -> tuple[int, int, int, int, list[np.ndarray]]:
    """``(version, count, shDegree, fractionalBits, streams)`` of an SPZ version 2 or
    3 file's bytes; ``streams`` the five attributes as ``(count, bytes) uint8``."""
    try:
        data = gzip.decompress(raw)
    except (OSError, EOFError, zlib.error) as err:
        raise InputError(f"SPZ {path} is not a complete gzip stream ({err})") from None
    if len(data) < _HEADER.size:
        raise InputError(f"{path} is not an SPZ file")
    magic, version, count, degree, bits, flags, _ = _HEADER.unpack_from(data)
    if magic != MAGIC:
        raise InputError(f"{path} is not an SPZ file (magic {magic:#x})")
    if version not in (2, 3):
        raise InputError(f"SPZ {path} is a gzip stream of version {version}; "
                         "versions 2 and 3 are gzip")
    if flags & 2:
        raise InputError(f"SPZ {path} uses extensions, which are not read")
    sizes = _sizes(version)
    need = _HEADER.size + count * (sum(sizes) + 3 * ((degree + 1) ** 2 - 1))
    if degree > 4 or len(data) < need:
        raise InputError(f"SPZ {path} is truncated or has SH degree {degree}")
    arrays, at = [], _HEADER.size
    for size in sizes:
        arrays.append(np.frombuffer(data, np.uint8, count * size, at).reshape(count, size))
        at += count * size
    return version, count, degree, bits, arrays


def _decode_v4(raw: bytes, path: PathLike) -> tuple[int, int, int, int, list[np.ndarray]]:
    """As :func:`_decode_gzip`, of an SPZ version 4 file's bytes."""
    if len(raw) < _HEADER_V4.size:
        raise InputError(f"SPZ {path} is truncated (no version 4 header)")
    _, version, count, degree, bits, flags, streams, toc = _HEADER_V4.unpack_from(raw)
    if version != 4:
        raise InputError(f"SPZ {path} has a version 4 header but says version {version}")
    if flags & 2:
        raise InputError(f"SPZ {path} uses extensions, which are not read")
    expected = [size * count for size in _sizes(4)] + [3 * ((degree + 1) ** 2 - 1) * count]
    expected = [size for size in expected if size > 0]  # empty streams are left out
    if degree > 4 or streams != len(expected) or toc < _HEADER_V4.size:
        raise InputError(f"SPZ {path} has {streams} streams for SH degree {degree}, "
                         f"expected {len(expected)}")
    at = toc + streams * _TOC_ENTRY.size
    if len(raw) < at:
        raise InputError(f"SPZ {path} is truncated (table of contents)")
    zstd = zstd_module()
    arrays = []
    for i, size in enumerate(expected[:5]):
        packed, unpacked = _TOC_ENTRY.unpack_from(raw, toc + i * _TOC_ENTRY.size)
        if unpacked != size or at + packed > len(raw):
            raise InputError(f"SPZ {path} is truncated or its stream {i} has "
                             f"{unpacked} bytes, expected {size}")
        try:
            data = zstd.decompress(raw[at:at + packed])
        except zstd.ZstdError as err:
            raise InputError(f"SPZ {path}: stream {i} is not zstd ({err})") from None
        if len(data) != size:
            raise InputError(f"SPZ {path}: stream {i} holds {len(data)} bytes, not {size}")
        arrays.append(np.frombuffer(data, np.uint8).reshape(count, size // max(count, 1)))
        at += packed
    return version, count, degree, bits, arrays


def _fractional_bits(positions: np.ndarray, scales: np.ndarray) -> int:
    """Bits after the point: the finest step that fits every coordinate in 24 bits,
    and no finer than the smallest splat (its longest axis: a centre is off by at
    most half its standard deviation, the nearest splats only)."""
    largest = float(np.abs(positions).max())
    fits = int(np.floor(np.log2((2**23 - 1) / largest))) if largest > 0 else _MAX_BITS
    useful = int(np.ceil(np.log2(1.0 / float(scales.max(axis=1).min()))))
    bits = min(fits, _MAX_BITS, max(useful, 0))
    if bits < 0:
        raise InputError(f"splat positions up to {largest:g} do not fit SPZ's 24-bit "
                         "fixed point")
    return bits


def _to_byte(values: np.ndarray) -> np.ndarray:
    return np.clip(np.rint(values), 0, 255).astype(np.uint8)


def _rotations_v2(q: np.ndarray) -> np.ndarray:
    """``(N, 3) uint8``: x, y, z of the unit quaternions ``q (w, x, y, z)`` with w >= 0."""
    xyz = q[:, 1:] * np.where(q[:, :1] < 0, -1.0, 1.0)
    return _to_byte(xyz * 127.5 + 127.5)


def _unpack_v2(raw: np.ndarray) -> np.ndarray:
    xyz = raw / 127.5 - 1.0
    w = np.sqrt(np.maximum(0.0, 1.0 - (xyz**2).sum(axis=1, keepdims=True)))
    return np.concatenate([w, xyz], axis=1)


def _rotations_v3(q: np.ndarray) -> np.ndarray:
    """``(N, 4) uint8``: the smallest-three packing of ``q (w, x, y, z)`` (SPZ's
    component order is x, y, z, w)."""
    xyzw = np.concatenate([q[:, 1:], q[:, :1]], axis=1)
    largest = np.abs(xyzw).argmax(axis=1)
    sign = np.where(np.take_along_axis(xyzw, largest[:, None], 1) < 0, -1.0, 1.0)
    xyzw = xyzw * sign
    word = largest.astype(np.uint32)
    for i in range(4):
        value = xyzw[:, i]
        magnitude = np.floor(511.0 * np.abs(value) / np.sqrt(0.5) + 0.5).astype(np.uint32)
        bits = (np.uint32(1) << 9) * (value < 0) | np.minimum(magnitude, 511)
        word = np.where(largest == i, word, (word << 10) | bits.astype(np.uint32))
    return word.astype("<u4").view(np.uint8).reshape(-1, 4)


def _unpack_v3(raw: np.ndarray) -> np.ndarray:
    word = raw.copy().view("<u4")[:, 0].astype(np.uint64)
    largest = (word >> 30).astype(np.int64)
    xyzw = np.zeros((len(word), 4))
    for i in (3, 2, 1, 0):
        here = largest != i
        value = np.sqrt(0.5) * (word & 511) / 511.0 * np.where((word >> 9) & 1, -1.0, 1.0)
        xyzw[here, i] = value[here]
        word = np.where(here, word >> 10, word)
    rest = (xyzw**2).sum(axis=1)
    xyzw[np.arange(len(word)), largest] = np.sqrt(np.maximum(0.0, 1.0 - rest))
    return np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1)
