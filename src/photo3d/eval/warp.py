"""Forward warping of a rectified left view into the right view (z-buffered).

Used for two things in the evaluation: the *naive forward warp* baseline (holes
left), and the *disocclusion mask*: right-view pixels that no left pixel reaches.
Each left pixel covers its footprint on the row; neighbours whose disparities differ
by less than ``continuity`` pixels are joined into one span (a continuous surface
leaves no cracks), larger jumps leave the gap open. Nearer (larger disparity) wins.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np


@dataclass(frozen=True)
class Warp:
    """Attributes:
    color: ``(H, W, 3) float32`` warped image, 0 where nothing arrives.
    reached: ``(H, W) bool`` right pixels some left pixel reaches.
    frame: ``(H, W) bool`` right pixels between the first and last reached pixel of
        their row (the part of the right view the left view can explain at all).
    """

    color: np.ndarray
    reached: np.ndarray
    frame: np.ndarray

    @property
    def disoccluded(self) -> np.ndarray:
        """``(H, W) bool``: inside the frame, not reached."""
        return self.frame & ~self.reached


@numba.njit(cache=True)
def _splat(color, disp, continuity):  # pragma: no cover - jit
    h, w = disp.shape
    out = np.zeros((h, w, 3), np.float32)
    zbuf = np.full((h, w), -np.inf, np.float32)
    for y in range(h):
        for x in range(w):
            d0 = disp[y, x]
            if not np.isfinite(d0):
                continue
            a = x + 0.5 - d0  # continuous right-view coordinate of the pixel centre
            joined = False
            if x + 1 < w and np.isfinite(disp[y, x + 1]) and abs(disp[y, x + 1] - d0) < continuity:
                b = x + 1.5 - disp[y, x + 1]
                joined = True
            else:
                b = a
            lo = min(a, b) - (0.0 if joined else 0.5)
            hi = max(a, b) + (0.0 if joined else 0.5)
            for xr in range(max(0, math.ceil(lo - 0.5)), min(w - 1, math.floor(hi - 0.5)) + 1):
                c = xr + 0.5
                t = 0.0 if b == a else min(max((c - a) / (b - a), 0.0), 1.0)
                dd = d0 + t * ((disp[y, x + 1] if joined else d0) - d0)
                if dd > zbuf[y, xr]:
                    zbuf[y, xr] = dd
                    for ch in range(3):
                        c1 = color[y, x + 1, ch] if joined else color[y, x, ch]
                        out[y, xr, ch] = (1 - t) * color[y, x, ch] + t * c1
    return out, zbuf > -np.inf


def forward_warp(image: np.ndarray, disparity: np.ndarray, *, continuity: float = 1.0) -> Warp:
    """Warp the left view into the right view of a rectified pair.

    Args:
        image: ``(H, W, 3) float32`` left view.
        disparity: ``(H, W)`` left-view disparity in pixels (``x_right = x_left - d``);
            NaN or inf where unknown.
        continuity: neighbours closer than this in disparity form a continuous span.

    Example:
        >>> img = np.ones((1, 8, 3), np.float32)
        >>> d = np.array([[0, 0, 0, 0, 3, 3, 3, 3]], np.float32)  # right half is nearer
        >>> w = forward_warp(img, d)
        >>> w.reached[0].astype(int).tolist()
        [1, 1, 1, 1, 1, 0, 0, 0]
    """
    color, reached = _splat(np.ascontiguousarray(image, np.float32),
                            np.ascontiguousarray(disparity, np.float32), float(continuity))
    cols = np.arange(reached.shape[1])
    first = np.where(reached.any(1), np.argmax(reached, 1), reached.shape[1])
    last = np.where(reached.any(1), reached.shape[1] - 1 - np.argmax(reached[:, ::-1], 1), -1)
    frame = (cols[None] >= first[:, None]) & (cols[None] <= last[:, None])
    return Warp(color=color, reached=reached, frame=frame)
