"""Pixels no triangle covers: filled from the farther side first."""

import numpy as np
import pytest

from photo3d.errors import ConfigError
from photo3d.render._resolve import grow_fill, grow_fill_far
from photo3d.render.renderer import RenderSettings


def _gap(width=10):
    """A row image: near red on the left, a gap of ``width`` px, far blue on the right."""
    h, w = 12, 30
    color = np.zeros((h, w, 3), np.float32)
    coverage = np.ones((h, w), np.float32)
    depth = np.full((h, w), np.inf, np.float32)
    color[:, :10] = (1, 0, 0)
    depth[:, :10] = 1.0
    color[:, 10 + width:] = (0, 0, 1)
    depth[:, 10 + width:] = 3.0
    coverage[:, 10:10 + width] = 0.0
    color[:, 10:10 + width] = 0.0
    return color, coverage, depth


def test_a_gap_takes_the_far_side():
    color, coverage, depth = _gap()
    assert grow_fill_far(color, coverage, depth, 32, 0.05) == 0
    np.testing.assert_allclose(color[:, 10:20], np.broadcast_to((0, 0, 1), (12, 10, 3)))
    # both sides alike: the near half turns red
    color, coverage, depth = _gap()
    assert grow_fill(color, coverage, 8) == 0
    assert color[:, 10:13, 0].min() > 0.9


def test_only_near_surroundings_still_fill_and_far_rings_stop():
    color, coverage, depth = _gap()
    depth[:, 20:] = 0.5                    # the right side is now the nearer one
    grow_fill_far(color, coverage, depth, 32, 0.05)
    assert color[:, 10:20, 0].min() > 0.99          # red is the farther side
    color, coverage, depth = _gap(width=18)
    assert grow_fill_far(color, coverage, depth, 4, 0.05) == 12 * 10  # 18 px gap, 4 rings
    assert np.all(color[:, 24:28, 2] == 1.0) and np.all(color[:, 10:14, 0] == 1.0)
    assert np.all(color[:, 14:24] == 0.0)  # left to the pyramid fill


def test_partly_covered_pixels_keep_their_share():
    color, coverage, depth = _gap(width=1)
    coverage[:, 10] = 0.5
    color[:, 10] = (0, 1, 0)
    grow_fill_far(color, coverage, depth, 32, 0.05)
    np.testing.assert_allclose(color[:, 10], np.broadcast_to((0, 0.5, 0.5), (12, 3)))


def test_unknown_mode_is_refused():
    with pytest.raises(ConfigError, match="hole_fill"):
        RenderSettings(hole_fill="nearest")
