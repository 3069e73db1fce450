"""Tests of photo3d.sample: the bundled Middlebury motorcycle pair."""

from __future__ import annotations

import dataclasses
import sys

import numpy as np
import pytest

from photo3d.errors import InputError
from photo3d.sample import StereoSample, motorcycle


@pytest.fixture(scope="module")
def sample() -> StereoSample:
    return motorcycle()


def test_shapes_and_dtypes(sample):
    assert sample.left.shape == (500, 741, 3)
    assert sample.right.shape == (500, 741, 3)
    assert sample.disparity.shape == (500, 741)
    assert sample.left.dtype == sample.right.dtype == sample.disparity.dtype == np.float32


def test_images_are_in_unit_range_and_differ(sample):
    for image in (sample.left, sample.right):
        assert image.min() >= 0.0 and image.max() <= 1.0
        assert image.max() > 0.9  # scaled by 1/255, not left in 0..255 or squashed
    assert np.abs(sample.left - sample.right).mean() > 0.01


def test_disparity_is_raw_pixels_with_inf_where_unknown(sample):
    disparity = sample.disparity
    unknown = np.isposinf(disparity)
    assert unknown.any()
    assert not np.isnan(disparity).any()
    known = disparity[~unknown]
    assert known.min() > 5.0 and known.max() < 70.0  # pixels, not normalised


def test_disparity_maps_left_pixels_onto_the_right_view(sample):
    """left[y, x] matches right[y, x - d]: the warp must beat doing nothing by far."""
    ys, xs = np.nonzero(np.isfinite(sample.disparity))
    target = np.rint(xs - sample.disparity[ys, xs]).astype(int)
    inside = target >= 0
    ys, xs, target = ys[inside], xs[inside], target[inside]
    warped_error = np.abs(sample.left[ys, xs] - sample.right[ys, target]).mean()
    unwarped_error = np.abs(sample.left[ys, xs] - sample.right[ys, xs]).mean()
    assert warped_error < 0.5 * unwarped_error


def test_calibration_from_scikit_image_docstring(sample):
    assert sample.focal == 994.978
    assert sample.cx == 311.193
    assert sample.cy == 254.877
    assert sample.doffs == 31.086
    assert sample.baseline == 193.001


def test_sample_is_frozen(sample):
    with pytest.raises(dataclasses.FrozenInstanceError):
        sample.focal = 1.0


def test_missing_scikit_image_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "skimage", None)
    with pytest.raises(
        InputError,
        match=r"^the bundled sample needs scikit-image: pip install 'photo3d\[sample\]'$",
    ):
        motorcycle()


def test_the_files_read_directly_are_scikit_images_arrays():
    import skimage
    from skimage.data import stereo_motorcycle

    from photo3d.sample import _bundled_files

    files = _bundled_files(skimage)
    assert files is not None
    for ours, theirs in zip(files, stereo_motorcycle(), strict=True):
        assert ours.dtype == theirs.dtype and ours.shape == theirs.shape
        assert ours.tobytes() == theirs.tobytes()


def test_loading_does_not_import_skimage_io():
    import subprocess

    code = ("import sys; from photo3d.sample import motorcycle; motorcycle(); "
            "print('skimage.io' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"
