"""The near side of each depth edge grows into the far side (mixed contour pixels)."""

import numpy as np
import pytest

import photo3d
from photo3d.camera import Camera
from photo3d.config import Config, PreprocessConfig, RegionConfig
from photo3d.render.renderer import RenderSettings
from photo3d.stages.preprocess import grow_foreground, preprocess


def test_a_step_moves_into_the_far_side_by_the_given_steps():
    d = np.zeros((6, 12), np.float32)
    d[:, :5] = 1.0            # near on the left
    d[2:4, 8:] = 0.5          # a middle step on the right
    out = grow_foreground(d, 2, 0.04)
    # 4-connected growth: two steps reach two pixels right, down and diagonally one+one
    np.testing.assert_array_equal(out[2], [1, 1, 1, 1, 1, 1, 1, .5, .5, .5, .5, .5])
    np.testing.assert_array_equal(out[0], [1, 1, 1, 1, 1, 1, 1, 0, .5, .5, .5, .5])
    assert out[1, 7] == 0.5 and np.all(out[:, 5:7] == 1.0)
    np.testing.assert_array_equal(grow_foreground(d, 0, 0.04), d)


def test_slopes_below_the_threshold_are_untouched():
    ramp = np.tile(np.linspace(0, 1, 60, dtype=np.float32), (8, 1))   # 0.017 per pixel
    np.testing.assert_array_equal(grow_foreground(ramp, 3, 0.04), ramp)


def test_preprocess_grows_by_photo_pixels():
    """The width is in pixels of the input photo: a photo enlarged 4x grows 4 px."""
    d = np.zeros((16, 32), np.float32)
    d[:, :16] = 1.0
    img = np.zeros((16, 32, 3), np.float32)
    grow = PreprocessConfig(grow_foreground=1.0, filter_windows=())
    for size, expected in ((None, 17), (128, 68)):
        pre = preprocess(img, d, config=Config(size=size, preprocess=grow))
        assert int((pre.disparity[0] > 0.5).sum()) == expected
    off = PreprocessConfig(grow_foreground=0.0, filter_windows=())
    assert int((preprocess(img, d, config=Config(size=None, preprocess=off))
                .disparity[0] > 0.5).sum()) == 16


def _contour_scene():
    """Red near half, blue far half; the far side's first column mixes both colours."""
    img = np.zeros((40, 80, 3), np.float32)
    img[:, :40, 0] = 1.0
    img[:, 40:, 2] = 1.0
    img[:, 40] = (0.5, 0.0, 0.5)
    disp = np.ones((40, 80), np.float32)
    disp[:, :40] = 2.0        # the depth edge puts the mixed column on the far side
    return img, disp


@pytest.mark.parametrize("grow", [0.0, 1.0])
def test_mixed_contour_pixels_move_with_the_object(grow):
    img, disp = _contour_scene()
    config = Config(size=None, spatial_scale=1.0,
                    preprocess=PreprocessConfig(min_edge_length=5, grow_foreground=grow),
                    regions=RegionConfig(synthesis_iterations=16, context_iterations=16,
                                         edge_dilation=0, border=0))
    photo = photo3d.make(img, depth=disp, config=config)
    settings = RenderSettings(ssaa=1, fill_holes=False, backend="numba")
    k = photo.ldi.intrinsics
    # the input view is the photo either way
    np.testing.assert_allclose(photo.render(Camera(k, np.eye(4)), settings=settings).color,
                               img, atol=0.02)
    # moving right reveals background to the right of the red half
    view = photo.render(Camera.translated(k, (0.08, 0.0, 0.0)), settings=settings).color
    red = view[..., 0] > 0.75
    mixed = (view[..., 0] > 0.25) & (view[..., 0] < 0.75) & (view[..., 1] < 0.2)
    revealed = (photo.ldi.label == 2).sum()
    assert revealed > 0
    # a mixed pixel whose left neighbour is not red: a line left behind the object
    stray = mixed[:, 1:] & ~red[:, :-1]
    if grow:
        assert not stray[5:-5].any()
    else:
        assert stray[5:-5].sum(axis=1).min() >= 1   # every row has the fringe
