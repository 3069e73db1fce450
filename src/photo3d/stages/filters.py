"""Bilateral median filter for disparity sharpening (paper, Sec. 3.1; Ma et al. 2013).

Each output pixel is the weighted median of its window, weights
``exp(-r^2 / 2 sigma_s^2) * exp(-(d_q - d_p)^2 / 2 sigma_i^2)``. As in the authors'
code it is applied only where the window straddles a discontinuity (elsewhere the
median of a smooth ramp is the ramp itself), over several passes.

That median erases structures thinner than about half its window (a 2 px pole in
front of a wall takes the wall's disparity). With ``edges="align"``/``"soft"`` the
thin structures the photo shows are kept (:func:`keep_thin`): a second, colour-guided
run (each weight also falls with the photo's colour difference from the centre,
so a pole's own pixels vote for the pole) gives the values of the long, thin parts
where the two runs disagree; everywhere else, stereo outliers included, the paper's
median stands (``docs/edges.md``, "A median that keeps thin structures").
"""

from __future__ import annotations

import numba
import numpy as np

from photo3d import parallel
from photo3d.stages.steps import spread_above

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
def _weighted_median_at(disp, image, ys, xs, radius, sigma_s, sigma_i, sigma_c, out, vals,
                        wts):  # pragma: no cover - jit
    """Fill ``out (K,) float32`` with the weighted median of the window of each pixel
    ``(ys[k], xs[k])`` of ``disp (H, W) float32`` (the window clipped at the image
    border): the smallest window value whose own and smaller values' weights (rounded
    to float32) reach half of all its weights (:func:`weighted_median`; ``vals`` and
    ``wts``: ``((2 radius + 1)^2,) float32`` scratch). Summed in float64, up to 64
    float32 weights give the same sums in any order while the largest is less than
    2^23 times the smallest (the defaults: 0.08 to 1), so this is the value the
    insertion sort and scan of before found. With ``sigma_c > 0`` each weight is also
    multiplied by ``exp(-|c_q - c_p|^2 / 2 sigma_c^2)``, ``c`` the colour of ``image
    (H, W, 3) float32`` at the neighbour and at the centre: the pixels that look like
    the centre vote (a thin pole's own pixels for the pole), the others hardly; with
    ``sigma_c`` 0 ``image`` is not read (the paper's filter)."""
    h, w = disp.shape
    inv_s = 1.0 / (2.0 * sigma_s * sigma_s)
    inv_i = 1.0 / (2.0 * sigma_i * sigma_i)
    colour = sigma_c > 0.0
    inv_c = 1.0 / (2.0 * sigma_c * sigma_c) if colour else 0.0
    r0 = g0 = b0 = np.float32(0.0)
    for k in range(ys.shape[0]):
        y, x = ys[k], xs[k]
        centre = disp[y, x]
        if colour:
            r0, g0, b0 = image[y, x, 0], image[y, x, 1], image[y, x, 2]
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
                e = (dy * dy + dx * dx) * inv_s + (v - centre) * (v - centre) * inv_i
                if colour:
                    dr = image[yy, xx, 0] - r0
                    dg = image[yy, xx, 1] - g0
                    db = image[yy, xx, 2] - b0
                    e += (dr * dr + dg * dg + db * db) * inv_c
                wt = np.exp(-e)
                vals[n] = v
                wts[n] = wt
                n += 1
                total += wt
                top = max(top, v)
        out[k] = weighted_median(vals, wts, n, 0.5 * total, top)


KERNELS = ((_weighted_median_at, "(float32[:, ::1], float32[:, :, ::1], int64[::1], "
                                 "int64[::1], int64, float64, float64, float64, float32[::1], "
                                 "float32[::1], float32[::1])"),)
"""The kernels ``make`` runs here and the argument types it gives them, compiled ahead
by :func:`photo3d.kernels.compile_kernels` (``tests/test_kernels.py`` checks ``make``
gives no others)."""


def keep_thin(plain: np.ndarray, guided: np.ndarray, *, threshold: float,
              width: int, min_length: int = 0,
              original: np.ndarray | None = None) -> np.ndarray:
    """``(H, W) float32``: ``plain`` (the paper's median) with the thin structures
    ``guided`` (the colour-guided median) kept: where the two differ by more than
    ``threshold``, the pixels a ``width x width`` opening of that set removes (parts
    narrower than ``width``: a pole, a wire) take ``guided``'s value; wider parts (a
    stereo outlier patch the photo's colours happen to outline) keep ``plain``'s.
    ``width`` 0: ``guided`` everywhere.

    Example:
        >>> p = np.zeros((9, 9), np.float32); g = p.copy(); g[:, 4] = 1; g[1:6, 0:6] += 1
        >>> out = keep_thin(p, g, threshold=0.5, width=3)
        >>> out[8].tolist()[3:6], float(out[2, 2])
        ([0.0, 1.0, 0.0], 0.0)
    """
    if width <= 0:
        return guided
    from scipy import ndimage

    differ = np.abs(guided - plain) > threshold
    if original is not None:
        differ &= np.abs(guided - original) <= threshold
    thin = differ & ~ndimage.binary_opening(differ, np.ones((width, width), bool))
    if min_length > 1:
        labels, _ = ndimage.label(thin, np.ones((3, 3), bool))
        boxes = ndimage.find_objects(labels)
        extent = np.array([0] + [max(b[0].stop - b[0].start, b[1].stop - b[1].start)
                                 for b in boxes])
        thin = extent[labels] >= min_length
    return np.where(thin, guided, plain).astype(np.float32)


def bilateral_median(
    disparity: np.ndarray,
    *,
    windows: tuple[int, ...] = (7, 7, 5, 5, 5),
    sigma_spatial: float = 4.0,
    sigma_intensity: float = 0.5,
    threshold: float = 0.04,
    image: np.ndarray | None = None,
    sigma_color: float = 0.1,
    only: np.ndarray | None = None,
) -> np.ndarray:
    """Sharpen a normalised disparity map near its discontinuities.

    Args:
        disparity: ``(H, W) float32`` normalised disparity in [0, 1].
        windows: odd window sizes, one filter pass each.
        sigma_spatial: spatial sigma, pixels.
        sigma_intensity: range sigma, normalised disparity.
        threshold: only pixels whose window spans more than this are filtered.
        image: ``(H, W, 3) float32`` photo in [0, 1], or None. Given, each weight is
            also multiplied by ``exp(-|c_q - c_p|^2 / 2 sigma_color^2)`` (colours of
            the neighbour and of the centre): a thin structure the photo shows keeps
            its disparity (its own pixels vote for it), while an outlier of the
            surface's colour is still outvoted.
        sigma_color: colour sigma (RGB distance, colours in [0, 1]) when ``image``.
        only: ``(H, W) bool`` or None: filter only these pixels (and only where the
            window spans more than ``threshold``).

    Returns:
        ``(H, W) float32`` filtered copy.

    Example:
        >>> d = np.zeros((9, 9), np.float32); d[:, 5:] = 1.0; d[4, 4] = 0.5
        >>> out = bilateral_median(d)
        >>> float(out[4, 4]) in (0.0, 1.0), float(out[0, 0]), float(out[0, 8])
        (True, 0.0, 1.0)
    """
    out = np.ascontiguousarray(disparity, dtype=np.float32).copy()
    if image is None:  # the paper's filter: no colour term, the photo is not read
        guide, colour = np.zeros((1, 1, 3), np.float32), 0.0
    else:
        guide, colour = np.ascontiguousarray(image, dtype=np.float32), float(sigma_color)
    threads = parallel.threads()  # this thread's budget: `batch` gives each worker 1
    with parallel.thread_pool(threads, name="median") as pool:
        for size in windows:
            if size < 1 or size % 2 == 0:
                raise ValueError(f"filter window sizes must be odd and positive, got {size}")
            todo = spread_above(out, size, threshold)
            if only is not None:
                todo &= only
            ys, xs = np.nonzero(todo)
            if ys.size == 0:
                break
            ys, xs = ys.astype(np.int64), xs.astype(np.int64)  # contiguous: views of one array
            medians = np.empty(len(ys), np.float32)
            cuts = np.linspace(0, len(ys), _CHUNKS * threads + 1).astype(np.int64)

            def run(a: int, b: int, size=size, ys=ys, xs=xs, medians=medians) -> None:
                _weighted_median_at(out, guide, ys[a:b], xs[a:b], size // 2,
                                    float(sigma_spatial), float(sigma_intensity), colour,
                                    medians[a:b], np.empty(size * size, np.float32),
                                    np.empty(size * size, np.float32))

            list(pool.map(run, cuts[:-1], cuts[1:]))
            out[ys, xs] = medians
    return out
