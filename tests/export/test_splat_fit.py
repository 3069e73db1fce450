"""Spark's image as a linear operator (photo3d.export.spark_model) and the splat
colours fitted through it (photo3d.export.splat_fit). Spark itself checks both in
test_splats_browser.py."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import exact_config, texture
from scipy.ndimage import gaussian_filter

import photo3d
from photo3d.camera import Camera, Intrinsics
from photo3d.errors import ConfigError
from photo3d.export import export_folder
from photo3d.export.spark_model import (
    MIN_ALPHA,
    spark_quantized,
    spark_weights,
    visible_weights,
)
from photo3d.export.splat_fit import fit_colors, input_view, reference_view
from photo3d.export.splats import build_splats
from photo3d.io.splat_ply import read_splat_ply
from photo3d.resources import export_memory_estimate
from photo3d.save_options import SaveOptions
from photo3d.structures.splats import Splats


@pytest.fixture(scope="module")
def photo():
    """A textured background with detail of a few pixels and a box in front."""
    disp = np.ones((48, 64), np.float32)
    disp[14:34, 20:46] = 2.5
    detail = gaussian_filter(np.random.default_rng(3).normal(size=(48, 64, 3)), (1, 1, 0))
    image = np.clip(texture(48, 64, seed=3) * 0.5 + 0.25 + detail / detail.std() * 0.1, 0, 1)
    return photo3d.make(image.astype(np.float32), depth=disp, config=exact_config(border=6))


def _disc(x, y, z, sigma_px, k, color=0.5, opacity=0.99):
    """One splat facing the camera at pixel (x, y) (its centre), depth z."""
    return Splats(np.array([[(x + 0.5 - k.cx) * z / k.fx, (y + 0.5 - k.cy) * z / k.fy, z]]),
                  np.full((1, 3), color), np.full(1, opacity),
                  np.full((1, 3), sigma_px * z / k.fx), np.array([[1.0, 0, 0, 0]]))


def test_one_splat_weighs_as_spark_draws_it():
    k = Intrinsics.default(16, 16)
    one = spark_quantized(_disc(7, 9, 2.0, 0.6, k), Camera(k, np.eye(4)))
    w = spark_weights(one, Camera(k, np.eye(4)), quantize=False).toarray().reshape(16, 16)
    var = one.scales[0, 0] ** 2 * k.fx**2 / 4  # px² at z = 2
    peak = 0.99 * var / (var + 0.3)  # Spark's 0.3 px² and its opacity compensation
    assert w.argmax() == 9 * 16 + 7
    assert w[9, 7] == pytest.approx(peak, rel=0.03)
    assert w[9, 8] == pytest.approx(peak * np.exp(-0.5 / (var + 0.3)), rel=0.03)
    assert np.count_nonzero(w) < 30 and w.min() >= 0  # cut at sqrt(8) standard deviations


def test_front_splat_hides_the_one_behind_by_its_opacity():
    k = Intrinsics.default(8, 8)
    near, far = _disc(4, 4, 1.0, 3.0, k), _disc(4, 4, 2.0, 3.0, k)
    both = Splats(*(np.concatenate([getattr(far, f), getattr(near, f)]) for f in
                    ("positions", "colors", "opacity", "scales", "rotations")))
    w = spark_weights(both, Camera(k, np.eye(4))).toarray()[4 * 8 + 4]
    a = w[1]  # the near splat, drawn on top whatever its index
    assert w[0] == pytest.approx((1 - a) * a, rel=0.05)  # same footprint, same alpha


def test_visible_weights_are_the_columns_in_blending_order(photo):
    splats = build_splats(photo.ldi)
    camera = Camera(photo.ldi.intrinsics, np.eye(4))
    full = spark_weights(splats, camera)
    part, order = visible_weights(splats, camera)
    assert (full[:, order] != part).nnz == 0
    seen = np.zeros(len(splats), bool)
    seen[order] = True
    assert full[:, ~seen].nnz == 0
    coverage = np.asarray(full.sum(1)).ravel()
    assert coverage.max() <= 1 + 1e-5 and np.mean(coverage > 0.9) > 0.95
    assert full.min() >= 0 and full.data.min() >= 1e-4 > MIN_ALPHA / 100


def test_fit_brings_the_model_closer_to_photo3ds_render(photo):
    splats = build_splats(photo.ldi)
    k = photo.ldi.intrinsics
    camera = Camera(k, np.eye(4))
    color, covered = reference_view(photo.ldi)
    fitted = fit_colors(splats, camera, color, covered)
    for attr in ("positions", "opacity", "scales", "rotations"):
        np.testing.assert_array_equal(getattr(fitted, attr), getattr(splats, attr))
    assert fitted.colors.min() >= 0 and fitted.colors.max() <= 1

    def error(s, cam, reference):
        image = (spark_weights(s, cam) @ spark_quantized(s, cam).colors)
        want, where = reference
        return np.mean((image.reshape(want.shape)[where] - want[where]) ** 2)

    before, after = error(splats, camera, (color, covered)), error(fitted, camera, (color, covered))
    assert after < 0.5 * before
    # a camera the fit never saw gains too (the pull toward the built colours)
    moved = Camera.translated(k, (0.03, -0.02, 0.0))
    other = reference_view(photo.ldi, moved)
    assert error(fitted, moved, other) < error(splats, moved, other)
    # splats the input view does not see (behind others) keep their colours
    part, order = visible_weights(splats, camera)
    hidden = np.setdiff1d(np.arange(len(splats)), order[np.diff(part.indptr) > 0])
    assert len(hidden) > 0.1 * len(splats)
    np.testing.assert_array_equal(fitted.colors[hidden], np.clip(splats.colors[hidden], 0, 1))


def test_export_writes_fitted_splats_by_default(photo, tmp_path):
    folder = photo.save(tmp_path / "out", viewer=False, glb=False)
    export_folder(folder, ["splats.ply", "splats.spz"])  # built once, on the pool
    fitted = read_splat_ply(folder / "splats.ply")
    built = build_splats(photo.ldi)
    np.testing.assert_allclose(fitted.positions, built.positions)
    assert np.abs(fitted.colors - built.colors).max() > 0.05
    expected = build_splats(photo.ldi, fit=True).colors
    np.testing.assert_allclose(fitted.colors, expected, atol=1e-5)
    export_folder(folder, ["splats.ply"], splat_fit=False)  # the colours as built
    np.testing.assert_allclose(read_splat_ply(folder / "splats.ply").colors,
                               np.clip(built.colors, 0, 1), atol=1e-5)


def test_cli_fits_unless_told_not_to(photo, tmp_path):
    from photo3d.cli import main

    folder = photo.save(tmp_path / "out", viewer=False, glb=False)
    built = np.clip(build_splats(photo.ldi).colors, 0, 1)
    assert main(["export", str(folder), "splats.ply", "-q"]) == 0
    assert np.abs(read_splat_ply(folder / "splats.ply").colors - built).max() > 0.05
    assert main(["export", str(folder), "splats.ply", "--splat-fit", "-q"]) == 0
    assert np.abs(read_splat_ply(folder / "splats.ply").colors - built).max() > 0.05
    assert main(["export", str(folder), "splats.ply", "--no-splat-fit", "-q"]) == 0
    np.testing.assert_allclose(read_splat_ply(folder / "splats.ply").colors, built, atol=1e-5)
    assert SaveOptions().splat_fit is True


def test_input_view_is_photo3ds_render_without_rendering(photo):
    color, covered = input_view(photo.ldi)
    want, where = reference_view(photo.ldi)
    assert covered.mean() > 0.99 and where.mean() > 0.99
    both = covered & where
    err = np.mean((color[both] - want[both]) ** 2)
    assert 10 * np.log10(1 / err) > 30  # apart only in the half pixel beyond depth edges
    ldi, own = photo.ldi, photo.ldi.label == 1
    raw = np.zeros_like(color)
    raw[ldi.y[own], ldi.x[own]] = ldi.color[own]
    assert err < 0.5 * np.mean((raw[both] - want[both]) ** 2)  # closer than the photo


def test_the_default_export_states_the_fits_memory(photo, tmp_path, monkeypatch):
    import photo3d.export as export

    checked = []
    monkeypatch.setattr(export, "check_export_memory",
                        lambda pixels, formats, **kw: checked.append(kw["splat_fit"]))
    folder = photo.save(tmp_path / "out", viewer=False, glb=False)
    export_folder(folder, ["splats.spz"])
    export_folder(folder, ["splats.spz"], splat_fit=False)
    assert checked == [True, False]  # bench_export.py: 1084 MB peak, 1864 MB stated


def test_splat_fit_option_is_checked_and_costs_memory():
    with pytest.raises(ConfigError, match="splat_fit"):
        SaveOptions(splat_fit="yes")
    plain = export_memory_estimate(1_000_000, ["splats.spz"], splat_fit=False)
    assert export_memory_estimate(1_000_000, ["splats.spz"], splat_fit=True) > plain
    assert export_memory_estimate(1_000_000, ["quilt"], splat_fit=True) == \
        export_memory_estimate(1_000_000, ["quilt"])


@pytest.mark.parametrize("threads", [1, 2])
def test_a_failed_splat_build_fails_its_files_only(photo, tmp_path, monkeypatch, threads):
    import photo3d.export.splats as splats_module
    from photo3d.export import FORMATS, submit_writers
    from photo3d.parallel import share, thread_pool

    def broken(*args, **kwargs):
        raise ConfigError("no splats today")

    monkeypatch.setattr(splats_module, "build_splats", broken)
    targets = [(FORMATS[name], tmp_path / name) for name in
               ("splats.ply", "quilt", "splats.spz", "mesh.usdz")]
    with share(threads), thread_pool(2) as pool:
        jobs = submit_writers(pool, photo.ldi, targets)
        for job, (fmt, _) in zip(jobs, targets, strict=True):
            if fmt.name.startswith("splats"):
                with pytest.raises(ConfigError, match="no splats today"):
                    job.result(timeout=120)
            else:
                assert job.result(timeout=120) is None
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mesh.usdz", "quilt"]
