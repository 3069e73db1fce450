"""Plausibility warnings: inverted maps and maps with almost no range."""

from __future__ import annotations

import numpy as np
import pytest

from photo3d.depth.checks import check_depth, depth_range, inverted_columns
from photo3d.errors import InputError


def ground_plane(h: int = 90, w: int = 120) -> np.ndarray:
    """Disparity of a camera looking at a floor and a far wall: bottom rows near."""
    rows = np.arange(h, dtype=np.float32)[:, None]
    disparity = np.where(rows < h // 3, 0.5, 0.5 + (rows - h // 3) / h * 6)
    rng = np.random.default_rng(0)
    return np.tile(disparity, (1, w)) + rng.normal(0, 0.02, (h, w)).astype(np.float32)


def test_plausible_map_gives_no_warning():
    assert check_depth(ground_plane()) == []


def test_inverted_disparity_suggests_depth_kind():
    depth_given_as_disparity = 1.0 / ground_plane()
    notes = check_depth(depth_given_as_disparity)
    assert len(notes) == 1
    assert notes[0].startswith("depth looks inverted (near is dark): pass --depth-kind depth")


def test_inverted_depth_suggests_disparity_kind():
    # The user said "depth" but the file held disparity: after 1/x it is inverted.
    notes = check_depth(1.0 / ground_plane(), kind="depth")
    assert notes[0].startswith("depth looks inverted (near is bright): pass --depth-kind disparity")


def test_inversion_needs_most_columns():
    d = ground_plane()
    d[:, : d.shape[1] // 2] = 1.0 / d[:, : d.shape[1] // 2]  # half the columns inverted
    assert inverted_columns(d) == pytest.approx(0.5, abs=0.02)
    assert check_depth(d) == []


def test_constant_plus_noise_is_flat():
    rng = np.random.default_rng(1)
    d = 5.0 + rng.normal(0, 0.02, (60, 80))
    assert depth_range(d) < 0.05
    assert check_depth(d) == ["depth has almost no range: the 3D photo will look flat"]


def test_all_zero_is_flat_not_an_error():
    assert check_depth(np.zeros((10, 10))) == [
        "depth has almost no range: the 3D photo will look flat"]


def test_a_small_object_does_not_hide_the_range():
    d = np.ones((50, 50))
    d[20:30, 20:30] = 4.0  # 4 % of pixels: inside the 1-99 percentiles
    assert depth_range(d) == pytest.approx(0.75)


def test_shape_checks():
    with pytest.raises(InputError, match=r"disparity has shape \(4, 4\) but image is \(5, 4, 3\)"):
        check_depth(np.ones((4, 4)), np.zeros((5, 4, 3)))
    with pytest.raises(InputError, match="expected"):
        check_depth(np.ones((4, 4, 2)))
