"""Synthetic scenes with known answers, shared by the stage tests."""

from __future__ import annotations

import numpy as np
import pytest

from photo3d.config import Config, PreprocessConfig, RegionConfig


def texture(h: int, w: int, seed: int = 0) -> np.ndarray:
    """``(h, w, 3) float32`` smooth random texture in [0.1, 0.9]."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w] / max(h, w)
    img = np.stack(
        [0.5 + 0.3 * np.sin(2 * np.pi * (rng.random() * 3 * xx + rng.random() * 3 * yy)
                            + rng.random() * 6) for _ in range(3)], axis=2)
    return img.astype(np.float32)


def two_planes(h: int = 64, w: int = 96, split: int = 48) -> tuple[np.ndarray, np.ndarray]:
    """Background plane (disparity 1) on the left, foreground (disparity 2) from ``split``."""
    disp = np.ones((h, w), np.float32)
    disp[:, split:] = 2.0
    return texture(h, w), disp


def exact_config(**regions) -> Config:
    """Config with spatial sizes taken literally (no scaling), no border by default."""
    base = dict(synthesis_iterations=6, context_iterations=10, edge_dilation=0, border=0)
    base.update(regions)
    return Config(size=None, spatial_scale=1.0, preprocess=PreprocessConfig(min_edge_length=5),
                  regions=RegionConfig(**base))


@pytest.fixture
def planes():
    return two_planes()
