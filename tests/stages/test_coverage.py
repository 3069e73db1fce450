"""Depth steps moved to where the photo's coverage crosses one half (issue 44)."""

from __future__ import annotations

import numpy as np
import pytest

from photo3d.config import Config, PreprocessConfig
from photo3d.stages.coverage import snap_to_coverage
from photo3d.stages.preprocess import preprocess

THRESHOLD = 0.04


def _pole(width: int, mixed: float, fat: int, *, size: int = 40):
    """A white pole ``width`` px wide on a dark textured wall, a column of ``mixed``
    coverage on each side, and a disparity map ``fat`` px wider than the pole on each
    side: ``(image, disparity, pole columns)``."""
    rng = np.random.default_rng(0)
    image = np.empty((size, size, 3), np.float32)
    image[:] = rng.uniform(0.05, 0.2, (size, size, 1))  # a grey wall with some texture
    x0 = size // 2 - width // 2
    cols = np.arange(x0, x0 + width)
    image[:, cols] = 0.95
    for c in (x0 - 1, x0 + width):  # the mixed pixels on either side
        image[:, c] = mixed * 0.95 + (1 - mixed) * image[:, c]
    disparity = np.full((size, size), 0.2, np.float32)
    disparity[:, x0 - fat:x0 + width + fat] = 0.8
    return image, disparity, cols


def test_a_mostly_background_pixel_goes_to_the_far_side():
    image, disparity, cols = _pole(6, 0.25, 3)
    out = snap_to_coverage(image, disparity, threshold=THRESHOLD, radius=3)
    near = np.flatnonzero(out[20] > 0.5)
    np.testing.assert_array_equal(near, cols)  # the 25 % columns and beyond: far


def test_a_mostly_foreground_pixel_stays_near():
    image, disparity, cols = _pole(6, 0.75, 3)
    out = snap_to_coverage(image, disparity, threshold=THRESHOLD, radius=3)
    near = np.flatnonzero(out[20] > 0.5)
    np.testing.assert_array_equal(near, np.arange(cols[0] - 1, cols[-1] + 2))


@pytest.mark.parametrize("width", [1, 2])
def test_a_wire_without_inner_pixels_keeps_its_depth(width):
    """No pixel of a 1 or 2 px wire lies a step inside it: no foreground sample, no
    coverage, no move (the alignment keeps wires; so does this)."""
    image, disparity, _ = _pole(width, 0.0, 0)
    out = snap_to_coverage(image, disparity, threshold=THRESHOLD, radius=3)
    np.testing.assert_array_equal(out, disparity)


def test_alike_sides_and_no_steps_change_nothing():
    image = np.full((16, 16, 3), 0.5, np.float32)
    disparity = np.zeros((16, 16), np.float32)
    disparity[:, 8:] = 1.0
    np.testing.assert_array_equal(
        snap_to_coverage(image, disparity, threshold=THRESHOLD), disparity)
    flat = np.full((16, 16), 0.3, np.float32)
    np.testing.assert_array_equal(snap_to_coverage(image, flat, threshold=THRESHOLD), flat)
    image, disparity, _ = _pole(6, 0.25, 3)
    np.testing.assert_array_equal(
        snap_to_coverage(image, disparity, threshold=THRESHOLD, passes=0), disparity)


def _near_columns(config: Config, fat: int) -> np.ndarray:
    image, disparity, _ = _pole(6, 0.25, fat, size=64)
    out = preprocess(image, disparity, config=config)
    return np.flatnonzero(out.disparity[32] > 0.5)


def test_preprocess_cuts_fat_depth_where_exact_depth_is_cut():
    """With depth 2 px fat, the near side after ``preprocess`` is where exact depth
    puts it (the pole and, grown by ``grow_foreground``, its mixed pixels); without
    the coverage (the alignment alone) one background column more stays near."""
    config = Config(size=None)
    exact = _near_columns(config, 0)
    np.testing.assert_array_equal(_near_columns(config, 2), exact)
    off = config.with_(preprocess=PreprocessConfig(coverage_passes=0))
    assert _near_columns(off, 2).size > exact.size
