"""Preprocessing (paper, Sec. 3.1): working size, normalisation, sharpening, edges."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from PIL import Image

from photo3d.config import Config, working_shape
from photo3d.depth.normalize import normalize
from photo3d.stages.align import align_edges
from photo3d.stages.edges import DepthEdges, link_edges
from photo3d.stages.filters import bilateral_median, keep_thin
from photo3d.stages.steps import sharpen_ramps


@dataclass(frozen=True)
class Preprocessed:
    """Inputs of the LDI stage at working size.

    Attributes:
        image: ``(H, W, 3) float32`` sRGB in [0, 1].
        disparity: ``(H, W) float32`` normalised and sharpened disparity.
        edges: linked depth edges of ``disparity``.
        disparity_range: ``(min, max)`` of the input disparity before normalisation.
        working_size: longer side in pixels (spatial parameters scale with it).
    """

    image: np.ndarray
    disparity: np.ndarray
    edges: DepthEdges
    disparity_range: tuple[float, float]
    working_size: int


def resize(array: np.ndarray, shape: tuple[int, int], *, nearest: bool = False) -> np.ndarray:
    """Resize ``(H, W)`` or ``(H, W, C)`` float32 with Pillow.

    Lanczos when shrinking, bicubic when enlarging, or nearest neighbour when
    ``nearest`` (used for disparity: interpolation would spread each depth step
    over several pixels, each below the discontinuity threshold, and no median
    filter restores a monotone ramp).

    Example:
        >>> resize(np.ones((4, 6), np.float32), (2, 3)).shape
        (2, 3)
    """
    h, w = shape
    if array.shape[:2] == (h, w):
        return array.astype(np.float32, copy=True)
    if nearest:
        method = Image.Resampling.NEAREST
    elif h < array.shape[0]:
        method = Image.Resampling.LANCZOS
    else:
        method = Image.Resampling.BICUBIC
    if array.ndim == 2:
        img = Image.fromarray(np.ascontiguousarray(array, np.float32), mode="F")
        return np.asarray(img.resize((w, h), method), np.float32)
    return np.stack([resize(array[..., c], shape, nearest=nearest)
                     for c in range(array.shape[2])], axis=2)


def grow_foreground(disparity: np.ndarray, steps: int, threshold: float) -> np.ndarray:
    """Move every depth discontinuity ``steps`` pixels into its far side.

    A pixel whose 4-neighbour is nearer by more than ``threshold`` takes the
    nearest such neighbour's disparity, ``steps`` times; smooth slopes are untouched.

    Args:
        disparity: ``(H, W) float32`` normalised disparity (larger is nearer).
        steps: pixels to grow.
        threshold: the discontinuity threshold.

    Returns:
        ``(H, W) float32``.

    Example:
        >>> d = np.zeros((1, 6), np.float32); d[0, :2] = 1.0; d[0, 4:] = np.linspace(0, .02, 2)
        >>> grow_foreground(d, 1, 0.04)[0].tolist()
        [1.0, 1.0, 1.0, 0.0, 0.0, 0.019999999552965164]
    """
    out = np.array(disparity, np.float32, copy=True)
    for _ in range(steps):
        padded = np.pad(out, 1, mode="edge")
        near = np.maximum.reduce([padded[:-2, 1:-1], padded[2:, 1:-1],
                                  padded[1:-1, :-2], padded[1:-1, 2:]])
        jump = near - out > threshold
        if not jump.any():
            break
        out[jump] = near[jump]
    return out


def preprocess(image: np.ndarray, disparity: np.ndarray, *, config: Config) -> Preprocessed:
    """Resize, normalise, sharpen, align the depth steps with the photo's colour edges
    (``config.edges`` ``align`` or ``soft``: :func:`~photo3d.stages.align.align_edges`) and find
    linked depth edges. With ``align`` or ``soft`` the bilateral median keeps the long
    thin structures a colour-guided run of it keeps
    (:func:`~photo3d.stages.filters.keep_thin`).

    Args:
        image: ``(H, W, 3) float32`` in [0, 1].
        disparity: ``(H, W) float32`` filled disparity (any positive scale).
        config: the pipeline configuration.

    Returns:
        :class:`Preprocessed` at the working size.

    Example:
        >>> from photo3d.config import Config
        >>> d = np.zeros((64, 64), np.float32); d[:, 32:] = 1.0
        >>> p = preprocess(np.zeros((64, 64, 3), np.float32), d, config=Config(size=None))
        >>> p.edges.count, p.image.shape
        (1, (64, 64, 3))
    """
    shape = working_shape(disparity.shape, config.size)
    img = np.clip(resize(image, shape), 0.0, 1.0)
    disp = resize(disparity, shape, nearest=True)
    norm, lo, hi = normalize(disp)
    pre = config.preprocess
    working = max(shape)
    if config.edges in ("align", "soft") and pre.ramp_passes > 0:
        norm = sharpen_ramps(norm, threshold=pre.discontinuity, iterations=pre.ramp_passes)
    median = {"windows": pre.filter_windows, "sigma_spatial": pre.sigma_spatial,
              "sigma_intensity": pre.sigma_intensity, "threshold": pre.discontinuity}
    filtered = bilateral_median(norm, **median)
    if config.edges in ("align", "soft") and pre.filter_sigma_color > 0:
        changed = np.abs(filtered - norm) > pre.discontinuity  # only these can be kept
        guided = bilateral_median(norm, image=img, sigma_color=pre.filter_sigma_color,
                                  only=changed, **median)
        filtered = keep_thin(filtered, guided, threshold=pre.discontinuity,
                             width=pre.filter_thin_width,
                             min_length=config.spatial(pre.filter_thin_length, working),
                             original=norm)
    if config.edges in ("align", "soft"):
        filtered = align_edges(img, filtered, radius=pre.align_radius,
                               iterations=pre.align_iterations,
                               sigma_color=pre.align_sigma_color, threshold=pre.discontinuity)
    if pre.grow_foreground > 0:
        scale = working / max(disparity.shape)  # working px per photo px
        filtered = grow_foreground(filtered, max(1, round(pre.grow_foreground * scale)),
                                   pre.discontinuity)
    edges = link_edges(filtered, threshold=pre.discontinuity,
                       min_length=config.spatial(pre.min_edge_length, working),
                       attach_short=pre.attach_short)
    return Preprocessed(img, filtered, edges, (lo, hi), working)
