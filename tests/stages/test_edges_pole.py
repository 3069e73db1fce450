"""Issue 44, item 5: a 2 px spread depth map around a thin pole. A test of behaviour
only (no import of the alignment module), so that it also runs on the code before it:
on commit e951c93 it fails (the pole's layer carries 3 px of wall on each side)."""

import numpy as np
import pytest

import photo3d
from photo3d.config import Config

POLE = np.array([0.9, 0.1, 0.9], np.float32)  # magenta
WALL = np.array([0.2, 0.45, 0.8], np.float32)


def pole_scene(width: int, spread: int, h: int = 64, w: int = 96):
    """A vertical pole ``width`` px wide in front of a textured wall; the depth map's
    pole is ``spread`` px wider on each side (onto the far side). Returns ``(image (h,
    w, 3) float32, disparity (h, w) float32, the pole's columns)``."""
    from scipy import ndimage

    rng = np.random.default_rng(0)
    blobs = ndimage.gaussian_filter(rng.normal(0, 1, (h, w, 3)), (3, 3, 0))
    img = np.clip(WALL + 0.08 * blobs / blobs.std() + rng.normal(0, 0.02, (h, w, 3)), 0, 1)
    img = img.astype(np.float32)
    c = w // 2
    img[:, c:c + width] = POLE
    disp = np.full((h, w), 0.2, np.float32)
    disp[:, c - spread:c + width + spread] = 1.0
    return img, disp, slice(c, c + width)


def pole_coloured(colors: np.ndarray) -> np.ndarray:
    """``(N,) bool`` of ``colors (N, 3)``: within 0.3 of the pole's colour."""
    return np.abs(colors - POLE).max(axis=1) < 0.3


@pytest.mark.parametrize("width", [2, 4])
def test_a_spread_pole_leaves_no_pole_colour_behind_and_takes_no_wall_with_it(width):
    """No pole-coloured pixel on the background layer, and the pole's layer holds the
    pole's photo pixels and at most ``grow_foreground`` px of wall on each side (before:
    the depth map's 2 px spread plus that), those mostly transparent or wall-coloured."""
    img, disp, _ = pole_scene(width, spread=2)
    config = Config(size=None)
    ldi = photo3d.make(img, depth=disp, config=config).ldi
    near = ldi.disparity > 0.5 * (ldi.disparity.max() + ldi.disparity.min())
    original = ldi.label == 1
    assert not (~near & pole_coloured(ldi.color)).any()
    grow = round(config.preprocess.grow_foreground)
    assert (near & original).sum() == (width + 2 * grow) * img.shape[0]
    solid = near & original & (ldi.alpha > 0.5)  # soft silhouettes: the grown pixels show
    assert (solid & pole_coloured(ldi.color)).sum() == width * img.shape[0]  # no more than that
