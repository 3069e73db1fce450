"""Tests of photo3d.io.images: files written by Pillow/tifffile, read back."""

from __future__ import annotations

import sys

import numpy as np
import pytest
import tifffile
from memtrace import traced_peak
from PIL import Image

from photo3d.errors import InputError, MissingExtra, OutputError
from photo3d.io.images import read_image, to_float_image, write_image

RNG = np.random.default_rng(0)
EXACT = 0.5 / 255  # lossless formats must come back to the same 8-bit value


def _random_rgb(height: int = 12, width: int = 16) -> np.ndarray:
    return RNG.integers(0, 256, size=(height, width, 3), dtype=np.uint8)


@pytest.mark.parametrize(
    ("suffix", "options"),
    [
        (".png", {}),
        (".tif", {}),
        (".tiff", {"compression": "tiff_lzw"}),
        (".webp", {"lossless": True}),
    ],
)
def test_lossless_formats_round_trip_exactly(tmp_path, suffix, options):
    pixels = _random_rgb()
    path = tmp_path / f"photo{suffix}"
    Image.fromarray(pixels).save(path, **options)
    image = read_image(path)
    assert image.shape == (12, 16, 3)
    assert image.dtype == np.float32
    np.testing.assert_allclose(image, pixels / 255.0, atol=EXACT)


def test_jpeg_round_trip_within_tolerance(tmp_path):
    y, x = np.mgrid[0:32, 0:48]
    pixels = np.stack([x * 5, y * 7, (x + y) * 3], axis=-1).astype(np.uint8)
    path = tmp_path / "photo.jpg"
    Image.fromarray(pixels).save(path, quality=95)
    image = read_image(path)
    assert image.shape == (32, 48, 3)
    assert np.abs(image - pixels / 255.0).mean() < 0.01


@pytest.mark.parametrize(("orientation", "red_corner"), [(6, "top_right"), (8, "bottom_left")])
def test_exif_orientation_is_applied(tmp_path, orientation, red_corner):
    stored = np.zeros((16, 24, 3), np.uint8)  # 24 wide, 16 tall, red block top-left
    stored[:8, :8, 0] = 255
    exif = Image.Exif()
    exif[0x0112] = orientation
    path = tmp_path / "rotated.jpg"
    Image.fromarray(stored).save(path, exif=exif, quality=95)

    image = read_image(path)

    assert image.shape == (24, 16, 3)  # width and height swapped
    corners = {
        "top_left": image[2, 2],
        "top_right": image[2, -3],
        "bottom_left": image[-3, 2],
        "bottom_right": image[-3, -3],
    }
    for name, pixel in corners.items():
        is_red = pixel[0] > 0.8 and pixel[1] < 0.2 and pixel[2] < 0.2
        assert is_red == (name == red_corner), (name, pixel)


def test_grey_becomes_three_equal_channels(tmp_path):
    grey = RNG.integers(0, 256, size=(10, 9), dtype=np.uint8)
    path = tmp_path / "grey.png"
    Image.fromarray(grey).save(path)
    image = read_image(path)
    assert image.shape == (10, 9, 3)
    for channel in range(3):
        np.testing.assert_allclose(image[..., channel], grey / 255.0, atol=1e-6)


def test_transparent_pixels_are_composited_over_white(tmp_path):
    rgba = np.zeros((8, 8, 4), np.uint8)  # black everywhere
    rgba[:, :4, 3] = 0  # left half fully transparent
    rgba[:, 4:, 3] = 255  # right half opaque
    rgba[0, 4:, 3] = 128  # first row of the right half half transparent
    path = tmp_path / "rgba.png"
    Image.fromarray(rgba).save(path)
    image = read_image(path)
    np.testing.assert_array_equal(image[:, :4], 1.0)
    np.testing.assert_array_equal(image[1:, 4:], 0.0)
    np.testing.assert_allclose(image[0, 4:], 1.0 - 128 / 255, atol=1e-6)


def test_palette_with_transparency_is_composited_over_white(tmp_path):
    indices = np.zeros((8, 8), np.uint8)
    indices[4:] = 1
    im = Image.fromarray(indices, mode="P")
    im.putpalette([0, 0, 255, 255, 0, 0] + [0] * 762)
    path = tmp_path / "palette.png"
    im.save(path, transparency=0)  # index 0 (blue) is transparent
    image = read_image(path)
    np.testing.assert_array_equal(image[:4], 1.0)
    np.testing.assert_array_equal(image[4:, :, 0], 1.0)
    np.testing.assert_array_equal(image[4:, :, 1:], 0.0)


@pytest.mark.parametrize("suffix", [".png", ".tif"])
def test_sixteen_bit_grey_is_divided_by_65535(tmp_path, suffix):
    values = np.zeros((8, 8), np.uint16)
    values[0, 0], values[0, 1], values[0, 2] = 65535, 32768, 257
    path = tmp_path / f"grey16{suffix}"
    Image.fromarray(values).save(path)
    image = read_image(path)
    assert image[0, 0].tolist() == [1.0, 1.0, 1.0]
    np.testing.assert_allclose(image[0, 1], 0.5, atol=1e-4)
    np.testing.assert_allclose(image[0, 2], 257 / 65535, rtol=1e-6)
    assert image[1, 1].tolist() == [0.0, 0.0, 0.0]


def test_sixteen_bit_rgb_tiff_keeps_its_precision(tmp_path):
    values = RNG.integers(0, 65536, size=(9, 11, 3), dtype=np.uint16)
    path = tmp_path / "rgb16.tif"
    tifffile.imwrite(path, values, photometric="rgb")
    image = read_image(path)
    np.testing.assert_allclose(image, values / 65535.0, rtol=1e-6, atol=1e-7)


def test_sixteen_bit_planar_rgb_tiff(tmp_path):
    values = RNG.integers(0, 65536, size=(3, 9, 11), dtype=np.uint16)
    path = tmp_path / "planar.tif"
    tifffile.imwrite(path, values, photometric="rgb", planarconfig="separate")
    image = read_image(path)
    np.testing.assert_allclose(image, np.moveaxis(values, 0, -1) / 65535.0, rtol=1e-6)


def test_sixteen_bit_rgb_tiff_orientation_tag_is_applied(tmp_path):
    values = RNG.integers(0, 65536, size=(9, 11, 3), dtype=np.uint16)
    path = tmp_path / "rgb16.tif"
    tifffile.imwrite(path, values, photometric="rgb", extratags=[(274, "H", 1, 6, True)])
    image = read_image(path)
    expected = np.rot90(values, k=-1)  # orientation 6: turn 90 degrees clockwise
    np.testing.assert_allclose(image, expected / 65535.0, rtol=1e-6, atol=1e-7)


def test_sixteen_bit_rgb_tiff_without_tifffile_names_the_extra(tmp_path, monkeypatch):
    path = tmp_path / "rgb16.tif"
    tifffile.imwrite(path, np.zeros((9, 9, 3), np.uint16), photometric="rgb")
    monkeypatch.setitem(sys.modules, "tifffile", None)
    message = r"^cannot read image .*rgb16.tif: this TIFF needs the tifffile package: pip "
    with pytest.raises(InputError, match=message + r"install 'photo3d\[tiff\]'$") as err:
        read_image(path)
    assert isinstance(err.value.__cause__, MissingExtra) and err.value.__cause__.extra == "tiff"


def test_float_tiff_in_unit_range_is_read_and_out_of_range_refused(tmp_path):
    values = RNG.random((8, 8), dtype=np.float32)
    good, bad = tmp_path / "good.tif", tmp_path / "bad.tif"
    Image.fromarray(values).save(good)
    Image.fromarray(values * 10).save(bad)
    np.testing.assert_array_equal(read_image(good)[..., 2], values)
    with pytest.raises(InputError, match=r"bad\.tif.*expected \[0, 1\]"):
        read_image(bad)


def test_missing_file(tmp_path):
    path = tmp_path / "nope.jpg"
    with pytest.raises(InputError, match=r"^image file not found: .*nope\.jpg$"):
        read_image(path)


def test_text_file_named_png_is_not_an_image(tmp_path):
    path = tmp_path / "notes.png"
    path.write_text("hello, I am not a picture\n")
    with pytest.raises(InputError, match=r"^cannot read image .*notes\.png: ") as info:
        read_image(path)
    assert "\n" not in str(info.value)


def test_truncated_png_is_unreadable(tmp_path):
    path = tmp_path / "cut.png"
    Image.fromarray(_random_rgb(64, 64)).save(path)
    path.write_bytes(path.read_bytes()[:200])
    with pytest.raises(InputError, match=r"cannot read image .*cut\.png"):
        read_image(path)


def test_folder_is_not_an_image(tmp_path):
    with pytest.raises(InputError, match="folder"):
        read_image(tmp_path)


def test_tiny_image_is_refused_with_its_size(tmp_path):
    path = tmp_path / "tiny.png"
    Image.fromarray(np.zeros((3, 4, 3), np.uint8)).save(path)  # 4 wide, 3 tall
    message = r"^image .*tiny\.png is 4x3 pixels; photo3d needs at least 8x8$"
    with pytest.raises(InputError, match=message):
        read_image(path)


def test_errors_are_value_errors(tmp_path):
    with pytest.raises(ValueError, match="not found"):
        read_image(tmp_path / "missing.png")


def test_to_float_image_rules():
    rgb = _random_rgb(8, 8)
    np.testing.assert_allclose(to_float_image(rgb), rgb / 255.0, atol=1e-7)
    assert to_float_image(np.full((8, 8), 65535, np.uint16)).tolist() == np.ones((8, 8, 3)).tolist()
    floats = RNG.random((8, 8, 3))
    out = to_float_image(floats)
    assert out.dtype == np.float32 and out.flags.c_contiguous
    np.testing.assert_allclose(out, floats, atol=1e-7)


def test_to_float_image_returns_a_copy():
    floats = np.zeros((8, 8, 3), np.float32)
    out = to_float_image(floats)
    out[...] = 1.0
    assert floats.max() == 0.0


def test_to_float_image_rgba_float_alpha_blend():
    rgba = np.zeros((8, 8, 4), np.float32)
    rgba[..., 0] = 1.0  # red
    rgba[..., 3] = 0.25
    np.testing.assert_allclose(to_float_image(rgba)[0, 0], [1.0, 0.75, 0.75])


@pytest.mark.parametrize(
    ("array", "message"),
    [
        (
            np.zeros((4, 4, 5)),
            r"^image has shape \(4, 4, 5\); expected \(H, W\), \(H, W, 3\) or \(H, W, 4\)$",
        ),
        (np.zeros((4, 4, 1)), r"shape \(4, 4, 1\)"),
        (np.zeros(4), r"shape \(4,\)"),
        (np.zeros((0, 4, 3)), "no pixels"),
        (np.zeros((4, 4, 3), np.int32), "dtype int32"),
        (np.full((4, 4, 3), 1.5), r"span \[1\.5, 1\.5\]"),
        (np.full((4, 4, 3), np.nan), "NaN"),
    ],
)
def test_to_float_image_refuses_bad_arrays(array, message):
    with pytest.raises(InputError, match=message):
        to_float_image(array)


def test_write_image_float_clips_and_rounds(tmp_path):
    image = np.array([[-0.2, 0.5, 1.3, 0.2]], np.float32).repeat(8, axis=0)
    image = np.repeat(image[:, :, None], 3, axis=2)
    path = tmp_path / "out.png"
    write_image(path, image)
    stored = np.asarray(Image.open(path))  # independent reader
    assert stored.dtype == np.uint8
    assert stored[0, :, 0].tolist() == [0, 128, 255, 51]


def test_write_image_uint8_and_grey_written_as_is(tmp_path):
    pixels = _random_rgb(8, 9)
    write_image(tmp_path / "rgb.png", pixels)
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "rgb.png")), pixels)
    grey = pixels[..., 0]
    write_image(tmp_path / "grey.png", grey)
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "grey.png")), grey)


def test_write_image_jpeg(tmp_path):
    image = np.full((16, 16, 3), [0.2, 0.4, 0.6], np.float32)
    path = tmp_path / "out.JPEG"
    write_image(path, image)
    with Image.open(path) as im:
        assert im.format == "JPEG"
    np.testing.assert_allclose(read_image(path), image, atol=0.02)


def test_write_image_errors(tmp_path):
    image = np.zeros((8, 8, 3), np.float32)
    with pytest.raises(OutputError, match=r"unsupported extension '\.bmp'"):
        write_image(tmp_path / "out.bmp", image)
    with pytest.raises(OutputError, match=r"cannot write .*missing"):
        write_image(tmp_path / "missing" / "out.png", image)
    with pytest.raises(InputError, match=r"shape \(8, 8, 4\)"):
        write_image(tmp_path / "out.png", np.zeros((8, 8, 4)))
    with pytest.raises(InputError, match="dtype uint16"):
        write_image(tmp_path / "out.png", np.zeros((8, 8, 3), np.uint16))
    with pytest.raises(InputError, match="NaN"):
        write_image(tmp_path / "out.png", np.full((8, 8, 3), np.nan))


# --- photos read for a working size: decoded reduced, memory checked first (issue 36) --


def _natural(name: str) -> np.ndarray:
    """A natural photo of scikit-image: ``(H, W, 3) uint8``."""
    data = pytest.importorskip("skimage.data")
    return getattr(data, name)()


def test_decoded_shape_keeps_the_working_shape_and_the_aspect():
    from photo3d.config import working_shape
    from photo3d.io.images import KEEP, decoded_shape

    rng = np.random.default_rng(3)
    reduced = 0
    for _ in range(3000):
        size = int(rng.integers(16, 2048))
        shape = tuple(int(v) for v in rng.integers(8, 20 * size, 2))
        out = decoded_shape(shape, size)
        if max(shape) <= KEEP * size:
            assert out == shape
            continue
        working = working_shape(shape, size)
        assert working_shape(out, size) == working, (shape, size, out)
        if out != shape:
            reduced += 1
            assert KEEP * size <= max(out) < 2 * KEEP * size
            assert min(out) >= max(8, KEEP * min(working))
            assert abs(out[1] * shape[0] / (out[0] * shape[1]) - 1) <= 1.001e-3
            assert decoded_shape(shape[::-1], size) == out[::-1]  # either way up
    assert reduced > 2000
    assert decoded_shape((9750, 13000), None) == (9750, 13000)


@pytest.mark.parametrize("suffix", [".png", ".jpg"])
@pytest.mark.parametrize(("name", "size"), [("astronaut", 48), ("astronaut", 100),
                                            ("coffee", 64), ("coffee", 125)])
def test_a_reduced_photo_gives_the_same_working_image(tmp_path, suffix, name, size):
    """The pipeline's resize of the reduced photo matches its resize of the whole."""
    from photo3d.config import working_shape
    from photo3d.io.images import decoded_shape
    from photo3d.stages.preprocess import resize

    path = tmp_path / f"{name}{suffix}"
    Image.fromarray(_natural(name)).save(path, quality=92)
    whole = read_image(path)
    reduced = read_image(path, working_size=size)
    assert reduced.shape[:2] == decoded_shape(whole.shape[:2], size) != whole.shape[:2]
    shape = working_shape(whole.shape[:2], size)
    diff = np.abs(np.clip(resize(whole, shape), 0, 1) - np.clip(resize(reduced, shape), 0, 1))
    assert diff.mean() < 0.5 / 255 and diff.max() < 16 / 255, (diff.mean() * 255,
                                                                 diff.max() * 255)


def test_photos_up_to_keep_times_the_working_size_are_decoded_exactly(tmp_path):
    path = tmp_path / "a.png"
    Image.fromarray(_natural("coffee")).save(path)  # 600 x 400
    whole = read_image(path)
    for size in (300, 400, 1024):
        np.testing.assert_array_equal(read_image(path, working_size=size), whole)


@pytest.mark.parametrize("mode", ["P", "LA", "RGBA", "1", "I;16", "I", "F", "CMYK"])
def test_every_mode_is_reduced_like_the_whole(tmp_path, mode):
    from photo3d.config import working_shape
    from photo3d.stages.preprocess import resize

    rgb = Image.fromarray(_natural("coffee"))
    alpha = Image.fromarray(np.tile(np.linspace(0, 255, 600, dtype=np.uint8), (400, 1)))
    if mode == "P":
        im = rgb.convert("P")
        im.info["transparency"] = 0
    elif mode in ("LA", "RGBA"):
        im = rgb.convert("RGBA")
        im.putalpha(alpha)
        im = im.convert(mode)
    elif mode in ("I;16", "I", "F"):
        grey = np.asarray(rgb.convert("L"), np.float32) / 255
        im = Image.fromarray((grey * 65535).astype(np.uint16)) if mode == "I;16" else (
            Image.fromarray((grey * 65535).astype(np.int32)) if mode == "I" else
            Image.fromarray(grey, "F"))
    else:
        im = rgb.convert(mode)
    path = tmp_path / ("a.tif" if mode in ("I", "F", "CMYK") else "a.png")
    im.save(path)
    whole = read_image(path)
    reduced = read_image(path, working_size=64)
    shape = working_shape(whole.shape[:2], 64)
    diff = np.abs(np.clip(resize(whole, shape), 0, 1) - np.clip(resize(reduced, shape), 0, 1))
    assert reduced.shape[:2] != whole.shape[:2]
    assert diff.mean() < 1 / 255 and diff.max() < 16 / 255, (diff.mean() * 255,
                                                              diff.max() * 255)


@pytest.mark.parametrize("kind", ["tiff16", "png16"])
def test_sixteen_bit_colour_photos_are_reduced_like_the_whole(tmp_path, kind):
    from photo3d.config import working_shape
    from photo3d.stages.preprocess import resize

    pixels = _natural("astronaut").astype(np.uint16) * 257
    if kind == "tiff16":
        path = tmp_path / "a.tif"
        tifffile.imwrite(path, pixels, photometric="rgb")
    else:
        cv2 = pytest.importorskip("cv2")
        path = tmp_path / "a.png"
        cv2.imwrite(str(path), np.ascontiguousarray(pixels[:, :, ::-1]))
    whole = read_image(path)
    reduced = read_image(path, working_size=64)
    assert reduced.shape == (128, 128, 3)
    shape = working_shape(whole.shape[:2], 64)
    diff = np.abs(np.clip(resize(whole, shape), 0, 1) - np.clip(resize(reduced, shape), 0, 1))
    assert diff.mean() < 0.5 / 255 and diff.max() < 16 / 255


@pytest.mark.parametrize("suffix", [".jpg", ".png"])
def test_a_reduced_photo_is_turned_upright(tmp_path, suffix):
    from photo3d.io.images import decoded_shape

    stored = np.zeros((400, 600, 3), np.uint8)  # red block top-left
    stored[:100, :100, 0] = 255
    exif = Image.Exif()
    exif[0x0112] = 6  # turned clockwise: the block goes top right
    path = tmp_path / f"rotated{suffix}"
    Image.fromarray(stored).save(path, exif=exif, quality=95)
    image = read_image(path, working_size=64)
    assert image.shape[:2] == decoded_shape((600, 400), 64) == (129, 86)
    assert image[5, -5, 0] > 0.9 and image[5, 5, 0] < 0.1 and image[-5, -5, 0] < 0.1


def test_a_large_photo_never_exists_as_float32(tmp_path):
    """4000 x 3000 at working size 64: today's reader made a 144 MB float32 copy (and
    more) before any resize."""
    path = tmp_path / "large.png"
    Image.new("RGB", (4000, 3000), (200, 100, 50)).save(path)
    image, peak = traced_peak(lambda: read_image(path, working_size=64))
    assert image.shape == (96, 128, 3)
    np.testing.assert_allclose(image[0, 0], [200 / 255, 100 / 255, 50 / 255], atol=EXACT)
    assert peak < 10e6, peak


@pytest.mark.parametrize("suffix", [".png", ".jpg", ".tif"])
def test_decoding_beyond_the_available_memory_is_refused_first(tmp_path, monkeypatch,
                                                               suffix):
    import photo3d.io.images as images

    path = tmp_path / f"large{suffix}"
    Image.new("RGB", (4000, 3000), (200, 100, 50)).save(path)
    monkeypatch.setattr("photo3d.io.limits.available_memory", lambda: 50_000_000)

    def no_decoding(im):
        raise AssertionError("decoded before the memory check")

    monkeypatch.setattr(images, "load_pixels", no_decoding)
    with pytest.raises(InputError, match=r"large\S*: decoding its 4000x3000 pixels needs "
                                         r"about \d+ MB of memory but 50 MB are avail") as err:
        read_image(path)
    assert "\n" not in str(err.value)


def test_a_reduced_photo_fits_where_the_whole_would_not(tmp_path, monkeypatch):
    path = tmp_path / "large.jpg"
    Image.new("RGB", (4000, 3000), (200, 100, 50)).save(path)
    monkeypatch.setattr("photo3d.io.limits.available_memory", lambda: 100_000_000)
    with pytest.raises(InputError, match="decoding its 4000x3000 pixels needs about"):
        read_image(path)
    assert read_image(path, working_size=256).shape == (384, 512, 3)  # the decoder scales


@pytest.mark.parametrize("suffix", [".png", ".tif"])
def test_pillows_decompression_bomb_warning_is_not_shown(tmp_path, monkeypatch, suffix):
    """More pixels than Pillow's warning limit: the memory check decides, silently
    (pytest turns any warning into an error)."""
    path = tmp_path / f"many{suffix}"
    Image.new("RGB", (1200, 1000), (200, 100, 50)).save(path)
    monkeypatch.setattr(Image, "MAX_IMAGE_PIXELS", 1_000_000)
    assert read_image(path).shape == (1000, 1200, 3)
    assert read_image(path, working_size=64).shape == (110, 132, 3)


@pytest.mark.parametrize(("suffix", "kind"), [(".gif", "frames"), (".webp", "frames"),
                                              (".tif", "pages")])
def test_a_file_of_many_frames_is_read_at_its_first_with_a_warning(tmp_path, suffix, kind):
    # issue 45: animated GIF/WebP and multi-page TIFF used their first frame silently
    from PIL import Image

    from photo3d.io.images import read_image

    frames = [Image.new("RGB", (16, 12), colour) for colour in ("red", "lime", "blue")]
    path = tmp_path / f"moving{suffix}"
    frames[0].save(path, save_all=True, append_images=frames[1:])
    with pytest.warns(UserWarning, match=f"moving{suffix} has 3 {kind}; photo3d uses the first"):
        image = read_image(path)
    assert image[0, 0, 0] > 0.9 and image[0, 0, 1] < 0.1  # red: the first frame
