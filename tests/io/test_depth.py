"""Tests of photo3d.io.depth: depth files written independently, read back raw."""

from __future__ import annotations

import struct
import sys
import zlib

import numpy as np
import pytest
import tifffile
from PIL import Image

from photo3d.errors import InputError, MissingExtra, OutputError
from photo3d.io.depth import read_depth, write_depth_png16, write_pfm

RNG = np.random.default_rng(1)


def _png_bytes(values: np.ndarray, colour_type: int) -> bytes:
    """A minimal 16-bit PNG (Pillow cannot write 16-bit colour), filter 0 per row."""
    height, width = values.shape[:2]
    rows = values.astype(">u2").reshape(height, -1)
    raw = b"".join(b"\x00" + row.tobytes() for row in rows)

    def chunk(kind: bytes, data: bytes) -> bytes:
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    header = struct.pack(">IIBBBBB", width, height, 16, colour_type, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", header)
        + chunk(b"IDAT", zlib.compress(raw))
        + chunk(b"IEND", b"")
    )


def test_eight_bit_png_exact_values(tmp_path):
    values = np.arange(256, dtype=np.uint8).reshape(16, 16)
    path = tmp_path / "d8.png"
    Image.fromarray(values).save(path)
    depth = read_depth(path)
    assert depth.dtype == np.float32 and depth.shape == (16, 16)
    np.testing.assert_array_equal(depth, values)


def test_sixteen_bit_png_exact_values(tmp_path):
    values = RNG.integers(0, 65536, size=(7, 9), dtype=np.uint16)
    values[0, :3] = [0, 1, 65535]
    path = tmp_path / "d16.png"
    Image.fromarray(values).save(path)
    np.testing.assert_array_equal(read_depth(path), values)


def test_sixteen_bit_grey_png_written_by_hand_is_read(tmp_path):
    values = np.array([[0, 300], [65535, 4097]], np.uint16)
    path = tmp_path / "hand.png"
    path.write_bytes(_png_bytes(values, colour_type=0))
    np.testing.assert_array_equal(read_depth(path), values)


def test_sixteen_bit_colour_png_is_refused(tmp_path):
    path = tmp_path / "rgb16.png"
    path.write_bytes(_png_bytes(np.zeros((2, 2, 3), np.uint16), colour_type=2))
    with pytest.raises(InputError, match=r"rgb16\.png.*16-bit grey"):
        read_depth(path)


def test_rgb_png_with_equal_channels_gives_the_first(tmp_path):
    grey = RNG.integers(0, 256, size=(6, 5), dtype=np.uint8)
    path = tmp_path / "rgb.png"
    Image.fromarray(np.repeat(grey[:, :, None], 3, axis=2)).save(path)
    np.testing.assert_array_equal(read_depth(path), grey)


def test_rgb_png_with_different_channels_is_refused(tmp_path):
    rgb = np.zeros((6, 5, 3), np.uint8)
    rgb[2, 3, 1] = 9
    path = tmp_path / "colour.png"
    Image.fromarray(rgb).save(path)
    with pytest.raises(InputError, match=r"colour\.png.*must be grey"):
        read_depth(path)


@pytest.mark.parametrize("shape", [(5, 7), (1, 5, 7), (5, 7, 1)])
def test_npy_values_and_singleton_axis(tmp_path, shape):
    values = RNG.normal(size=shape)
    values.flat[0] = np.inf
    path = tmp_path / "d.npy"
    np.save(path, values)
    depth = read_depth(path)
    assert depth.shape == (5, 7) and depth.dtype == np.float32
    np.testing.assert_array_equal(depth, values.reshape(5, 7).astype(np.float32))


def test_npy_integer_array(tmp_path):
    values = np.arange(12, dtype=np.int64).reshape(3, 4) * 1000
    path = tmp_path / "d.npy"
    np.save(path, values)
    np.testing.assert_array_equal(read_depth(path), values)


def test_npy_float64_beyond_float32_reads_as_inf_without_a_warning(tmp_path):
    """inf is an unknown pixel (the module's rule); before, NumPy's "overflow
    encountered in cast" reached the user as a warning line."""
    path = tmp_path / "d.npy"
    np.save(path, np.array([[1e300, -1e300], [2.0, 3.0]]))
    assert read_depth(path).tolist() == [[np.inf, -np.inf], [2.0, 3.0]]


def test_npy_object_array_is_refused(tmp_path):
    path = tmp_path / "evil.npy"
    np.save(path, np.array([[1, "a"], [None, 2.0]], dtype=object), allow_pickle=True)
    with pytest.raises(InputError, match=r"evil\.npy.*numeric"):
        read_depth(path)


@pytest.mark.parametrize(("shape", "message"), [((2, 3, 4), r"\(2, 3, 4\)"), ((6,), r"\(6,\)")])
def test_npy_wrong_shape_is_refused(tmp_path, shape, message):
    path = tmp_path / "d.npy"
    np.save(path, np.zeros(shape))
    with pytest.raises(InputError, match=message):
        read_depth(path)


def test_npy_complex_is_refused(tmp_path):
    path = tmp_path / "d.npy"
    np.save(path, np.zeros((3, 3), complex))
    with pytest.raises(InputError, match="complex"):
        read_depth(path)


def test_pfm_round_trip_with_non_finite_values(tmp_path):
    values = RNG.normal(size=(4, 6)).astype(np.float32)
    values[0, 0], values[1, 2], values[3, 5] = np.inf, -np.inf, np.nan
    path = tmp_path / "d.pfm"
    write_pfm(path, values)
    np.testing.assert_array_equal(read_depth(path), values)  # NaN == NaN here


def test_pfm_file_layout_is_standard(tmp_path):
    values = np.arange(6, dtype=np.float32).reshape(2, 3)  # row 0 = top = [0, 1, 2]
    path = tmp_path / "d.pfm"
    write_pfm(path, values)
    raw = path.read_bytes()
    header = b"Pf\n3 2\n-1.0\n"
    assert raw.startswith(header)
    stored = np.frombuffer(raw[len(header) :], "<f4")
    assert stored.tolist() == [3, 4, 5, 0, 1, 2]  # bottom row first


def test_pfm_big_endian_colour_uses_first_channel_and_flips_rows(tmp_path):
    top, bottom = [[1, 9, 9], [2, 9, 9]], [[3, 9, 9], [4, 9, 9]]
    data = np.array([bottom, top], ">f4")  # file order: bottom row first
    path = tmp_path / "be.pfm"
    path.write_bytes(b"PF\r\n2 2\r\n1.0\r\n" + data.tobytes())
    np.testing.assert_array_equal(read_depth(path), [[1, 2], [3, 4]])


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (b"P6\n2 2\n255\n" + bytes(12), "not a PFM"),
        (b"Pf\n2 2\n-1.0\n" + bytes(8), "truncated"),
        (b"Pf\n2 2\n0\n" + bytes(16), "scale"),
        (b"Pf\n2 2\nabc\n" + bytes(16), "scale"),
    ],
)
def test_pfm_bad_files_are_refused(tmp_path, content, message):
    path = tmp_path / "bad.pfm"
    path.write_bytes(content)
    with pytest.raises(InputError, match=rf"bad\.pfm.*{message}"):
        read_depth(path)


@pytest.mark.parametrize("suffix", [".tif", ".tiff"])
def test_float_tiff_round_trip(tmp_path, suffix):
    values = RNG.normal(size=(5, 8)).astype(np.float32) * 100
    values[2, 2] = np.inf
    path = tmp_path / f"d{suffix}"
    tifffile.imwrite(path, values)
    np.testing.assert_array_equal(read_depth(path), values)


def test_float_tiff_written_by_pillow(tmp_path):
    values = RNG.random((6, 4), dtype=np.float32) * 40
    path = tmp_path / "d.tif"
    Image.fromarray(values).save(path)
    np.testing.assert_array_equal(read_depth(path), values)


def test_float64_tiff_goes_through_tifffile(tmp_path):
    values = RNG.normal(size=(5, 8)) * 1000
    path = tmp_path / "d.tif"
    tifffile.imwrite(path, values)
    np.testing.assert_array_equal(read_depth(path), values.astype(np.float32))


def test_float64_tiff_without_tifffile_names_the_extra(tmp_path, monkeypatch):
    path = tmp_path / "d.tif"
    tifffile.imwrite(path, np.zeros((5, 8)))
    monkeypatch.setitem(sys.modules, "tifffile", None)
    with pytest.raises(InputError, match=r"pip install 'photo3d\[tiff\]'") as err:
        read_depth(path)
    assert isinstance(err.value.__cause__, MissingExtra) and err.value.__cause__.extra == "tiff"


def test_grey_tiff_stored_as_separate_colour_planes(tmp_path):
    """tifffile gives (C, H, W) for separate planes; the shared reader puts them last."""
    rng = np.random.default_rng(0)
    depth = rng.random((20, 30)).astype(np.float32)
    path = tmp_path / "planes.tif"
    tifffile.imwrite(path, np.stack([depth] * 3), planarconfig="separate", photometric="rgb")
    np.testing.assert_array_equal(read_depth(path), depth)


def test_sixteen_bit_tiff_raw_values(tmp_path):
    values = RNG.integers(0, 65536, size=(5, 8), dtype=np.uint16)
    path = tmp_path / "d.tif"
    tifffile.imwrite(path, values)
    np.testing.assert_array_equal(read_depth(path), values)


def test_unsupported_extension_names_path_and_formats(tmp_path):
    path = tmp_path / "depth.jpg"
    Image.fromarray(np.zeros((8, 8), np.uint8)).save(path)
    with pytest.raises(InputError, match=r"depth\.jpg.*'\.jpg'.*\.png.*\.npy.*\.pfm.*\.tif"):
        read_depth(path)


def test_missing_depth_file(tmp_path):
    with pytest.raises(InputError, match=r"^depth file not found: .*gone\.pfm; .*\.npy"):
        read_depth(tmp_path / "gone.pfm")


@pytest.mark.parametrize("suffix", [".png", ".npy", ".tif"])
def test_garbage_file_is_unreadable(tmp_path, suffix):
    path = tmp_path / f"junk{suffix}"
    path.write_text("not depth at all, just some text\n" * 4)
    with pytest.raises(InputError, match=rf"^cannot read depth .*junk\{suffix}: .*\.pfm"):
        read_depth(path)


def test_write_depth_png16_maps_linearly(tmp_path):
    depth = np.array([[2.0, 4.0, 6.0], [np.inf, np.nan, 3.0]])
    path = tmp_path / "d.png"
    assert write_depth_png16(path, depth) == (2.0, 6.0)
    with Image.open(path) as im:  # independent reader
        assert im.mode.startswith("I")
        stored = np.asarray(im).astype(np.int64)
    assert stored.tolist() == [[0, 32768, 65535], [0, 0, 16384]]


def test_write_depth_png16_explicit_range_clips(tmp_path):
    path = tmp_path / "d.png"
    used = write_depth_png16(path, np.array([[0.0, 5.0, 10.0]]), vmin=5.0, vmax=7.0)
    assert used == (5.0, 7.0)
    assert read_depth(path).tolist() == [[0.0, 0.0, 65535.0]]


def test_write_depth_png16_constant_and_errors(tmp_path):
    path = tmp_path / "d.png"
    assert write_depth_png16(path, np.full((2, 2), 3.0)) == (3.0, 3.0)
    assert read_depth(path).max() == 0.0
    with pytest.raises(InputError, match="vmax"):
        write_depth_png16(path, np.zeros((2, 2)), vmin=2.0, vmax=1.0)
    with pytest.raises(OutputError, match=r"\.png"):
        write_depth_png16(tmp_path / "d.tif", np.zeros((2, 2)))
    with pytest.raises(InputError, match=r"shape \(2, 2, 3\)"):
        write_depth_png16(path, np.zeros((2, 2, 3)))


def test_write_pfm_errors(tmp_path):
    with pytest.raises(InputError, match=r"shape \(2, 2, 2\)"):
        write_pfm(tmp_path / "d.pfm", np.zeros((2, 2, 2)))
    with pytest.raises(OutputError, match=r"cannot write .*nowhere"):
        write_pfm(tmp_path / "nowhere" / "d.pfm", np.zeros((2, 2)))


# --- maps read for a working size: resampled before the float conversion (issue 36) ----


def _write_map(path, values: np.ndarray) -> None:
    """Write ``values`` in the format ``path``'s suffix names (npy, pfm, else Pillow)."""
    if path.suffix == ".npy":
        np.save(path, values)
    elif path.suffix == ".pfm":
        write_pfm(path, values)
    else:
        Image.fromarray(values).save(path)


def _large_map() -> np.ndarray:
    """``(3000, 4000) uint16``: steps and a ramp, compressible."""
    values = np.full((3000, 4000), 1000, np.uint16)
    values[:, 2000:] = 3000
    values[1000:2000, 500:1500] = np.arange(1000, dtype=np.uint16)[None, :] + 5000
    return values


@pytest.mark.parametrize("suffix", [".png", ".npy", ".pfm", ".tif"])
def test_a_large_map_comes_back_at_the_photos_decoded_shape(tmp_path, suffix):
    """As the photo of its size is decoded (io.images.decoded_shape), by nearest
    neighbour as match_shape resamples, and never whole as float32."""
    import tracemalloc

    from photo3d.depth.normalize import match_shape
    from photo3d.io.images import decoded_shape

    values = _large_map()
    path = tmp_path / f"d{suffix}"
    _write_map(path, values)
    tracemalloc.start()
    try:
        depth = read_depth(path, working_size=64)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    shape = decoded_shape(values.shape, 64)
    assert depth.shape == shape == (96, 128) and depth.dtype == np.float32
    np.testing.assert_array_equal(depth, match_shape(values.astype(np.float32), shape)[0])
    # the stored values and one copy; before, also the whole map as float32: 3 times
    # (PFM: 4 times) the map's uint16 bytes
    assert peak < 2.5 * values.nbytes, peak / values.nbytes
    np.testing.assert_array_equal(read_depth(path), values.astype(np.float32))


@pytest.mark.parametrize("suffix", [".png", ".npy", ".pfm", ".tif"])
def test_a_map_beyond_the_available_memory_is_refused_first(tmp_path, monkeypatch, suffix):
    path = tmp_path / f"d{suffix}"
    values = _large_map()
    _write_map(path, values)
    monkeypatch.setattr("photo3d.io.limits.available_memory", lambda: 20_000_000)
    with pytest.raises(InputError, match=r"d\.\w+: decoding .* needs about \d+ MB of memory "
                                         r"but 20 MB are available") as err:
        read_depth(path)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("suffix", [".png", ".tif"])
def test_pillows_decompression_bomb_warning_is_not_shown_for_maps(tmp_path, monkeypatch,
                                                                  suffix):
    path = tmp_path / f"d{suffix}"
    Image.fromarray(np.full((1000, 1200), 7, np.uint16)).save(path)
    monkeypatch.setattr(Image, "MAX_IMAGE_PIXELS", 1_000_000)
    assert read_depth(path).shape == (1000, 1200)  # pytest turns warnings into errors
