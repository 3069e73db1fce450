"""Bilateral median filter for disparity sharpening (paper, Sec. 3.1; Ma et al. 2013).

Each output pixel is the weighted median of its window, weights
``exp(-r^2 / 2 sigma_s^2) * exp(-(d_q - d_p)^2 / 2 sigma_i^2)``. As in the authors'
code it is applied only where the window straddles a discontinuity (elsewhere the
median of a smooth ramp is the ramp itself), over several passes.
"""

from __future__ import annotations

import numba
import numpy as np

from photo3d import parallel

_CHUNKS = 4  # pieces per thread, so that no thread is left alone with the last


@numba.njit(cache=True, nogil=True)
def weighted_median(vals, wts, n, half, top):  # pragma: no cover - jit
    """The smallest of ``vals[:n] (float32)`` whose own and smaller values' weights
    ``wts[:n] (float32)`` sum to ``half`` or more (``top``, the largest, if none do),
    by three-way partitions (quickselect; ``vals`` and ``wts`` are reordered). Called
    from numba kernels (this filter's and :mod:`photo3d.stages.align`'s).

    Example:
        >>> vals = np.array([3, 1, 2], np.float32); wts = np.array([1, 1, 5], np.float32)
        >>> float(weighted_median(vals, wts, 3, 3.5, 3.0))
        2.0
    """
    below = 0.0  # weight of the values known to be smaller than the answer
    lo, hi = 0, n  # the values still in question
    while lo < hi:
        pivot = vals[(lo + hi) >> 1]
        lt, i, gt = lo, lo, hi  # [lo, lt) < pivot, [lt, i) == pivot, [gt, hi) > pivot
        s_lt = s_eq = 0.0
        while i < gt:
            v, wt = vals[i], wts[i]
            if v < pivot:
                s_lt += wt
                vals[i] = vals[lt]
                wts[i] = wts[lt]
                vals[lt] = v
                wts[lt] = wt
                lt += 1
                i += 1
            elif v > pivot:
                gt -= 1
                vals[i] = vals[gt]
                wts[i] = wts[gt]
                vals[gt] = v
                wts[gt] = wt
            else:
                s_eq += wt
                i += 1
        if below + s_lt >= half:
            hi = lt
        elif below + s_lt + s_eq >= half:
            return pivot
        else:
            below += s_lt + s_eq
            lo = gt
    return top  # no value reaches half (float32 rounding)


@numba.njit(cache=True, nogil=True)
def _weighted_median_at(disp, ys, xs, radius, sigma_s, sigma_i, out, vals,
                        wts):  # pragma: no cover - jit
    """Fill ``out (K,) float32`` with the weighted median of the window of each pixel
    ``(ys[k], xs[k])`` of ``disp (H, W) float32`` (the window clipped at the image
    border): the smallest window value whose own and smaller values' weights (rounded
    to float32) reach half of all its weights (:func:`weighted_median`; ``vals`` and
    ``wts``: ``((2 radius + 1)^2,) float32`` scratch). Summed in float64, up to 64
    float32 weights give the same sums in any order while the largest is less than
    2^23 times the smallest (the defaults: 0.08 to 1), so this is the value the
    insertion sort and scan of before found."""
    h, w = disp.shape
    inv_s = 1.0 / (2.0 * sigma_s * sigma_s)
    inv_i = 1.0 / (2.0 * sigma_i * sigma_i)
    for k in range(ys.shape[0]):
        y, x = ys[k], xs[k]
        centre = disp[y, x]
        n = 0
        total = 0.0
        top = centre
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
                vals[n] = v
                wts[n] = wt
                n += 1
                total += wt
                top = max(top, v)
        out[k] = weighted_median(vals, wts, n, 0.5 * total, top)


KERNELS = ((_weighted_median_at, "(float32[:, ::1], int64[::1], int64[::1], int64, float64, "
                                 "float64, float32[::1], float32[::1], float32[::1])"),)
"""The kernels ``make`` runs here and the argument types it gives them, compiled ahead
by :func:`photo3d.kernels.compile_kernels` (``tests/test_kernels.py`` checks ``make``
gives no others)."""


def spread_above(disparity: np.ndarray, size: int, threshold: float) -> np.ndarray:
    """``(H, W) bool``: where the ``size x size`` window of ``disparity (H, W) float32``
    spans more than ``threshold``: its largest minus its smallest value, the window
    clipped at the border. The same as ``scipy.ndimage.maximum_filter(d, size) -
    minimum_filter(d, size) > threshold`` (their default ``reflect`` border repeats
    values the clipped window holds), in a sixth of the time: ``size - 1`` shifted
    maxima and minima along each axis.

    Example:
        >>> d = np.zeros((3, 6), np.float32); d[:, 4:] = 1.0
        >>> spread_above(d, 3, 0.5)[0].tolist()
        [False, False, False, True, True, False]
    """
    d = np.asarray(disparity)
    hi, lo = d.copy(), d.copy()
    for k in range(1, size // 2 + 1):  # along the rows' axis
        np.maximum(hi[k:], d[:-k], out=hi[k:])
        np.maximum(hi[:-k], d[k:], out=hi[:-k])
        np.minimum(lo[k:], d[:-k], out=lo[k:])
        np.minimum(lo[:-k], d[k:], out=lo[:-k])
    top, bottom = hi.copy(), lo.copy()
    for k in range(1, size // 2 + 1):  # then along the columns'
        np.maximum(top[:, k:], hi[:, :-k], out=top[:, k:])
        np.maximum(top[:, :-k], hi[:, k:], out=top[:, :-k])
        np.minimum(bottom[:, k:], lo[:, :-k], out=bottom[:, k:])
        np.minimum(bottom[:, :-k], lo[:, k:], out=bottom[:, :-k])
    top -= bottom
    return top > threshold


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
    threads = parallel.threads()  # this thread's budget: `batch` gives each worker 1
    with parallel.thread_pool(threads, name="median") as pool:
        for size in windows:
            if size < 1 or size % 2 == 0:
                raise ValueError(f"filter window sizes must be odd and positive, got {size}")
            ys, xs = np.nonzero(spread_above(out, size, threshold))
            if ys.size == 0:
                break
            ys, xs = ys.astype(np.int64), xs.astype(np.int64)  # contiguous: views of one array
            medians = np.empty(len(ys), np.float32)
            cuts = np.linspace(0, len(ys), _CHUNKS * threads + 1).astype(np.int64)

            def run(a: int, b: int, size=size, ys=ys, xs=xs, medians=medians) -> None:
                _weighted_median_at(out, ys[a:b], xs[a:b], size // 2, float(sigma_spatial),
                                    float(sigma_intensity), medians[a:b],
                                    np.empty(size * size, np.float32),
                                    np.empty(size * size, np.float32))

            list(pool.map(run, cuts[:-1], cuts[1:]))
            out[ys, xs] = medians
    return out



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
    lo7, hi7 = _window_range(out, 3)
    tall = (hi7 - lo7)[ys, xs] > min_rise * threshold
    ys, xs = ys[tall], xs[tall]
    near_side = (out - lo7 >= hi7 - out)[ys, xs]
    for _ in range(iterations):
        lo, hi = _window_range(out, 1)
        target = np.where(near_side, hi[ys, xs], lo[ys, xs])
        if np.array_equal(target, out[ys, xs]):
            break
        out[ys, xs] = target
    return out


def _window_range(disparity: np.ndarray, radius: int) -> tuple[np.ndarray, np.ndarray]:
    """The smallest and largest value of each pixel's ``2 radius + 1`` square window
    (clipped at the border), ``(H, W) float32`` each."""
    lo, hi = disparity.copy(), disparity.copy()
    for k in range(1, radius + 1):  # along the rows' axis
        np.minimum(lo[k:], disparity[:-k], out=lo[k:])
        np.minimum(lo[:-k], disparity[k:], out=lo[:-k])
        np.maximum(hi[k:], disparity[:-k], out=hi[k:])
        np.maximum(hi[:-k], disparity[k:], out=hi[:-k])
    rows_lo, rows_hi = lo.copy(), hi.copy()
    for k in range(1, radius + 1):  # then along the columns'
        np.minimum(lo[:, k:], rows_lo[:, :-k], out=lo[:, k:])
        np.minimum(lo[:, :-k], rows_lo[:, k:], out=lo[:, :-k])
        np.maximum(hi[:, k:], rows_hi[:, :-k], out=hi[:, k:])
        np.maximum(hi[:, :-k], rows_hi[:, k:], out=hi[:, :-k])
    return lo, hi


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
    near = mask.copy()
    for k in range(1, radius + 1):  # along the rows' axis, then the columns'
        near[k:] |= mask[:-k]
        near[:-k] |= mask[k:]
    grown = near.copy()
    for k in range(1, radius + 1):
        grown[:, k:] |= near[:, :-k]
        grown[:, :-k] |= near[:, k:]
    return grown

