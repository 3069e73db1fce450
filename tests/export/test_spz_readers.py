"""splats.spz, versions 3 and 4, and splats.glb read by readers that others wrote, in
headless Chromium: three.js's SPZLoader and PlayCanvas's splat-transform read both
SPZ versions, three.js's glTF loader with its KHR_gaussian_splatting plugin the GLB;
Spark 2 reads version 3 and refuses version 4 (tests/export/spz_readers.py,
spark_renderer.py; skipped when Chromium, playwright or the npm packages are missing).
"""

from __future__ import annotations

import gzip

import numpy as np
import pytest
from conftest import exact_config, texture
from glbfile import write_glb as write_raw_glb
from spark_renderer import chromium, read_splats
from spark_renderer import missing as spark_missing
from spz_readers import missing, read_with

import photo3d
from photo3d.export.splats import build_splats, write_glb, write_spz
from photo3d.structures.splats import SH_C0, Splats

if missing():
    pytest.skip(missing(), allow_module_level=True)

RUB = np.array([1.0, -1.0, -1.0])  # SPZ's axes from the splats' OpenCV ones
COLOR_STEP = SH_C0 / (0.15 * 255)  # SPZ's colour byte


@pytest.fixture(scope="module")
def browser():
    with chromium() as browser:
        yield browser


@pytest.fixture(scope="module")
def photo():
    """A textured wall with a flat, slanted floor: one-pixel splats and joined,
    tilted, anisotropic ones."""
    h, w = 48, 64
    disp = np.ones((h, w), np.float32)
    disp[24:] = np.linspace(1.2, 2.5, h - 24, dtype=np.float32)[:, None]
    image = texture(h, w, seed=3)
    image[24:] = 0.45
    return photo3d.make(image, depth=disp, config=exact_config(border=4))


def step(path) -> float:
    """The fixed-point step of an SPZ file's positions (its ``fractionalBits``)."""
    raw = path.read_bytes()
    header = raw[:16] if raw[:4] == b"NGSP" else gzip.decompress(raw)[:16]
    return 2.0 ** -header[13]


def covariances(splats) -> np.ndarray:
    """``(N, 3, 3)`` covariances of ``splats`` in SPZ's axes."""
    w, x, y, z = splats.rotations.astype(np.float64).T
    r = np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], 1)
    cov = r @ (splats.scales.astype(np.float64)[:, :, None] ** 2 * np.transpose(r, (0, 2, 1)))
    return cov * np.outer(RUB, RUB)


@pytest.mark.parametrize("version", [3, 4])
def test_three_js_reads_the_splats(photo, tmp_path, browser, version):
    splats = build_splats(photo.ldi)
    assert 0.02 < (np.abs(splats.rotations[:, 0]) < 0.999).mean() < 0.9  # some tilted
    write_spz(photo.ldi, tmp_path / "splats.spz", spz_version=version, splats=splats)
    got = read_with("three", tmp_path / "splats.spz", browser)
    assert len(got["position"]) == len(splats)
    half = step(tmp_path / "splats.spz") / 2 + 1e-6
    assert half <= splats.scales.max(axis=1).min() / 2
    np.testing.assert_allclose(got["position"], splats.positions * RUB, atol=half)
    np.testing.assert_allclose(got["color"][:, :3] / 255, np.clip(splats.colors, 0, 1),
                               atol=COLOR_STEP / 2 + 1.5 / 255)
    np.testing.assert_allclose(got["color"][:, 3] / 255, splats.opacity, atol=1 / 255)
    # the covariance three.js builds from SPZ's log scales (steps of 1/16) and
    # rotations: within the scales' rounding, relative to the splat's largest variance
    mine = covariances(splats)
    theirs = got["covariance"][:, [0, 1, 2, 1, 3, 4, 2, 4, 5]].reshape(-1, 3, 3)
    largest = np.abs(mine).reshape(len(mine), -1).max(axis=1)
    error = np.abs(theirs - mine).reshape(len(mine), -1).max(axis=1) / largest
    assert error.max() < 0.15
    # and the comparison can fail: the tilted splats, were they not tilted, would differ
    tilted = np.abs(splats.rotations[:, 0]) < 0.99
    flat = covariances(Splats(splats.positions, splats.colors, splats.opacity,
                              splats.scales, np.tile([1.0, 0, 0, 0], (len(splats), 1))))
    wrong = np.abs(theirs - flat).reshape(len(mine), -1).max(axis=1) / largest
    assert np.median(wrong[tilted]) > 0.3


@pytest.mark.parametrize("version", [3, 4])
def test_playcanvas_splat_transform_reads_the_splats(photo, tmp_path, browser, version):
    splats = build_splats(photo.ldi)
    write_spz(photo.ldi, tmp_path / "splats.spz", spz_version=version, splats=splats)
    got = read_with("playcanvas", tmp_path / "splats.spz", browser)
    centres = np.stack([got["x"], got["y"], got["z"]], 1)
    np.testing.assert_allclose(centres, splats.positions * RUB,
                               atol=step(tmp_path / "splats.spz") / 2 + 1e-6)
    colours = 0.5 + SH_C0 * np.stack([got[f"f_dc_{i}"] for i in range(3)], 1)
    np.testing.assert_allclose(colours, splats.colors, atol=COLOR_STEP / 2 + 1e-5)
    np.testing.assert_allclose(1 / (1 + np.exp(-got["opacity"])), splats.opacity,
                               atol=1 / 255)
    scales = np.exp(np.stack([got[f"scale_{i}"] for i in range(3)], 1))
    np.testing.assert_allclose(np.log(scales), np.log(splats.scales), atol=1 / 32 + 1e-5)
    q = np.stack([got[f"rot_{i}"] for i in range(4)], 1)  # w x y z, SPZ's axes
    mine = splats.rotations * np.array([1, 1, -1, -1])
    assert np.abs((q / np.linalg.norm(q, axis=1, keepdims=True) * mine).sum(1)).min() > 0.999


@pytest.mark.skipif(spark_missing() is not None, reason="needs Spark")
def test_spark_reads_version_3_and_refuses_version_4(photo, tmp_path, browser):
    splats = build_splats(photo.ldi)
    write_spz(photo.ldi, tmp_path / "v3.spz", splats=splats)  # the default: 3
    assert len(read_splats(tmp_path / "v3.spz", browser=browser)) == len(splats)
    write_spz(photo.ldi, tmp_path / "v4.spz", spz_version=4, splats=splats)
    with pytest.raises(AssertionError, match="Spark failed"):
        read_splats(tmp_path / "v4.spz", browser=browser)


def test_three_js_reads_the_glb_by_the_ratified_extension(photo, tmp_path, browser):
    """three.js's plugin follows KHR_gaussian_splatting as ratified: it refuses a
    primitive without ``kernel`` or ``colorSpace`` and reads the extension's
    attribute names."""
    splats = build_splats(photo.ldi)
    write_glb(photo.ldi, tmp_path / "splats.glb", splats=splats)
    got = read_with("three_glb", tmp_path / "splats.glb", browser)
    np.testing.assert_allclose(got["position"], splats.positions * RUB, atol=1e-6)
    np.testing.assert_allclose(got["color"][:, 3] / 255, splats.opacity, atol=1 / 255)
    np.testing.assert_allclose(got["color"][:, :3] / 255, np.clip(splats.colors, 0, 1),
                               atol=1.5 / 255)
    mine = covariances(splats)
    theirs = got["covariance"][:, [0, 1, 2, 1, 3, 4, 2, 4, 5]].reshape(-1, 3, 3)
    largest = np.abs(mine).reshape(len(mine), -1).max(axis=1)
    assert (np.abs(theirs - mine).reshape(len(mine), -1).max(axis=1) / largest).max() < 1e-3
    # without the required colorSpace the plugin refuses the file
    from photo3d.io.glb import read_chunks

    document, binary = read_chunks(tmp_path / "splats.glb")
    del document["meshes"][0]["primitives"][0]["extensions"]["KHR_gaussian_splatting"][
        "colorSpace"]
    write_raw_glb(tmp_path / "bad.glb", document, binary)
    with pytest.raises(AssertionError, match="colorSpace is required"):
        read_with("three_glb", tmp_path / "bad.glb", browser)
