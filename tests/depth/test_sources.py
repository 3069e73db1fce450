"""resolve_depth: one entry point for every source; export_depth round trip."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from photo3d.depth.export import VIRIDIS, colorize, export_depth
from photo3d.depth.normalize import normalize, prepare_depth
from photo3d.depth.sources import DepthEstimate, read_photo, resolve_depth
from photo3d.errors import InputError, OutputError
from photo3d.io.depth import read_depth, write_pfm
from photo3d.io.images import read_image, write_image


def floor_disparity(h: int = 48, w: int = 64) -> np.ndarray:
    """A plausible map: bottom rows nearer than top rows."""
    return np.tile(np.linspace(1.0, 4.0, h, dtype=np.float32)[:, None], (1, w))


def photo_file(tmp_path, h: int = 48, w: int = 64):
    path = tmp_path / "photo.png"
    write_image(path, np.full((h, w, 3), 0.5, np.float32))
    return path


def test_depth_file_is_passed_on_with_its_kind(tmp_path):
    write_pfm(tmp_path / "d.pfm", 1.0 / floor_disparity())
    est = resolve_depth(photo_file(tmp_path), depth=tmp_path / "d.pfm", kind="depth")
    assert est.kind == "depth" and est.warnings == ()
    assert est.source == f"depth file {tmp_path / 'd.pfm'} (depth)"
    np.testing.assert_allclose(est.depth, 1.0 / floor_disparity())


def test_depth_given_as_disparity_by_mistake_is_flagged(tmp_path):
    est = resolve_depth(photo_file(tmp_path), depth=1.0 / floor_disparity())
    assert est.kind == "disparity"
    assert est.warnings[0].startswith(
        "depth looks inverted (near is dark): pass --depth-kind depth")


def test_depth_of_another_size_reports_the_resampling(tmp_path):
    est = resolve_depth(photo_file(tmp_path), depth=floor_disparity(24, 32))
    assert est.depth.shape == (48, 64)  # resampled once here: the pipeline does not warn
    assert sum("resampling" in w for w in est.warnings) == 1
    with pytest.raises(InputError, match="aspect ratios differ"):
        resolve_depth(photo_file(tmp_path), depth=floor_disparity(48, 20))


def test_stereo_source(tmp_path):
    from test_stereo import layered_pair  # skips this test without OpenCV contrib

    left, right, truth = layered_pair()
    est = resolve_depth(left, right=right)
    assert est.kind == "disparity" and est.depth.shape == truth.shape
    assert est.source.startswith("stereo pair (SGBM, ") and "disparities up to" in est.source
    write_image(tmp_path / "l.png", left)
    write_image(tmp_path / "r.png", right)
    from_files = resolve_depth(tmp_path / "l.png", right=tmp_path / "r.png")
    assert np.median(np.abs(from_files.depth - truth)) < 0.5


def test_model_source_with_a_tiny_onnx_model(tmp_path):
    pytest.importorskip("onnxruntime")
    from test_models import first_channel_onnx

    model = first_channel_onnx(tmp_path / "net.onnx", [1, 3, 28, 28])
    photo = np.zeros((48, 64, 3), np.float32)
    photo[..., 0] = np.linspace(0.2, 1.0, 48)[:, None]  # "disparity" = red: bottom near
    est = resolve_depth(photo, depth_model=model)
    assert est.kind == "disparity" and est.depth.shape == (48, 64)
    assert est.source.startswith(f"monocular depth model {model} (disparity: assumed")
    assert est.warnings == ("the model's output kind is unknown; disparity assumed "
                            "(pass --depth-kind to change it)",)
    flat = resolve_depth(np.zeros((48, 64, 3)), depth_model=model)
    assert "almost no range" in flat.warnings[-1]
    assert resolve_depth(photo, depth_model=model, kind="depth").kind == "depth"


def test_embedded_depth_is_resized_to_the_photo(tmp_path):
    from test_portrait import expected_depth, write_gdepth_jpeg

    v16 = np.tile(np.linspace(65535, 0, 30).round()[:, None], (1, 40))  # bottom near
    path = tmp_path / "portrait.jpg"
    write_gdepth_jpeg(path, v16, near=0.3, far=4.2, fmt="RangeInverse")  # photo is 60x80
    est = resolve_depth(path)
    assert est.kind == "depth" and est.depth.shape == (60, 80) and est.warnings == ()
    assert est.source == "embedded GDepth depth map (range inverse, near 0.3, far 4.2)"
    small = expected_depth(v16, 0.3, 4.2, "RangeInverse")
    assert est.depth.min() >= small.min() - 1e-5 and est.depth.max() <= small.max() + 1e-5
    kinded = resolve_depth(path, kind="disparity")
    assert "--depth-kind disparity ignored" in kinded.warnings[0]


def test_no_source_and_nothing_embedded(tmp_path):
    # without a fallback model (the default model: tests/depth/test_default_model.py)
    with pytest.raises(InputError) as err:
        resolve_depth(photo_file(tmp_path), fallback_model=None)
    assert str(err.value) == ("no depth given: pass --depth FILE, --right IMAGE or "
                              "--depth-model NAME; photo.png has no embedded depth map")
    with pytest.raises(InputError, match="an image array has no embedded depth map"):
        resolve_depth(np.zeros((8, 8, 3)), fallback_model=None)


def test_sources_exclude_each_other():
    with pytest.raises(InputError, match="give only one depth source, got depth and right"):
        resolve_depth(np.zeros((8, 8, 3)), depth=np.ones((8, 8)), right=np.zeros((8, 8, 3)))
    with pytest.raises(InputError, match="depth kind must be"):
        resolve_depth(np.zeros((8, 8, 3)), depth=np.ones((8, 8)), kind="z")


@pytest.mark.parametrize("kind", ["disparity", "depth"])
def test_export_round_trip_gives_the_pipelines_disparity(tmp_path, kind):
    rng = np.random.default_rng(0)
    raw = floor_disparity() + rng.random((48, 64)).astype(np.float32)
    raw[5:9, 10:20] = np.nan  # unknown: filled like the pipeline does
    if kind == "depth":
        raw = 1.0 / raw
    est = DepthEstimate(raw, kind, "test")
    png, preview = export_depth(est, tmp_path / "depth.png")
    assert preview == tmp_path / "depth_preview.png"
    expected, _, _ = normalize(prepare_depth(raw, raw.shape, kind=kind).disparity)
    back = read_depth(png)
    np.testing.assert_allclose(back / 65535.0, expected, atol=1 / 65535)
    # Fed back as a disparity PNG, the pipeline sees the same normalised disparity.
    again, _, _ = normalize(prepare_depth(back, raw.shape, kind="disparity").disparity)
    np.testing.assert_allclose(again, expected, atol=2 / 65535)
    colours = np.asarray(Image.open(preview))
    assert colours.shape == (48, 64, 3) and colours.dtype == np.uint8
    assert (colours == colorize(back / 65535.0)).all()
    assert (colours[back == 65535] == VIRIDIS[255]).all()  # nearest: yellow


def test_export_refuses_other_extensions(tmp_path):
    with pytest.raises(OutputError, match="must be a .png"):
        export_depth(DepthEstimate(floor_disparity(), "disparity", "t"), tmp_path / "d.jpg")


def test_viridis_is_monotonic_in_lightness():
    lum = VIRIDIS @ np.array([0.2126, 0.7152, 0.0722])
    assert (np.diff(lum[::4]) > 0).all()  # 8-bit rounding makes some neighbours equal
    assert colorize(np.array([[np.nan, 2.0]])).tolist() == [[[68, 1, 84], [253, 231, 37]]]


def test_read_photo_is_the_one_photo_reader(tmp_path):
    from photo3d.depth import sources

    path = photo_file(tmp_path, 8, 12)
    np.testing.assert_array_equal(read_photo(path), read_image(path))
    assert read_photo(np.zeros((8, 12), np.uint8)).shape == (8, 12, 3)
    assert not hasattr(sources, "load_photo")  # photo3d.load reloads 3D photos, not photos
    with pytest.raises(InputError, match="not found"):
        read_photo(tmp_path / "missing.heic")
