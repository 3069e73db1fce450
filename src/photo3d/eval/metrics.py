"""Image quality metrics on all or some pixels: PSNR and SSIM (LPIPS: :mod:`.lpips`).

Images are ``(H, W, 3) float32`` in [0, 1]. A ``mask`` ``(H, W) bool`` restricts the
average to its pixels (SSIM and LPIPS are computed on the whole image and their
per-pixel maps averaged over the mask).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from photo3d.errors import InputError

RANGE_SLACK = 1e-3
"""How far outside [0, 1] an image's values may lie (float rounding of resampled or
blended colours); 0..255 images are far beyond it."""


def check_images(a: np.ndarray, b: np.ndarray, mask: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(a, b, mask)`` as arrays once they are images the metrics are defined on:
    ``(H, W, 3)`` floats in [0, 1] (within :data:`RANGE_SLACK`) of one shape
    (uint8 images, or floats of 0..255, gave scores with no meaning), ``mask``
    ``(H, W)`` bool (default: every pixel). Lists are taken.

    Raises:
        InputError: one line naming the image and what is wrong with it.

    Example:
        >>> a = np.zeros((4, 4, 3), np.float32)
        >>> check_images(a, a)[2].sum()
        np.int64(16)
        >>> check_images(a, (a * 255).astype(np.uint8))  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        photo3d.errors.InputError: b has dtype uint8; expected floats in [0, 1] ...
    """
    a, b = np.asarray(a), np.asarray(b)
    for name, image in (("a", a), ("b", b)):
        if image.ndim != 3 or image.shape[2] != 3:
            raise InputError(f"{name} has shape {image.shape}; expected (H, W, 3)")
        if not np.issubdtype(image.dtype, np.floating):
            raise InputError(f"{name} has dtype {image.dtype}; expected floats in [0, 1] "
                             f"(photo3d.io.images.to_float_image converts uint8 / uint16)")
        if image.size and not (np.isfinite(image).all() and -RANGE_SLACK <= image.min()
                               and image.max() <= 1 + RANGE_SLACK):
            raise InputError(f"{name} has values outside [0, 1] (or NaN / inf): span "
                             f"[{image.min():g}, {image.max():g}]")
    if a.shape != b.shape:
        raise InputError(f"images differ in shape: {a.shape} vs {b.shape}")
    if mask is None:
        return a, b, np.ones(a.shape[:2], bool)
    mask = np.asarray(mask)
    if mask.shape != a.shape[:2]:
        raise InputError(f"mask has shape {mask.shape} but images are {a.shape[:2]}")
    return a, b, mask.astype(bool)


def psnr(a: np.ndarray, b: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Peak signal-to-noise ratio in dB (peak 1.0) over ``mask``; inf for identical images.

    Example:
        >>> a = np.zeros((4, 4, 3), np.float32); b = a + 0.1
        >>> round(psnr(a, b), 2)
        20.0
    """
    a, b, m = check_images(a, b, mask)
    if not m.any():
        return float("nan")
    mse = float(np.mean((a[m].astype(np.float64) - b[m]) ** 2))
    return float("inf") if mse == 0 else float(10.0 * np.log10(1.0 / mse))


def ssim_map(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per-pixel SSIM (Wang et al. 2004: Gaussian window sigma 1.5, K1 0.01, K2 0.03,
    data range 1), averaged over the colour channels: ``(H, W) float64``."""
    c1, c2 = 0.01**2, 0.03**2
    out = np.zeros(a.shape[:2])
    for ch in range(a.shape[2]):
        x, y = a[..., ch].astype(np.float64), b[..., ch].astype(np.float64)

        def blur(v: np.ndarray) -> np.ndarray:
            return ndimage.gaussian_filter(v, 1.5, truncate=3.5, mode="reflect")

        mx, my = blur(x), blur(y)
        vx, vy, cxy = blur(x * x) - mx * mx, blur(y * y) - my * my, blur(x * y) - mx * my
        out += ((2 * mx * my + c1) * (2 * cxy + c2)) / ((mx**2 + my**2 + c1) * (vx + vy + c2))
    return out / a.shape[2]


def ssim(a: np.ndarray, b: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Mean SSIM over ``mask`` (1 = identical).

    Example:
        >>> a = np.random.default_rng(0).random((32, 32, 3)).astype(np.float32)
        >>> ssim(a, a), ssim(a, 1 - a) < 0
        (1.0, True)
    """
    a, b, m = check_images(a, b, mask)
    if not m.any():
        return float("nan")
    return float(np.mean(ssim_map(a, b)[m]))
