"""Depth steps on the pixel grid: where they are, the range of values around them,
and ramps across them turned into steps (:func:`sharpen_ramps`, before the
bilateral median of :mod:`photo3d.stages.filters`).

Every window here is a square, clipped at the image border, and is computed as
shifted maxima or minima along one axis and then the other (:func:`window_range`,
:func:`grow_square`).

Example:
    >>> d = np.zeros((1, 6), np.float32); d[0, 3:] = 1.0
    >>> near_steps(d, 1, 0.5).astype(int).tolist()
    [[0, 1, 1, 1, 1, 0]]
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np


def window_range(values: np.ndarray, radius: int) -> tuple[np.ndarray, np.ndarray]:
    """The smallest and largest value of each pixel's ``2 radius + 1`` square window
    (clipped at the border), ``(H, W)`` each, new arrays.

    Example:
        >>> lo, hi = window_range(np.arange(4, dtype=np.float32)[None], 1)
        >>> lo.tolist(), hi.tolist()
        ([[0.0, 0.0, 1.0, 2.0]], [[1.0, 2.0, 3.0, 3.0]])
    """
    return _extreme(values, radius, np.minimum), _extreme(values, radius, np.maximum)


def _extreme(values: np.ndarray, radius: int, op: Callable) -> np.ndarray:
    """``op`` (``np.minimum``, ``np.maximum``, ``np.logical_or``) over each pixel's
    ``2 radius + 1`` square window, clipped at the border: along the rows' axis, then
    the columns'."""
    rows = values.copy()
    for k in range(1, radius + 1):
        op(rows[k:], values[:-k], out=rows[k:])
        op(rows[:-k], values[k:], out=rows[:-k])
    out = rows.copy()
    for k in range(1, radius + 1):
        op(out[:, k:], rows[:, :-k], out=out[:, k:])
        op(out[:, :-k], rows[:, k:], out=out[:, :-k])
    return out


def spread_above(disparity: np.ndarray, size: int, threshold: float) -> np.ndarray:
    """``(H, W) bool``: where the ``size x size`` window of ``disparity (H, W) float32``
    spans more than ``threshold``: its largest minus its smallest value, the window
    clipped at the border. The same as ``scipy.ndimage.maximum_filter(d, size) -
    minimum_filter(d, size) > threshold`` (their default ``reflect`` border repeats
    values the clipped window holds), in a sixth of the time (:func:`window_range`).

    Example:
        >>> d = np.zeros((3, 6), np.float32); d[:, 4:] = 1.0
        >>> spread_above(d, 3, 0.5)[0].tolist()
        [False, False, False, True, True, False]
    """
    lo, hi = window_range(np.asarray(disparity), size // 2)
    hi -= lo
    return hi > threshold


def sharpen_ramps(disparity: np.ndarray, *, threshold: float = 0.04,
                  iterations: int = 4, min_rise: float = 3.0) -> np.ndarray:
    """Turn ramps across depth steps into steps at their middle (a toggle filter,
    Kramer and Bruckner 1975, limited to the pixels inside a ramp).

    A network's or a stereo matcher's depth is smooth at a silhouette: the step is a
    ramp a few pixels wide whose pixels differ from their neighbours by more than the
    discontinuity threshold, so each would be cut out as a sliver of its own depth,
    stretched between the two sides in novel views (and a median keeps a monotone
    ramp as it is). The ramp's pixels are those within one pixel of a 4-neighbour
    step (more than ``threshold``) whose value lies strictly between their left and
    right neighbours' or their upper and lower neighbours', and whose 7 x 7 window
    spans more than ``min_rise`` thresholds, in the map as it comes (a gentler rise:
    a slanted surface or a small step, left to the median). Each is given a side:
    below the middle of its 7 x 7 window's range the far side, else (at the middle
    too) the near side. Then each pass, every ramp pixel takes its 3 x 3 window's
    largest value (near side) or smallest (far side), all at once: the plateaus grow
    into the ramp from both ends, each pixel only moves towards its side, and the
    step ends up where the ramp crossed its middle. The other pixels keep their
    values: plateaus, a 1 px pole, a corner where three layers meet (between two of
    them only diagonally), and slopes whose neighbours differ by less than
    ``threshold`` (no step near them). A ramp wider than about twice ``iterations``
    keeps a middle part.

    Args:
        disparity: ``(H, W) float32`` normalised disparity.
        threshold: the discontinuity threshold (normalised disparity).
        iterations: passes (each moves a ramp's plateaus one pixel further in: ramps
            up to about twice as wide become steps).
        min_rise: the smallest range of a ramp pixel's 7 x 7 window, in thresholds.

    Returns:
        ``(H, W) float32`` copy.

    Example:
        >>> d = np.array([[0.0, 0.0, 0.1, 0.3, 0.45, 0.7, 0.9, 1.0, 1.0]], np.float32)
        >>> sharpen_ramps(d)[0].tolist()
        [0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0]
    """
    out = np.array(disparity, np.float32, copy=True)
    ys, xs = np.nonzero(_between_neighbours(out) & near_steps(out, 1, threshold))
    if ys.size == 0:
        return out
    lo7, hi7 = window_range(out, 3)
    tall = (hi7 - lo7)[ys, xs] > min_rise * threshold
    ys, xs = ys[tall], xs[tall]
    near_side = (out - lo7 >= hi7 - out)[ys, xs]
    for _ in range(iterations):
        lo, hi = window_range(out, 1)
        target = np.where(near_side, hi[ys, xs], lo[ys, xs])
        if np.array_equal(target, out[ys, xs]):
            break
        out[ys, xs] = target
    return out


def _between_neighbours(disparity: np.ndarray) -> np.ndarray:
    """``(H, W) bool``: pixels strictly between their left and right neighbours' values
    or between their upper and lower neighbours' (inside a ramp; a corner where three
    layers meet, between two layers only diagonally, is not)."""
    d = np.pad(disparity, 1, mode="edge")
    mid = d[1:-1, 1:-1]
    out = np.zeros(mid.shape, bool)
    for a, b in ((d[1:-1, :-2], d[1:-1, 2:]), (d[:-2, 1:-1], d[2:, 1:-1])):
        out |= ((a < mid) & (mid < b)) | ((b < mid) & (mid < a))
    return out


def near_steps(disparity: np.ndarray, radius: int, threshold: float) -> np.ndarray:
    """``(H, W) bool``: pixels within ``radius`` (Chebyshev) of a pixel that differs from
    a 4-neighbour by more than ``threshold`` (a smooth slope has none).

    Example:
        >>> d = np.zeros((1, 6), np.float32); d[0, 3:] = 1.0
        >>> near_steps(d, 1, 0.5).astype(int).tolist()
        [[0, 1, 1, 1, 1, 0]]
    """
    step = np.zeros(disparity.shape, bool)
    jump = np.abs(np.diff(disparity, axis=1)) > threshold
    step[:, 1:] |= jump
    step[:, :-1] |= jump
    jump = np.abs(np.diff(disparity, axis=0)) > threshold
    step[1:] |= jump
    step[:-1] |= jump
    return grow_square(step, radius)


def grow_square(mask: np.ndarray, radius: int) -> np.ndarray:
    """``mask (H, W) bool`` grown by ``radius`` pixels (a square: Chebyshev distance).

    Example:
        >>> grow_square(np.eye(3, dtype=bool)[:1], 1).astype(int).tolist()
        [[1, 1, 0]]
    """
    return _extreme(mask, radius, np.logical_or)
