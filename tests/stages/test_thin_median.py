"""A thin structure with exact depth survives preprocessing (the colour-guided
bilateral median, ``PreprocessConfig.filter_sigma_color``); an outlier of the
surface's colour is still removed. With the paper's median (``filter_sigma_color=0``,
as ``edges="exact"`` keeps) the pole is gone: the first test fails."""

from dataclasses import replace

import numpy as np
import pytest

from photo3d.config import Config
from photo3d.stages.preprocess import preprocess

WALL, FAR = 0.5, 0.0  # normalised disparities: the wall, a far corner (sets the range)
POLE = 0.62  # a small step in front of the wall, as scene 0's pole's


def pole_scene(h: int = 64, w: int = 96):
    """A 2 px vertical pole a little in front of a noisy grey wall, a far column at
    the left border. Returns ``(image (h, w, 3) float32, disparity (h, w) float32,
    the pole's columns)``."""
    rng = np.random.default_rng(0)
    img = np.clip(0.6 + rng.normal(0, 0.02, (h, w, 3)), 0, 1).astype(np.float32)
    disp = np.full((h, w), WALL, np.float32)
    disp[:, 0] = FAR
    cols = slice(40, 42)
    disp[:, cols] = POLE
    img[:, cols] = (0.1, 0.1, 0.3)
    return img, disp, cols


def config(edges: str, sigma_color: float | None = None) -> Config:
    c = Config(size=None, edges=edges)
    if sigma_color is None:
        return c
    return replace(c, preprocess=replace(c.preprocess, filter_sigma_color=sigma_color))


@pytest.mark.parametrize("edges", ["align", "soft"])
def test_a_2px_pole_with_exact_depth_survives_preprocessing(edges):
    img, disp, cols = pole_scene()
    out = preprocess(img, disp, config=config(edges)).disparity  # normalised
    assert (out[:, cols] - out[:, 60:61] > 0.15).all()  # the step: 0.12 of 0.62


@pytest.mark.parametrize("edges", ["exact", "align"])
def test_the_papers_median_erases_it(edges):
    """The reference behaviour: ``exact`` (and the colour sigma 0) keeps the paper's filter."""
    img, disp, cols = pole_scene()
    out = preprocess(img, disp, config=config(edges, 0.0 if edges == "align" else None))
    assert np.allclose(out.disparity[:, cols], out.disparity[:, 60:61], atol=1e-6)


def test_an_outlier_patch_of_the_walls_colour_is_still_removed():
    img, disp, _ = pole_scene()
    disp[20:23, 70:72] = 0.9  # a stereo outlier: no colour of its own
    out = preprocess(img, disp, config=config("soft")).disparity
    assert np.allclose(out[18:25, 68:74], out[30, 60], atol=1e-6)
