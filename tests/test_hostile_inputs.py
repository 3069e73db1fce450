"""Hostile input files found by a fuzzing sweep: each one gives exit status 2 and one
line on stderr (a :class:`~photo3d.errors.Photo3DError`), never a traceback or a huge
allocation. The hostile files are built in ``tmp_path``; the CLI runs in-process with
the checks of ``test_robustness.run`` (one line, no traceback, nothing written)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import test_robustness
from memtrace import spy_read_npy
from test_robustness import FAST, run


@pytest.fixture
def photos(tmp_path, monkeypatch) -> Path:
    """``tmp/photos/{a.png, a.npy, notes.txt}``, the current folder ``tmp``
    (``test_robustness.photos``)."""
    return test_robustness.photos.__wrapped__(tmp_path, monkeypatch)


@pytest.fixture
def no_work(monkeypatch) -> None:
    """Fail the test if the pipeline starts (``test_robustness.no_work``)."""
    test_robustness.no_work.__wrapped__(monkeypatch)


# --- photo3d.npz: sizes checked against the image before reading ------------------------


def _ldi_npz(path: Path, n: int, *, size: int = 1, border: int = 0,
             meta: dict | None = None, declared: int | None = None,
             header: dict | None = None, disparity: float = 1.0) -> Path:
    """A folder ``path`` holding a ``photo3d.npz`` of ``n`` unlinked pixels of
    ``disparity`` on a ``size x size`` image; the ``y`` array's header declares
    ``declared`` values (default ``n``); ``header`` replaces fields of the JSON header."""
    import io
    import zipfile

    arrays = {
        "y": np.zeros(n, np.int32), "x": np.zeros(n, np.int32),
        "color": np.zeros((n, 3), np.float32), "disparity": np.full(n, disparity, np.float32),
        "links": np.full((n, 4), -1, np.int32), "label": np.zeros(n, np.uint8),
    }
    arrays["y"][: size * size] = np.arange(size * size) // size
    arrays["x"][: size * size] = np.arange(size * size) % size
    header = {"format": "photo3d-ldi", "version": 1,
              "intrinsics": [size, size, size / 2, size / 2, size, size],
              "mapping": [1.0, 0.0, 0.0], "border": border, "meta": meta or {},
              **(header or {})}
    arrays["header"] = np.frombuffer(json.dumps(header).encode(), np.uint8)
    path.mkdir()
    with zipfile.ZipFile(path / "photo3d.npz", "w", zipfile.ZIP_DEFLATED) as zf:
        for name, array in arrays.items():
            buf = io.BytesIO()
            np.save(buf, array)
            data = buf.getvalue()
            if name == "y" and declared is not None:  # a header promising more data
                head = io.BytesIO()
                np.lib.format.write_array_header_1_0(
                    head, {"descr": "<i4", "fortran_order": False, "shape": (declared,)})
                data = head.getvalue() + data[len(head.getvalue()):]
            zf.writestr(f"{name}.npy", data)
    return path


def test_a_valid_small_npz_renders(tmp_path, capsys):
    """The crafted files below differ from this one only in what they break."""
    run(capsys, "render", _ldi_npz(tmp_path / "ok", 4, size=2), "--still", "-q",
        status=0, root=tmp_path)


@pytest.mark.parametrize(("n", "declared", "border"), [
    (200, None, 0),  # 200 pixels for 1 image pixel: refused though every check passes
    (1 << 10, None, 1),  # 1024 > 16 * 3 * 3
    (4, 1 << 26, 0),  # the sweep's file: 2**26 pixels declared, never decompressed
])
def test_ldi_pixel_count_is_bounded_by_the_image_size(tmp_path, capsys, monkeypatch, n,
                                                      declared, border):
    path = _ldi_npz(tmp_path / "photo", n, border=border, declared=declared)
    sizes = spy_read_npy(monkeypatch)
    run(capsys, "render", path, "--still", "-q", status=2, root=tmp_path,
        message="pixels declared for a 1x1 image")
    assert sizes == [1 << 24]  # only the JSON header was read


@pytest.mark.parametrize("header", [
    {"intrinsics": [10**400, 2, 1, 1, 2, 2]},  # json reads it; float() overflows
    {"mapping": [1, 0, -(10**400)]},
])
def test_a_header_number_too_large_for_a_float_is_one_line(tmp_path, capsys, header):
    path = _ldi_npz(tmp_path / "photo", 4, size=2, header=header)
    run(capsys, "render", path, "--still", "-q", status=2, root=tmp_path,
        message="not a valid photo3d file")


@pytest.mark.parametrize(("header", "message"), [
    ({"border": True}, "border True is not an integer"),  # bool is an int in Python
    ({"border": 1.0}, "border 1.0 is not an integer"),
    ({"version": True}, "format version True is not an integer"),
    ({"intrinsics": [2, 2, 1, 1, True, 2]}, "intrinsics is not a list of numbers"),
    ({"intrinsics": [2, 2, 1, 1, "2", 2]}, "intrinsics is not a list of numbers"),
    ({"mapping": [1, 0, False]}, "mapping is not a list of numbers"),
])
def test_header_booleans_and_strings_are_not_numbers(tmp_path, capsys, header, message):
    # hostile round: "border": true passed as 1, then "pixel positions lie outside"
    path = _ldi_npz(tmp_path / "photo", 4, size=2, header=header)
    run(capsys, "render", path, "--still", "-q", status=2, root=tmp_path, message=message)


@pytest.mark.parametrize(("disparity", "mapping"), [
    (3e38, [3.0, 0.0, 0.05]),  # finite, but scale d overflows: z = 1 / inf = 0
    (1.0, [1.0, -5.0, -1.0]),  # a negative floor: z = -1
    (1.0, [0.0, 0.0, 0.0]),  # z = 1 / 0
])
def test_disparities_that_give_no_positive_depth_are_one_line(tmp_path, capsys, disparity,
                                                             mapping):
    path = _ldi_npz(tmp_path / "photo", 4, size=2, disparity=disparity,
                    header={"mapping": mapping})
    run(capsys, "render", path, "--still", "-q", status=2, root=tmp_path,
        message="do not give finite positive depths")


@pytest.mark.parametrize("quiet", [[], ["-q"]])  # without -q it states the memory first
def test_export_of_a_damaged_pixel_count_member_is_one_line(tmp_path, capsys, quiet):
    import zipfile

    path = _ldi_npz(tmp_path / "photo", 4, size=2)
    npz = path / "photo3d.npz"
    with zipfile.ZipFile(npz) as zf:
        y = zf.getinfo("y.npy")
    data = bytearray(npz.read_bytes())
    data[y.header_offset + 30 + len(y.filename) + len(y.extra)] = 0x07  # deflate type 3
    npz.write_bytes(bytes(data))
    run(capsys, "export", path, "splats.ply", *quiet, status=2, root=tmp_path,
        message="damaged or truncated file")


@pytest.mark.parametrize(("meta", "message"), [
    ({"config": 5}, "saved configuration is a int"),
    ({"config": ["size", 3]}, "saved configuration is a list"),
    ({"config": {"size": 3, "no_such_option": 1}}, "no_such_option"),
    ({"config": {"size": "512"}}, "size must be between 16 and 16384 (a whole number)"),
    ({"config": {"spatial_scale": "x"}}, "spatial_scale must be a number > 0 or None"),
])
def test_a_damaged_saved_config_is_one_line(tmp_path, capsys, meta, message):
    path = _ldi_npz(tmp_path / "photo", 4, size=2, meta=meta)
    run(capsys, "render", path, "--still", "-q", status=2, root=tmp_path, message=message)


def test_damaged_optional_records_are_dropped(tmp_path):
    import photo3d

    meta = {"timings": 3, "stats": "x", "inpainter": [1], "depth_source": {"a": 1}}
    photo = photo3d.load(_ldi_npz(tmp_path / "photo", 4, size=2, meta=meta))
    assert (photo.timings, photo.stats, photo.inpainter, photo.depth_source) == (
        {}, {}, {}, None)


# --- camera-path keyframe files: refused when loaded, before the work --------------------

DEEP = "[" * 100_000 + "]" * 100_000


@pytest.mark.parametrize(("name", "text", "message"), [
    ("deep.json", DEEP, "nested deeper than 64 levels"),
    ("deep.yaml", DEEP, "nested too deeply"),
    ("deep_block.yaml", "- " * 100_000 + "1", "nested too deeply"),
    ("bad.yaml", "a: [1, 2\nb: {", "cannot parse camera path"),  # YAML's message is 5 lines
    ("up.json", '[{"position": [0, 0, 0], "look_at": [0, -3, 0]}]', "straight up or down"),
    ("down.json", '[{"position": [0, 0, 0], "look_at": [1e-6, 5, 0]},'
     '{"position": [1, 0, 0], "look_at": [1, 0, 1]}]', "straight up or down"),
    ("same.json", '[{"position": [0, 0, 0], "look_at": [0, 0, 1]},'
     '{"position": [1, 2, 3], "look_at": [1, 2, 3]}]', "keyframe 1 looks at its own position"),
])
def test_hostile_camera_paths_are_refused_before_the_work(photos, capsys, no_work, name,
                                                          text, message):
    (photos / name).write_text(text)
    run(capsys, "make", photos / "a.png", "--depth", photos / "a.npy", "-o", "out",
        "--path", photos / name, "--size", "48", "-q", status=2, message=message)


def test_a_path_through_a_degenerate_view_is_refused():
    from photo3d.camera import Intrinsics
    from photo3d.errors import InputError
    from photo3d.render.paths import keyframe_path

    # the camera passes through the point it looks at half-way
    keys = [{"position": [0, 0, -1], "look_at": [0, 0, 0]},
            {"position": [0, 0, 1], "look_at": [0, 0, 0]}]
    with pytest.raises(InputError, match="frame 1 .between keyframes. looks at its own"):
        keyframe_path(keys, Intrinsics.default(64, 48), frames=3)


# --- stereo pairs too small or too elongated to match -----------------------------------


@pytest.mark.parametrize("size", [(8, 8), (16, 16), (20000, 10), (10, 20000), (3000, 40)])
def test_tiny_or_elongated_stereo_pairs_are_one_line(photos, capsys, size):
    from PIL import Image

    rng = np.random.default_rng(0)
    w, h = size
    for name in ("l.png", "r.png"):
        Image.fromarray(rng.integers(0, 255, (h, w, 3), np.uint8)).save(photos / name)
    run(capsys, "make", photos / "l.png", "--right", photos / "r.png", "-o", "out", *FAST,
        status=2, message=f"stereo pair is {w}x{h} pixels: too small or too elongated")


# --- eval with a malformed calib.txt -----------------------------------------------------

CALIB = ("cam0=[50 0 32; 0 50 24; 0 0 1]\ncam1=[50 0 34; 0 50 24; 0 0 1]\n"
         "doffs=2\nbaseline=100\nwidth=64\nheight=48\nndisp=32\n")


@pytest.mark.parametrize(("old", "new", "message"), [
    ("cam0=[50 0 32;", "cam0=[. 0 32;", "cam0 must hold a 3x3 matrix"),
    ("cam0=[50 0 32;", "cam0=[5e 0 32;", "cam0 must hold a 3x3 matrix"),
    ("cam1=[50 0 34;", "cam1=[1.2.3 0 34;", "cam1 must hold a 3x3 matrix"),
    ("cam0=[50 0 32;", "cam0=[0 0 32;", "positive focal lengths"),
    ("cam1=[50 0 34;", "cam1=[nan 0 34;", "positive focal lengths"),
    ("baseline=100", "baseline=0", "baseline must be a positive number"),
    ("baseline=100", "baseline=inf", "baseline must be a positive number"),
    ("doffs=2", "doffs=nan", "doffs must be a finite number"),
    ("width=64", "width=-64", "width must be between"),
    ("height=48", "height=x", "missing height"),
    ("doffs=2\n", "doffs=2\n\udcff\udcfe\n", "cannot read calibration"),  # not UTF-8
])
def test_a_malformed_calib_is_one_line(photos, capsys, old, new, message):
    from PIL import Image

    Image.fromarray(np.full((48, 64), 40, np.uint8)).save(photos / "disp.png")
    text = CALIB.replace(old, new)
    assert text != CALIB
    (photos / "calib.txt").write_bytes(text.encode("utf-8", "surrogateescape"))
    run(capsys, "eval", "--pair", photos / "a.png", photos / "a.png", photos / "disp.png",
        photos / "calib.txt", "--methods", "stretch", "--no-lpips", "-o", "ev", "-q",
        status=2, message=message)


# --- --depth-model and PHOTO3D_DEPTH_MODEL that name nothing -----------------------------

BAD_MODELS = [
    ("./missing_dir", "depth model ./missing_dir not found"),
    ("/no/such/model", "not found: no such folder or .onnx file"),
    ("a/b/c", "depth model a/b/c not found"),
    ("bad id with spaces", "nor a Hugging Face name"),
    ("owner/name.", "nor a Hugging Face name"),
    ("owner--x/name", "nor a Hugging Face name"),
]


@pytest.mark.parametrize(("model", "message"), [
    *BAD_MODELS, ("x" * 5000, "not a usable path or name"), ("", "empty"),
    ("a\0b", "nor a Hugging Face name"), ("missing.onnx", "not found"),
])
def test_check_model_name_refuses_names_that_name_nothing(model, message):
    from photo3d.depth.fetch import check_model_name
    from photo3d.errors import InputError

    with pytest.raises(InputError, match=message) as caught:
        check_model_name(model)
    assert "\n" not in str(caught.value) and len(str(caught.value)) < 300


@pytest.fixture
def offline(monkeypatch):
    """No network: a name that passes the checks would fail later, differently."""
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    monkeypatch.setattr("huggingface_hub.constants.HF_HUB_OFFLINE", True)


@pytest.mark.parametrize(("model", "message"), BAD_MODELS)
@pytest.mark.parametrize("command", ["make", "depth"])
def test_a_bad_depth_model_is_one_line(photos, capsys, offline, command, model, message):
    out, extra = ("out", FAST) if command == "make" else ("depth.png", [])
    run(capsys, command, photos / "a.png", "--depth-model", model, "-o", out, *extra,
        status=2, message=message)


@pytest.mark.parametrize(("model", "message"), BAD_MODELS[:4])
def test_a_bad_depth_model_in_the_environment_is_one_line(photos, capsys, offline,
                                                         monkeypatch, model, message):
    monkeypatch.setenv("PHOTO3D_DEPTH_MODEL", model)
    run(capsys, "make", photos / "a.png", "-o", "out", *FAST, status=2, message=message)


@pytest.mark.parametrize(("model", "message"), BAD_MODELS[:4])
@pytest.mark.parametrize("env", [False, True])
def test_batch_refuses_a_bad_depth_model(photos, capsys, offline, monkeypatch, env, model,
                                         message):
    (photos / "a.npy").unlink()  # a photo without depth needs the model
    (photos / "notes.txt").unlink()
    if env:
        monkeypatch.setenv("PHOTO3D_DEPTH_MODEL", model)
    run(capsys, "batch", photos, *([] if env else ["--depth-model", model]), "-o", "out",
        *FAST, status=2, message=message)


# --- TIFFs with damaged deflate data or orientation tags that are not one number ---------


def _tiff(path: Path, array: np.ndarray, *, damaged: bool = False, orientation=None,
          **options) -> Path:
    """Write ``array`` as a deflate TIFF; ``damaged``: its compressed strip garbled;
    ``orientation``: an Orientation tag (a tuple of numbers or a text)."""
    tifffile = pytest.importorskip("tifffile")
    extratags = []
    if orientation is not None:
        kind = "s" if isinstance(orientation, str) else "H"
        extratags = [(274, kind, len(orientation), orientation, True)]
    tifffile.imwrite(path, array, compression="zlib", extratags=extratags, **options)
    if damaged:
        with tifffile.TiffFile(path) as tif:
            start, count = tif.pages[0].dataoffsets[0], tif.pages[0].databytecounts[0]
        data = bytearray(path.read_bytes())
        data[start + 2:start + count] = np.random.default_rng(1).integers(
            0, 256, count - 2, dtype=np.uint8).tobytes()
        path.write_bytes(bytes(data))
    return path


_RNG = np.random.default_rng(0)
RGB16 = _RNG.integers(0, 65535, (48, 64, 3), dtype=np.uint16)
GREY16 = _RNG.integers(1, 65535, (48, 64), dtype=np.uint16)
RGB8 = _RNG.integers(0, 255, (48, 64, 3), dtype=np.uint8)
FLOAT32 = _RNG.random((48, 64), dtype=np.float32) + 0.5
FLOAT64 = FLOAT32.astype(np.float64)

TIFF_PHOTOS = {  # name: (array, damaged, orientation, message)
    "rgb16_damaged": (RGB16, True, None, "damaged or unreadable TIFF"),
    "grey16_damaged": (GREY16, True, None, "damaged image data"),
    "rgb16_two_orientations": (RGB16, False, (1, 6), "orientation tag is damaged"),
    "rgb16_text_orientation": (RGB16, False, "six", "orientation tag holds 'six'"),
    "rgb8_two_orientations": (RGB8, False, (1, 6), "orientation tag is damaged"),
    "rgb8_text_orientation": (RGB8, False, "six", "orientation tag holds 'six'"),
}


@pytest.mark.parametrize("name", sorted(TIFF_PHOTOS))
def test_hostile_tiff_photos_are_one_line(photos, capsys, no_work, name):
    array, damaged, orientation, message = TIFF_PHOTOS[name]
    options = {"photometric": "rgb"} if array.ndim == 3 else {}
    _tiff(photos / f"{name}.tif", array, damaged=damaged, orientation=orientation,
          **options)
    run(capsys, "make", photos / f"{name}.tif", "--depth", photos / "a.npy", "-o", "out",
        *FAST, status=2, message=message)


TIFF_DEPTHS = {
    "f32_damaged": (FLOAT32, True, None, "damaged image data"),
    "f64_damaged": (FLOAT64, True, None, "damaged or unreadable TIFF"),
    "u16_damaged": (GREY16, True, None, "damaged image data"),
    "f32_two_orientations": (FLOAT32, False, (1, 6), "orientation tag is damaged"),
    "f64_two_orientations": (FLOAT64, False, (1, 6), "orientation tag holds (1, 6)"),
    "f64_text_orientation": (FLOAT64, False, "six", "orientation tag holds 'six'"),
}


@pytest.mark.parametrize("name", sorted(TIFF_DEPTHS))
def test_hostile_tiff_depths_are_one_line(photos, capsys, no_work, name):
    array, damaged, orientation, message = TIFF_DEPTHS[name]
    _tiff(photos / f"{name}.tif", array, damaged=damaged, orientation=orientation)
    run(capsys, "make", photos / "a.png", "--depth", photos / f"{name}.tif", "-o", "out",
        *FAST, status=2, message=message)


def test_libtiff_messages_do_not_reach_the_terminal(photos, capfd):
    """libtiff prints its decoding errors on file descriptor 2 itself."""
    from photo3d.cli import main

    _tiff(photos / "d.tif", FLOAT32, damaged=True)
    code = main(["make", str(photos / "a.png"), "--depth", str(photos / "d.tif"), "-o",
                 "out", *FAST])
    err = capfd.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert "ZIPDecode" in err  # libtiff's reason, inside the one line


def test_valid_tiffs_still_read_upright(tmp_path):
    from photo3d.io.depth import read_depth
    from photo3d.io.images import read_image

    image = read_image(_tiff(tmp_path / "p.tif", RGB16, orientation=(6,), photometric="rgb"))
    assert image.shape == (64, 48, 3)  # orientation 6: turned upright
    np.testing.assert_allclose(read_depth(_tiff(tmp_path / "d.tif", FLOAT32)), FLOAT32)


# --- portrait JPEGs whose embedded depth is hostile: refused with one line ---------------


def _gdepth_jpeg(path: Path, data: str, *, image_data: str | None = None) -> Path:
    """A 48x64 JPEG with GDepth XMP (``GDepth:Data`` = ``data``, base64 text) in one
    APP1 segment, and optionally ``GImage:Data``."""
    import io

    from PIL import Image

    gimage = ("" if image_data is None else
              ' xmlns:GImage="http://ns.google.com/photos/1.0/image/" '
              f'GImage:Mime="image/jpeg" GImage:Data="{image_data}"')
    xmp = ('<x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF '
           'xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#"><rdf:Description '
           'rdf:about="" xmlns:GDepth="http://ns.google.com/photos/1.0/depthmap/" '
           'GDepth:Format="RangeInverse" GDepth:Near="1" GDepth:Far="10" '
           f'GDepth:Mime="image/png" GDepth:Data="{data}"{gimage}/></rdf:RDF></x:xmpmeta>')
    payload = b"http://ns.adobe.com/xap/1.0/\x00" + xmp.encode()
    buf = io.BytesIO()
    Image.fromarray(np.random.default_rng(0).integers(0, 255, (48, 64, 3), np.uint8)).save(
        buf, "JPEG")
    jpeg = buf.getvalue()
    segment = b"\xff\xe1" + (len(payload) + 2).to_bytes(2, "big") + payload
    path.write_bytes(jpeg[:2] + segment + jpeg[2:])
    return path


def _b64(data: bytes) -> str:
    import base64

    return base64.b64encode(data).decode()


def _png(array: np.ndarray) -> bytes:
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(array).save(buf, "PNG")
    return buf.getvalue()


def _embedded_cases() -> dict[str, tuple[str, str]]:
    from test_robustness import _png_header_only

    return {
        "pillow_bomb": (_b64(_png_header_only(100_000, 100_000)), "decompression bomb"),
        "large": (_b64(_png_header_only(5000, 5000)), "more than the 16,777,216"),
        "bad_padding": ("abc", "GDepth:Data is not valid base64"),
        "not_base64": ("!!!!" * 3, "not a readable PNG/JPEG"),  # decodes to nothing
        "not_an_image": (_b64(b"hello, world" * 10), "not a readable PNG/JPEG"),
        "truncated_png": (_b64(_png(np.zeros((48, 64), np.uint16))[:60]),
                          "not a readable PNG/JPEG"),
    }


@pytest.mark.parametrize("name", sorted(_embedded_cases()))
def test_hostile_embedded_depth_is_one_line(photos, capsys, no_work, name):
    data, message = _embedded_cases()[name]
    path = _gdepth_jpeg(photos / "portrait.jpg", data)
    run(capsys, "make", path, "-o", "out", *FAST, status=2, message=message)


@pytest.mark.parametrize("image_data", ["abc", _b64(b"not an image"), "@@"])
def test_a_broken_gimage_is_left_out_with_a_warning(tmp_path, image_data):
    from photo3d.depth.portrait import read_embedded_depth

    depth = _png(np.full((24, 32), 30000, np.uint16))
    found = read_embedded_depth(_gdepth_jpeg(tmp_path / "p.jpg", _b64(depth),
                                             image_data=image_data))
    assert found.image is None and found.depth.shape == (24, 32)
    assert len(found.warnings) == 1 and "GImage" in found.warnings[0], found.warnings


@pytest.mark.parametrize("argv", [["render", "--still", "-q"], ["export", "splats.ply", "-q"],
                                  ["view", "--no-browser"]])
def test_a_3d_photos_npz_given_as_its_folder_is_one_helpful_line(tmp_path, capsys, argv):
    # hostile round: "the folder .../photo3d.npz does not exist"
    npz = _ldi_npz(tmp_path / "photo", 4, size=2) / "photo3d.npz"
    run(capsys, argv[0], npz, *argv[1:], status=2, root=tmp_path,
        message=f"{npz} is a file: give the 3D photo's folder ({npz.parent})")


@pytest.mark.parametrize(("size", "message"), [
    ("99999999x48", "video size 99999999x48 is too large: at most 65536 pixels a side"),
    ("0x0", "video size must be positive, got 0x0"),
])
@pytest.mark.parametrize("still", [[], ["--still"]])
def test_a_render_size_names_its_real_problem(tmp_path, capsys, size, message, still):
    # hostile round: both said "video size must be even numbers"
    path = _ldi_npz(tmp_path / "photo", 4, size=2)
    run(capsys, "render", path, "--size", size, *still, "-q", status=2, root=tmp_path,
        message=message)
