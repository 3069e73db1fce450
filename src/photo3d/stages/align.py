"""Depth edges onto the photo's colour edges (issue 44), before the LDI is cut.

Depth from a network, a stereo matcher or a phone is smooth or fat at silhouettes:
its steps land a few pixels off the place where the colour changes, most often on the
far side (the foreground is fat). Cut there, the foreground carries a band of the
background's colour into every novel view (halos, doubled thin poles) and the
background keeps a sliver of the foreground's.

:func:`align_edges` moves each step onto the colour boundary with an image-guided
(joint) weighted median, iterated: each pixel near a step takes the weighted median
of its window's disparities, weights ``exp(-r^2 / 2 sigma_s^2) * exp(-D^2 / 2
sigma_c^2)``, ``D`` the largest colour difference from the pixel met on the straight
line to the neighbour (so the pixels that look like this one, and are not behind a
colour edge from it, vote), its own value left out (it is the one in doubt). A pixel
of the background's colour inside a fat foreground then finds more
background-coloured neighbours on the background than inside the band, and takes the
background's disparity; each
iteration peels the band from its outer side. A thin structure (a 2 px wire) keeps
its disparity: its own colour's pixels lie along it, and the far side beyond it is
behind a colour edge. Chosen by measurement
(``benchmarks/bench_edges.py``, ``docs/edges.md``).
"""

from __future__ import annotations

import numba
import numpy as np

from photo3d.stages.filters import weighted_median
from photo3d.stages.steps import grow_square, near_steps


def _offsets(radius: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The window's offsets ``(dy, dx)`` without the centre, nearest ring first, and
    each one's parent: the offset one step nearer the centre on the straight line
    (-1: the centre). ``(K,) int64`` each."""
    dys, dxs = [], []
    for n in range(1, radius + 1):
        for dy in range(-n, n + 1):
            for dx in range(-n, n + 1):
                if max(abs(dy), abs(dx)) == n:
                    dys.append(dy)
                    dxs.append(dx)
    index = {(dy, dx): i for i, (dy, dx) in enumerate(zip(dys, dxs, strict=True))}
    parents = []
    for dy, dx in zip(dys, dxs, strict=True):
        n = max(abs(dy), abs(dx))
        py, px = round(dy * (n - 1) / n), round(dx * (n - 1) / n)
        parents.append(index.get((py, px), -1))
    return (np.array(dys, np.int64), np.array(dxs, np.int64), np.array(parents, np.int64))


@numba.njit(cache=True, nogil=True, parallel=True)
def _joint_median_at(disp, image, ys, xs, dys, dxs, parents, sigma_s, sigma_c,
                     min_contrast, threshold, out):  # pragma: no cover - jit
    """Fill ``out (K,) float32`` with the colour-weighted median of the window of each
    pixel ``(ys[k], xs[k])`` of ``disp (H, W) float32`` where that median differs from
    the pixel's value by more than ``threshold`` (a move :func:`align_edges` takes),
    else with the pixel's value. The window is guided by ``image (H, W, 3) float32``:
    the neighbours at offsets ``dys, dxs`` (nearest first; ``parents``: each offset's
    neighbour one step nearer the centre, -1 = the centre, see :func:`_offsets`), each
    weighted by its distance and by the largest colour difference from the centre met
    on the straight line to it (a neighbour behind a colour edge does not vote; nor
    does one whose weight is below ``exp(-16)``). A pixel keeps its value when its
    neighbours all weigh nothing or none differs from it in colour by
    ``min_contrast`` or more (no colour edge to follow: a flat photo leaves the map as
    it is).

    The median is one of the window's values, so it is only sought where a neighbour
    differs from the pixel by more than ``threshold`` and those neighbours above it,
    or those below it, weigh about half of all (0.5 - 1e-9: float64 sums of float32
    weights are off by far less); elsewhere it cannot move the pixel across a step.
    ``threshold`` is taken a millionth lower than given, so that float32 rounding never
    has a neighbour counted near here that :func:`align_edges` counts far. The window
    is left as soon as neither side can weigh half: the far neighbours not yet met
    are counted at their spatial weight (the colour term is at most 1), plus a
    millionth for rounding; the sums only grow, so the end would have said the same."""
    h, w = disp.shape
    inv_s = 1.0 / (2.0 * sigma_s * sigma_s)
    inv_c = 1.0 / (2.0 * sigma_c * sigma_c)
    far = threshold * (1.0 - 1e-6)
    m = dys.shape[0]
    spatial = np.empty(m)  # each offset's spatial term of the exponent
    most = np.empty(m)  # above any weight at the offset
    for i in range(m):
        spatial[i] = (dys[i] * dys[i] + dxs[i] * dxs[i]) * inv_s
        most[i] = np.float32(np.exp(-spatial[i])) * (1.0 + 1e-6)
    for k in numba.prange(ys.shape[0]):
        y, x = ys[k], xs[k]
        centre = disp[y, x]
        out[k] = centre
        # the far neighbours above and below the pixel not yet met: how many, and the
        # most they can weigh (none: no step to cross, nothing to seek)
        count_a = count_b = 0
        rest_a = rest_b = 0.0
        for i in range(m):
            yy, xx = y + dys[i], x + dxs[i]
            if 0 <= yy < h and 0 <= xx < w:
                dv = disp[yy, xx] - centre
                if dv > far:
                    count_a += 1
                    rest_a += most[i]
                elif -dv > far:
                    count_b += 1
                    rest_b += most[i]
        if count_a == 0 and count_b == 0:
            continue
        vals = np.empty(m, np.float32)
        wts = np.empty(m, np.float32)
        seen = np.empty(m, np.float32)  # largest squared colour difference on the line
        r0, g0, b0 = image[y, x, 0], image[y, x, 1], image[y, x, 2]
        n = 0
        total = above = below = 0.0  # all weights, those of the far values each side
        top = centre
        contrast = 0.0  # the largest squared colour difference seen
        settled = False  # neither side can weigh half: the pixel stays
        for i in range(m):
            yy, xx = y + dys[i], x + dxs[i]
            if yy < 0 or yy >= h or xx < 0 or xx >= w:
                seen[i] = np.inf
                continue
            dr = image[yy, xx, 0] - r0
            dg = image[yy, xx, 1] - g0
            db = image[yy, xx, 2] - b0
            c2 = dr * dr + dg * dg + db * db
            p = parents[i]
            if p >= 0 and seen[p] > c2:
                c2 = seen[p]
            seen[i] = c2
            contrast = max(contrast, c2)
            v = disp[yy, xx]
            dv = v - centre
            side = 1 if dv > far else (-1 if -dv > far else 0)
            e = spatial[i] + c2 * inv_c
            if e <= 16.0:  # else a weight below 1e-7 of the nearest neighbour's: no vote
                wt = np.float32(np.exp(-e))
                vals[n] = v
                wts[n] = wt
                n += 1
                total += wt
                top = max(top, v)
                if side > 0:
                    above += wt
                elif side < 0:
                    below += wt
            if side > 0:
                count_a -= 1
                rest_a = rest_a - most[i] if count_a > 0 else 0.0
            elif side < 0:
                count_b -= 1
                rest_b = rest_b - most[i] if count_b > 0 else 0.0
            half = (0.5 - 1e-9) * total
            if above + rest_a < half and below + rest_b < half:
                settled = True
                break
        if settled or total < 1e-12 or contrast < min_contrast * min_contrast:
            continue  # no step to cross, or no colour edge to follow
        # not settled: the last check had met every far neighbour, a side weighs half
        out[k] = weighted_median(vals, wts, n, 0.5 * total, top)


KERNELS = ((_joint_median_at, "(float32[:, ::1], float32[:, :, ::1], int64[::1], int64[::1], "
                              "int64[::1], int64[::1], int64[::1], float64, float64, "
                              "float64, float64, float32[::1])"),)
"""The kernels ``make`` runs here and the argument types it gives them, compiled ahead
by :func:`photo3d.kernels.compile_kernels` (``tests/test_kernels.py`` checks ``make``
gives no others)."""


def align_edges(
    image: np.ndarray,
    disparity: np.ndarray,
    *,
    radius: int = 4,
    iterations: int = 4,
    sigma_color: float = 0.1,
    threshold: float = 0.04,
) -> np.ndarray:
    """Move the steps of ``disparity`` onto the colour edges of ``image``.

    Only pixels within ``radius`` of a step (4-neighbours more than ``threshold``
    apart) with a colour difference of ``2 sigma_color`` or more in their window
    change; each of ``iterations`` passes gives them the colour-guided
    weighted median of their ``2 radius + 1`` window (module docstring), all at once,
    where it differs from their value by more than ``threshold`` (the pixel moves to
    the other side of a step; smaller changes are not taken).

    Args:
        image: ``(H, W, 3) float32`` photo in [0, 1] (the guide).
        disparity: ``(H, W) float32`` normalised disparity (larger is nearer).
        radius: window radius, working pixels (steps move at most about this far a
            pass).
        iterations: passes.
        sigma_color: colour sigma, Euclidean RGB distance in [0, 1] units; the
            spatial sigma is ``radius``.
        threshold: the discontinuity threshold (normalised disparity).

    Returns:
        ``(H, W) float32`` disparity with its steps on the colour edges.

    Example:
        >>> img = np.zeros((12, 12, 3), np.float32); img[:, :4] = 1.0   # pole: x < 4
        >>> d = np.zeros((12, 12), np.float32); d[:, :6] = 1.0          # depth: x < 6
        >>> out = align_edges(img, d, radius=3, iterations=3)
        >>> out[6].tolist()
        [1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    """
    if image.shape[:2] != disparity.shape:
        raise ValueError(f"disparity has shape {disparity.shape} but image is {image.shape}")
    out = np.ascontiguousarray(disparity, dtype=np.float32).copy()
    if radius < 1 or iterations < 1:
        return out
    guide = np.ascontiguousarray(image, dtype=np.float32)
    ys, xs = np.nonzero(near_steps(out, radius, threshold))
    if ys.size == 0:
        return out
    ys, xs = ys.astype(np.int64), xs.astype(np.int64)
    dys, dxs, parents = _offsets(int(radius))
    for _ in range(iterations):
        medians = np.empty(ys.size, np.float32)
        _joint_median_at(out, guide, ys, xs, dys, dxs, parents, float(radius),
                         float(sigma_color), 2.0 * float(sigma_color), float(threshold),
                         medians)
        changed = np.abs(medians - out[ys, xs]) > threshold  # across a step: moved
        if not changed.any():
            break
        out[ys[changed], xs[changed]] = medians[changed]
        # next pass: only the pixels whose window changed (the others would give the
        # same median again); a smaller change (a slope's pixel taking a neighbour's
        # value) is not taken: this moves steps, the bilateral median filters
        moved = np.zeros(out.shape, bool)
        moved[ys[changed], xs[changed]] = True
        again = grow_square(moved, radius)[ys, xs]
        ys, xs = ys[again], xs[again]
    return out
