"""Ramps across depth steps (smooth network or stereo depth) turned into steps before
the LDI is cut (issue 44: blurred depth left slivers at in-between depths, stretched
across the gap in novel views)."""

from dataclasses import replace

import numpy as np
from scipy import ndimage
from test_edges_pole import pole_scene

from photo3d.config import Config, PreprocessConfig
from photo3d.stages.preprocess import preprocess
from photo3d.stages.steps import sharpen_ramps


def _blurred_pole(width: int):
    """``pole_scene(width)`` with its exact disparity blurred like a network's output
    (as ``benchmarks/bench_edges.py``'s ``blurred``: 4 x 4 block means upsampled
    bilinearly, then a Gaussian of sigma 1 px)."""
    img, disp, cols = pole_scene(width, spread=0)
    h, w = disp.shape
    small = disp.reshape(h // 4, 4, w // 4, 4).mean(axis=(1, 3))
    up = ndimage.zoom(small, 4, order=1)
    return img, ndimage.gaussian_filter(up, 1.0).astype(np.float32), cols


def test_a_blurred_step_becomes_a_step_at_its_middle():
    _, disp, cols = _blurred_pole(6)
    before, out = disp[10], sharpen_ramps(disp, threshold=0.04)[10]
    assert (np.abs(np.diff(before)) > 0.04).sum() > 4  # each side a ramp of steps
    assert (np.abs(np.diff(out)) > 0.04).sum() == 2  # one step each side (the tails:
    near = out > 0.5 * (out.min() + out.max())  # a slope below the threshold)
    assert near[cols].all() and near.sum() == 6


def test_steps_poles_layers_and_gentle_slopes_stay():
    d = np.zeros((12, 24), np.float32)
    d[:, 3] = 1.0  # a 1 px pole
    d[:, 8:11] = 0.4  # a 3 px layer between the wall and a nearer one
    d[:, 11:14] = 0.8
    d[:, 16:] = np.linspace(0.0, 0.2, 8)  # a slope, 0.029 per pixel
    d[5:8, :3] = 0.5  # a rail ending at the pole: its corners touch both
    np.testing.assert_array_equal(sharpen_ramps(d), d)


def test_make_cuts_a_blurred_thin_pole_without_slivers():
    """After preprocessing, a 2 px pole with network-like depth is the wall's depth and
    the pole's, no pixel between them (without the ramps sharpened a 4 px band beside
    the pole stays at a quarter of the way: measured 251 pixels), and exactly the
    pole's pixels are near."""
    img, disp, cols = _blurred_pole(2)
    pre = PreprocessConfig(grow_foreground=0.0)
    rows = slice(8, -8)  # away from the border
    for passes, slivers in ((0, True), (4, False)):
        config = Config(size=None, preprocess=replace(pre, ramp_passes=passes))
        d = preprocess(img, disp, config=config).disparity[rows]
        lo, hi = d.min(), d.max()
        between = int(((d > lo + 0.05) & (d < hi - 0.05)).sum())
        assert (between > 100) == slivers, (passes, between)
    near = d > 0.5 * (lo + hi)
    assert near[:, cols].all() and (near.sum(axis=1) == 2).all()
