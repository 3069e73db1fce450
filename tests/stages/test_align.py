"""Depth edges moved onto the photo's colour edges (issue 44, ``edges="align"``)."""

import json

import numpy as np
import pytest
from test_edges_pole import pole_scene

import photo3d
from photo3d.config import Config, PreprocessConfig
from photo3d.errors import ConfigError
from photo3d.stages.align import align_edges
from photo3d.stages.preprocess import preprocess

SKY = np.array([0.2, 0.45, 0.8], np.float32)


def _textured(h: int, w: int, seed: int = 0) -> np.ndarray:
    """A blue background with photo-like texture (smooth blobs plus noise)."""
    from scipy import ndimage

    rng = np.random.default_rng(seed)
    blobs = ndimage.gaussian_filter(rng.normal(0, 1, (h, w, 3)), (3, 3, 0))
    img = SKY + 0.08 * blobs / blobs.std() + rng.normal(0, 0.02, (h, w, 3))
    return np.clip(img, 0, 1).astype(np.float32)


def test_exact_edges_keep_the_depth_maps_steps():
    img, disp, _ = pole_scene(4, spread=2)
    ldi = photo3d.make(img, depth=disp, config=Config(size=None, edges="exact")).ldi
    near = (ldi.disparity > 0.5 * (ldi.disparity.max() + ldi.disparity.min())) & (ldi.label == 1)
    assert near.sum() > 4 * img.shape[0]  # the spread band stays on the pole's layer


@pytest.mark.parametrize("spread", [1, 2, 3])
def test_a_fat_step_moves_onto_the_colour_edge(spread):
    img, disp, cols = pole_scene(10, spread=spread)
    out = align_edges(img, disp, radius=4, iterations=4)
    expected = np.full(disp.shape, 0.2, np.float32)
    expected[:, cols] = 1.0
    wrong = int((out != expected).sum())
    if spread < 3:
        assert wrong == 0
    else:  # 3 px each side with a 4 px window: a few pixels stay (measured: 58 of 384)
        assert wrong < 0.2 * int((disp != expected).sum())


def test_a_shrunk_step_grows_back_onto_the_colour_edge():
    img, disp, cols = pole_scene(10, spread=0)
    disp[:, cols.start:cols.start + 2] = 0.2  # the depth map misses 2 px of the pole
    out = align_edges(img, disp, radius=4, iterations=4)
    assert np.all(out[:, cols] == 1.0) and (out > 0.5).sum() == 10 * img.shape[0]


def test_a_two_pixel_wire_stays_a_wire():
    """A dark 2 px wire across a textured wall with exact or 3 px fat depth."""
    h, w = 60, 90
    img = _textured(h, w, seed=1)
    yy, xx = np.mgrid[0:h, 0:w]
    line = np.abs(yy - (20 + 0.3 * xx)) < 1.0  # slanted, 2 px thick
    img[line] = 0.05
    from scipy import ndimage

    for fat in (0, 1, 2, 3):
        depth_line = ndimage.binary_dilation(line, iterations=fat) if fat else line
        disp = np.where(depth_line, 1.0, 0.2).astype(np.float32)
        near = align_edges(img, disp, radius=4, iterations=4) > 0.5
        assert not (line & ~near).any(), fat  # the whole wire is still there
        assert (near & ~line).sum() <= 2, fat  # and its fat is gone


def test_smooth_slopes_and_flat_maps_are_untouched():
    img = _textured(32, 48)
    ramp = np.tile(np.linspace(0, 1, 48, dtype=np.float32), (32, 1))  # 0.021 per pixel
    np.testing.assert_array_equal(align_edges(img, ramp), ramp)
    flat = np.full((32, 48), 0.5, np.float32)
    np.testing.assert_array_equal(align_edges(img, flat), flat)


def test_a_flat_photo_leaves_the_map_as_it_is():
    """No colour edge to follow: noise depth over a uniform photo is not smoothed (the
    held-out benchmark's region shapes come from depth alone, with a flat photo)."""
    noise = np.random.default_rng(0).random((40, 40)).astype(np.float32)
    np.testing.assert_array_equal(align_edges(np.zeros((40, 40, 3), np.float32), noise), noise)


def _joint_medians(disp, image, radius, sigma_c, threshold):
    """The colour-weighted median of every pixel's window (the definition in
    :mod:`photo3d.stages.align`, in plain Python): ``(H, W) float32``."""
    from photo3d.stages.align import _offsets

    dys, dxs, parents = _offsets(radius)
    h, w = disp.shape
    out = disp.copy()
    for y in range(h):
        for x in range(w):
            seen, vals, wts, contrast = {}, [], [], 0.0
            for i, (dy, dx, p) in enumerate(zip(dys, dxs, parents, strict=True)):
                if not (0 <= y + dy < h and 0 <= x + dx < w):
                    seen[i] = np.inf
                    continue
                diff = image[y + dy, x + dx] - image[y, x]
                c2 = max(float(np.dot(diff, diff)), seen[p] if p >= 0 else 0.0)
                seen[i], contrast = c2, max(contrast, c2)
                e = (dy * dy + dx * dx) / (2.0 * radius**2) + c2 / (2.0 * sigma_c**2)
                if e <= 16.0:
                    vals.append(disp[y + dy, x + dx])
                    wts.append(np.float32(np.exp(-e)))
            if sum(wts) < 1e-12 or contrast < (2 * sigma_c) ** 2:
                continue
            order = np.argsort(vals, kind="stable")
            reach = np.cumsum(np.array(wts, np.float64)[order]) >= 0.5 * sum(wts)
            out[y, x] = np.array(vals)[order][np.argmax(reach)]
    return out


@pytest.mark.parametrize("seed", range(6))
def test_the_kernel_moves_the_pixels_the_median_moves(seed):
    """The kernel seeks the median only where it can move the pixel across a step
    (and leaves a window early once it cannot): the same moves as the definition, on
    few colours and disparities at threshold multiples (+-1e-7, exactly on the edge)."""
    from photo3d.stages.align import _joint_median_at, _offsets

    rng = np.random.default_rng(seed)
    radius, threshold, sigma_c = 2 + seed % 2, 0.04, 0.1
    palette = (np.array([[0.1, 0.2, 0.3], [0.4, 0.3, 0.2], [0.2, 0.5, 0.4]])
               + rng.uniform(-0.05, 0.05, (3, 3))).astype(np.float32)
    image = np.ascontiguousarray(palette[rng.integers(0, 3, (14, 14))])
    disp = (rng.integers(0, 4, (14, 14)) * threshold
            + rng.choice([0.0, 1e-7, -1e-7, 1e-3], (14, 14))).astype(np.float32)
    ys, xs = (a.astype(np.int64).ravel() for a in np.indices(disp.shape))
    out = np.empty(ys.size, np.float32)
    _joint_median_at(disp, image, ys, xs, *_offsets(radius), float(radius), sigma_c,
                     2 * sigma_c, threshold, out)
    expected = _joint_medians(disp, image, radius, sigma_c, threshold).ravel()
    moves = np.abs(expected - disp.ravel()) > threshold
    assert moves.sum() > 10
    np.testing.assert_array_equal(np.abs(out - disp.ravel()) > threshold, moves)
    np.testing.assert_array_equal(out[moves], expected[moves])


def test_shapes_must_agree():
    with pytest.raises(ValueError, match="disparity has shape"):
        align_edges(np.zeros((4, 5, 3), np.float32), np.zeros((4, 4), np.float32))


def test_preprocess_aligns_by_default_and_not_with_exact():
    img, disp, cols = pole_scene(6, spread=2)
    pre = PreprocessConfig(grow_foreground=0.0)
    aligned = preprocess(img, disp, config=Config(size=None, preprocess=pre)).disparity
    exact = preprocess(img, disp, config=Config(size=None, edges="exact",
                                                 preprocess=pre)).disparity
    assert int((aligned[10] > 0.5).sum()) == 6
    assert int((exact[10] > 0.5).sum()) == 6 + 2 * 2


def test_the_edges_option_is_checked_and_recorded():
    with pytest.raises(ConfigError, match="edges must be one of align, soft, exact"):
        Config(edges="snap")
    assert Config().edges == "soft"
    data = json.loads(Config(edges="exact").to_json())
    assert data["edges"] == "exact" and Config.from_dict(data).edges == "exact"
