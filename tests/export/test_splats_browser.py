"""splats.ply and splats.spz in a real Gaussian splat renderer: Spark on three.js in
headless Chromium (tests/export/spark_renderer.py; skipped when Chromium, playwright or
the npm packages are missing)."""

from __future__ import annotations

import gzip

import numpy as np
import pytest
from conftest import exact_config, texture
from scipy.ndimage import gaussian_filter
from spark_renderer import chromium, missing, read_splats, render_views, widest_circle_camera

import photo3d
from photo3d.camera import Camera
from photo3d.export.spark_model import spark_quantized, spark_weights
from photo3d.export.splats import build_splats, write_ply, write_spz
from photo3d.render.renderer import Renderer, RenderSettings

if missing():
    pytest.skip(missing(), allow_module_level=True)


def psnr(a, b) -> float:
    return float(10 * np.log10(1.0 / np.mean((a - b) ** 2)))


def reference(photo, cameras):
    """photo3d's own renders (mesh, no hole filling): colour and covered pixels."""
    with Renderer(photo.mesh(), RenderSettings(fill_holes=False, backend="numba")) as r:
        views = [r.render(c) for c in cameras]
    return [(v.color, v.mask) for v in views]


@pytest.fixture(scope="module")
def browser():
    with chromium() as browser:
        yield browser


def check_views(photo, tmp_path, browser=None, *, density="adaptive", fit=False):
    """Spark's views of splats.ply (``fit``: colours fitted, photo3d.export.splat_fit)
    from the input camera and the circle path's widest one against photo3d's: returns
    (PSNR input, PSNR widest, empty fraction widest)."""
    write_ply(photo.ldi, tmp_path / "splats.ply", density=density, fit=fit)
    k = photo.ldi.intrinsics
    cameras = [Camera(k, np.eye(4)), widest_circle_camera(k)]
    got = render_views(tmp_path / "splats.ply", cameras, browser=browser)
    want = reference(photo, cameras + [Camera.translated(k, (0.05, 0.03, 0.0))])
    results = []
    for (color, covered), rgba in zip(want[:2], got, strict=True):
        assert covered.mean() > 0.9
        results.append(psnr(rgba[..., :3][covered], color[covered]))  # over black
    empty = float(np.mean(got[1][..., 3][want[1][1]] < 0.5))
    # the comparison can fail: the input view is far from another camera's render
    other, covered = want[2]
    assert psnr(got[0][..., :3][covered], other[covered]) < results[0] - 3
    return results[0], results[1], empty


@pytest.fixture(scope="module")
def box_photo():
    """128 x 96 textured background (detail of a few pixels, as in photos) with a box
    in front; inpainted layers behind the box (what the circle path reveals) and a
    16 px border."""
    disp = np.ones((96, 128), np.float32)
    disp[28:70, 40:90] = 2.5
    rng = np.random.default_rng(11)
    detail = gaussian_filter(rng.normal(size=(96, 128, 3)), (2, 2, 0))
    image = np.clip(texture(96, 128, seed=11) * 0.5 + 0.25 + detail / detail.std() * 0.08,
                    0, 1).astype(np.float32)
    return photo3d.make(image, depth=disp, config=exact_config(border=16))


@pytest.mark.parametrize("density", ["adaptive", "dense"])
def test_spark_renders_the_splats_as_photo3d_renders_the_photo(box_photo, tmp_path, browser,
                                                               density):
    p_input, p_widest, empty = check_views(box_photo, tmp_path, browser, density=density)
    print(f"{density}: input {p_input:.2f} dB, widest {p_widest:.2f} dB, "  # noqa: T201
          f"{100 * empty:.3f} % empty")
    assert p_input >= 25 and p_widest >= 25
    assert empty <= 0.01  # what the camera reveals is filled by the inpainted splats
    if density == "dense":
        return
    # without the inpainted layers the widest camera sees holes behind the box
    ldi = box_photo.ldi
    front = np.flatnonzero(np.isin(ldi.label, [1, 5]))
    keep = np.full(ldi.size, -1)
    keep[front] = np.arange(len(front))
    links = np.where(ldi.links >= 0, keep[np.maximum(ldi.links, 0)], -1)[front]
    from dataclasses import replace

    bare = photo3d.Photo3D(replace(ldi, y=ldi.y[front], x=ldi.x[front],
                                   color=ldi.color[front], disparity=ldi.disparity[front],
                                   links=links.astype(np.int32), label=ldi.label[front],
                                   alpha=ldi.alpha[front]),
                           box_photo.config)
    write_ply(bare.ldi, tmp_path / "bare.ply", density=density)
    k = ldi.intrinsics
    widest = render_views(tmp_path / "bare.ply", [widest_circle_camera(k)], browser=browser)[0]
    covered = reference(box_photo, [widest_circle_camera(k)])[0][1]
    assert np.mean(widest[..., 3][covered] < 0.5) > 5 * max(empty, 0.002)


@pytest.mark.parametrize("density", ["adaptive", "dense"])
def test_spark_model_reproduces_sparks_image(box_photo, tmp_path, browser, density):
    """photo3d.export.spark_model's weights times the colours give Spark's own image,
    from the input camera and a moved one, within Spark's 8-bit blending."""
    splats = build_splats(box_photo.ldi, density=density)
    write_ply(box_photo.ldi, tmp_path / "splats.ply", splats=splats)
    k = box_photo.ldi.intrinsics
    cameras = [Camera(k, np.eye(4)), widest_circle_camera(k)]
    got = render_views(tmp_path / "splats.ply", cameras, browser=browser)
    for camera, rgba in zip(cameras, got, strict=True):
        weights = spark_weights(splats, camera)
        image = (weights @ spark_quantized(splats, camera).colors).reshape(rgba[..., :3].shape)
        coverage = np.asarray(weights.sum(1)).reshape(rgba.shape[:2])
        assert psnr(image, rgba[..., :3]) >= 45 and psnr(coverage, rgba[..., 3]) >= 45
        # the comparison can fail: the splats a pixel to the right are far off
        assert psnr(np.roll(image, 1, axis=1), rgba[..., :3]) < 40


@pytest.mark.parametrize("density", ["adaptive", "dense"])
def test_fitted_colours_bring_spark_closer_to_photo3d(box_photo, tmp_path, browser, density):
    built = check_views(box_photo, tmp_path, browser, density=density)
    fitted = check_views(box_photo, tmp_path, browser, density=density, fit=True)
    print(f"{density}, fitted: input {fitted[0]:.2f} dB (built {built[0]:.2f}), "  # noqa: T201
          f"widest {fitted[1]:.2f} dB (built {built[1]:.2f}), {100 * fitted[2]:.3f} % empty")
    assert fitted[0] >= built[0] + 3  # the fitted camera
    assert fitted[1] >= built[1] + 1  # a camera the fit did not see
    assert fitted[2] == built[2]  # the fit moves no splat


def test_spz_read_back_by_spark_equals_the_ply_within_quantization(box_photo, tmp_path,
                                                                   browser):
    splats = build_splats(box_photo.ldi, density="dense")
    write_ply(box_photo.ldi, tmp_path / "splats.ply", splats=splats)
    write_spz(box_photo.ldi, tmp_path / "splats.spz", splats=splats)  # version 3
    ply = read_splats(tmp_path / "splats.ply", browser=browser)
    spz = read_splats(tmp_path / "splats.spz", browser=browser)
    assert len(ply) == len(spz) == len(splats)
    # SPZ is right-up-back: Spark reads it so; the PLY keeps OpenCV axes
    centres = spz[:, :3] * [1, -1, -1]
    with gzip.open(tmp_path / "splats.spz") as file:  # the step photo3d.io.spz chose
        bits = file.read(16)[13]
    assert 2.0**-bits <= splats.scales.max(axis=1).min()
    # Spark keeps centres as float16: its own rounding is added to SPZ's step
    half16 = np.abs(splats.positions) * 2.0**-11 + 2.0**-25
    assert (np.abs(centres - splats.positions) <= 2.0**-bits / 2 + half16 + 1e-7).all()
    assert (np.abs(ply[:, :3] - splats.positions) <= half16 + 1e-7).all()
    # colour: SPZ's step is SH_C0 / (0.15 * 255) = 0.0074; Spark stores 8 bits
    assert np.abs(spz[:, 11:] - ply[:, 11:]).max() <= 0.0074 / 2 + 1 / 255 + 1e-6
    assert np.abs(spz[:, 10] - ply[:, 10]).max() <= 1 / 255 + 1e-6  # opacity
    # scales: SPZ steps log(scale) by 1/16; Spark stores it in 8 bits over [-12, 9]
    assert np.abs(np.log(spz[:, 3:6] / ply[:, 3:6])).max() <= 1 / 32 + 21 / 255 + 1e-6
    # rotations: identity, SPZ v3 keeps the smallest three in steps of sqrt(1/2) / 511
    assert np.abs(spz[:, 6:10] - ply[:, 6:10]).max() <= np.sqrt(0.5) / 511 + 1e-6
    # and they are not all alike (the comparison can fail)
    assert np.abs(centres - centres[::-1]).max() > 0.1


@pytest.mark.slow
def test_bundled_sample_in_spark(tmp_path, browser):
    """The issue's proof on the bundled sample (``photo3d demo``'s 1024 px 3D photo),
    dense (1,453,295 splats) and adaptive, each as built and with its colours fitted
    (the default; ``--no-splat-fit`` keeps them as built): about five minutes in
    SwiftShader (``pytest -m slow -s`` prints the numbers). Issue 46's target (30 dB
    from the input camera, 28 dB and at most 0.5 % empty from the circle path's
    widest) is met with the fit only."""
    from photo3d.sample import motorcycle

    sample = motorcycle()
    photo = photo3d.make(sample.left, depth=np.asarray(sample.disparity))
    found = {}
    for density in ("dense", "adaptive"):
        for fit in (False, True):
            found[density, fit] = check_views(photo, tmp_path, browser, density=density,
                                              fit=fit)
            p_input, p_widest, empty = found[density, fit]
            print(f"bundled sample, {density}{', fitted' if fit else ''} "  # noqa: T201
                  f"({len(build_splats(photo.ldi, density=density)):,} splats): input "
                  f"{p_input:.2f} dB, widest {p_widest:.2f} dB, {100 * empty:.3f} % empty")
    for (density, fit), (p_input, p_widest, empty) in found.items():
        assert empty <= 0.005, density
        if fit:
            assert p_input >= 30 and p_widest >= 28, density
        else:
            assert p_input >= 27 and p_widest >= 26, density
    assert len(build_splats(photo.ldi)) <= 500_000
    write_spz(photo.ldi, tmp_path / "splats.spz")  # the default: fitted
    assert (tmp_path / "splats.spz").stat().st_size <= 4_000_000
