"""Bilateral median filter for disparity sharpening (paper, Sec. 3.1; Ma et al. 2013).

Each output pixel is the weighted median of its window, weights
``exp(-r^2 / 2 sigma_s^2) * exp(-(d_q - d_p)^2 / 2 sigma_i^2)``. As in the authors'
code it is applied only where the window straddles a discontinuity (elsewhere the
median of a smooth ramp is the ramp itself), over several passes.
"""

from __future__ import annotations

import numba
import numpy as np
from scipy import ndimage


@numba.njit(cache=True, parallel=True)
def _weighted_median_at(disp, ys, xs, radius, sigma_s, sigma_i):  # pragma: no cover - jit
    h, w = disp.shape
    out = np.empty(ys.shape[0], np.float32)
    inv_s = 1.0 / (2.0 * sigma_s * sigma_s)
    inv_i = 1.0 / (2.0 * sigma_i * sigma_i)
    size = (2 * radius + 1) * (2 * radius + 1)
    for k in numba.prange(ys.shape[0]):
        y, x = ys[k], xs[k]
        centre = disp[y, x]
        vals = np.empty(size, np.float32)
        wts = np.empty(size, np.float32)
        n = 0
        total = 0.0
        for dy in range(-radius, radius + 1):
            yy = y + dy
            if yy < 0 or yy >= h:
                continue
            for dx in range(-radius, radius + 1):
                xx = x + dx
                if xx < 0 or xx >= w:
                    continue
                v = disp[yy, xx]
                wt = np.exp(-(dy * dy + dx * dx) * inv_s - (v - centre) * (v - centre) * inv_i)
                # insertion sort by value
                j = n
                while j > 0 and vals[j - 1] > v:
                    vals[j] = vals[j - 1]
                    wts[j] = wts[j - 1]
                    j -= 1
                vals[j] = v
                wts[j] = wt
                n += 1
                total += wt
        half = 0.5 * total
        acc = 0.0
        res = vals[n - 1]
        for j in range(n):
            acc += wts[j]
            if acc >= half:
                res = vals[j]
                break
        out[k] = res
    return out


KERNELS = ((_weighted_median_at, "(float32[:, ::1], int64[::1], int64[::1], int64, float64, "
                                 "float64)"),)
"""The kernels ``make`` runs here and the argument types it gives them, compiled ahead
by :func:`photo3d.kernels.compile_kernels` (``tests/test_kernels.py`` checks ``make``
gives no others)."""


def bilateral_median(
    disparity: np.ndarray,
    *,
    windows: tuple[int, ...] = (7, 7, 5, 5, 5),
    sigma_spatial: float = 4.0,
    sigma_intensity: float = 0.5,
    threshold: float = 0.04,
) -> np.ndarray:
    """Sharpen a normalised disparity map near its discontinuities.

    Args:
        disparity: ``(H, W) float32`` normalised disparity in [0, 1].
        windows: odd window sizes, one filter pass each.
        sigma_spatial: spatial sigma, pixels.
        sigma_intensity: range sigma, normalised disparity.
        threshold: only pixels whose window spans more than this are filtered.

    Returns:
        ``(H, W) float32`` filtered copy.

    Example:
        >>> d = np.zeros((9, 9), np.float32); d[:, 5:] = 1.0; d[4, 4] = 0.5
        >>> out = bilateral_median(d)
        >>> float(out[4, 4]) in (0.0, 1.0), float(out[0, 0]), float(out[0, 8])
        (True, 0.0, 1.0)
    """
    out = np.ascontiguousarray(disparity, dtype=np.float32).copy()
    for size in windows:
        if size < 1 or size % 2 == 0:
            raise ValueError(f"filter window sizes must be odd and positive, got {size}")
        spread = ndimage.maximum_filter(out, size) - ndimage.minimum_filter(out, size)
        ys, xs = np.nonzero(spread > threshold)
        if ys.size == 0:
            break
        out[ys, xs] = _weighted_median_at(
            out, ys.astype(np.int64), xs.astype(np.int64), size // 2, sigma_spatial,
            sigma_intensity,
        )
    return out
