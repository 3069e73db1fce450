"""Exemplar texture: PatchMatch over one patch, sources strictly inside the context.

Given a first estimate of the synthesis region (the structure-respecting diffusion
of :mod:`photo3d.inpaint.structured`), every synthesis pixel is matched to a
``(2r+1)^2`` source patch lying wholly in the context, and the region is rebuilt by
averaging the overlapping source patches (Wexler et al.'s "vote"), a few times
(expectation-maximisation). The patch distance compares known pixels at full weight
and the current estimate of synthesis pixels at ``guide_weight``, so a source must
agree with the fill's colours too: patches come from the matching side of a
continued edge. The nearest-neighbour field is found with PatchMatch (Barnes et al.
2009: propagation and random search), started from each pixel's nearest source.
Sources never include the foreground or anything outside the context.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True, inline="always")
def _rand(state):  # pragma: no cover - jit
    # xorshift64*; state is a length-1 uint64 array.
    x = state[0]
    x ^= x >> np.uint64(12)
    x ^= x << np.uint64(25)
    x ^= x >> np.uint64(27)
    state[0] = x
    return ((x * np.uint64(2685821657736338717)) >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@numba.njit(cache=True, nogil=True)
def _dist(img, weight, py, px, qy, qx, r, best):  # pragma: no cover - jit
    h, w, c = img.shape
    d = 0.0
    for dy in range(-r, r + 1):
        ty = py + dy
        if ty < 0 or ty >= h:
            continue
        for dx in range(-r, r + 1):
            tx = px + dx
            if tx < 0 or tx >= w:
                continue
            wt = weight[ty, tx]
            if wt == 0.0:
                continue
            if c == 3:  # colours (every fill make runs): the loop below unrolled,
                # the same sums in the same order (5 % less PatchMatch)
                e = img[ty, tx, 0] - img[qy + dy, qx + dx, 0]
                d += wt * e * e
                e = img[ty, tx, 1] - img[qy + dy, qx + dx, 1]
                d += wt * e * e
                e = img[ty, tx, 2] - img[qy + dy, qx + dx, 2]
                d += wt * e * e
            else:
                for ch in range(c):
                    e = img[ty, tx, ch] - img[qy + dy, qx + dx, ch]
                    d += wt * e * e
        if d >= best:
            return d
    return d


@numba.njit(cache=True, nogil=True)
def _fill(img, context, synthesis, r, iterations, em_steps, guide_weight, seed,
          copy):  # pragma: no cover
    h, w, c = img.shape
    # Valid source centres: the whole patch inside the context (a window sum of the
    # context's integral image).
    area = np.zeros((h + 1, w + 1), np.int64)
    for y in range(h):
        run = 0
        for x in range(w):
            if context[y, x]:
                run += 1
            area[y + 1, x + 1] = area[y, x + 1] + run
    full = (2 * r + 1) * (2 * r + 1)
    src = np.zeros((h, w), np.bool_)
    n_src = 0
    for y in range(r, h - r):
        for x in range(r, w - r):
            if (area[y + r + 1, x + r + 1] - area[y - r, x + r + 1]
                    - area[y + r + 1, x - r] + area[y - r, x - r]) == full:
                src[y, x] = True
                n_src += 1
    if n_src == 0:
        return False
    # Synthesis pixels in scan order.
    n = 0
    sy = np.empty(h * w, np.int32)
    sx = np.empty(h * w, np.int32)
    for y in range(h):
        for x in range(w):
            if synthesis[y, x]:
                sy[n] = y
                sx[n] = x
                n += 1
    # Nearest source (breadth-first over the lattice) as the initial match; it stops
    # once every synthesis pixel has one (only theirs are read).
    fy = np.full((h, w), -1, np.int32)
    fx = np.full((h, w), -1, np.int32)
    qy = np.empty(h * w, np.int32)
    qx = np.empty(h * w, np.int32)
    head = 0
    tail = 0
    for y in range(h):
        for x in range(w):
            if src[y, x]:
                fy[y, x] = y
                fx[y, x] = x
                qy[tail] = y
                qx[tail] = x
                tail += 1
    missing = n
    while head < tail and missing > 0:
        y, x = qy[head], qx[head]
        head += 1
        for k in range(4):
            yy = y + (0, 0, -1, 1)[k]
            xx = x + (-1, 1, 0, 0)[k]
            if 0 <= yy < h and 0 <= xx < w and fy[yy, xx] < 0:
                fy[yy, xx] = fy[y, x]
                fx[yy, xx] = fx[y, x]
                qy[tail] = yy
                qx[tail] = xx
                tail += 1
                if synthesis[yy, xx]:
                    missing -= 1
    weight = np.zeros((h, w), np.float32)
    for y in range(h):
        for x in range(w):
            if context[y, x]:
                weight[y, x] = 1.0
            elif synthesis[y, x]:
                weight[y, x] = guide_weight
    cost = np.empty((h, w), np.float64)
    state = np.array([np.uint64(seed) * np.uint64(2654435761) + np.uint64(88172645463325252)])
    # the vote's sums; a fill that only copies (one step, ``copy``) needs none
    votes = em_steps > 1 or not copy
    acc = np.zeros((h, w, c) if votes else (1, 1, c), np.float64)
    cnt = np.zeros((h, w) if votes else (1, 1), np.float64)
    big = max(h, w)
    for em in range(em_steps):
        for i in range(n):
            # int64 sources, as the searches below give: one compiled _dist, not two
            cost[sy[i], sx[i]] = _dist(img, weight, sy[i], sx[i], np.int64(fy[sy[i], sx[i]]),
                                       np.int64(fx[sy[i], sx[i]]), r, np.inf)
        for it in range(iterations):
            forward = (it % 2) == 0
            step = 1 if forward else -1
            for j in range(n):
                i = j if forward else n - 1 - j
                y, x = sy[i], sx[i]
                best = cost[y, x]
                by, bx = fy[y, x], fx[y, x]
                # Propagation from the previous pixel in scan order (row and column).
                for k in range(2):
                    ny = y - step if k == 0 else y
                    nx = x if k == 0 else x - step
                    if ny < 0 or nx < 0 or ny >= h or nx >= w or not synthesis[ny, nx]:
                        continue
                    cy = fy[ny, nx] + (y - ny)
                    cx = fx[ny, nx] + (x - nx)
                    if cy < 0 or cx < 0 or cy >= h or cx >= w or not src[cy, cx]:
                        continue
                    if cy == by and cx == bx:
                        continue
                    d = _dist(img, weight, y, x, cy, cx, r, best)
                    if d < best:
                        best, by, bx = d, cy, cx
                # Random search around the current best. A candidate that is the best
                # itself cannot beat it: not measured (at radius 1 every candidate is,
                # at 2 a quarter of them; the same matches, about 15 % less PatchMatch).
                rad = big
                while rad >= 1:
                    cy = by + int((2.0 * _rand(state) - 1.0) * rad)
                    cx = bx + int((2.0 * _rand(state) - 1.0) * rad)
                    if (0 <= cy < h and 0 <= cx < w and src[cy, cx]
                            and (cy != by or cx != bx)):
                        d = _dist(img, weight, y, x, cy, cx, r, best)
                        if d < best:
                            best, by, bx = d, cy, cx
                    rad //= 2
                fy[y, x], fx[y, x], cost[y, x] = by, bx, best
        if copy and em == em_steps - 1:
            # Last step: each pixel takes its own match's centre (sharp texture), a
            # context pixel, which no step writes.
            for i in range(n):
                y, x = sy[i], sx[i]
                for ch in range(c):
                    img[y, x, ch] = img[fy[y, x], fx[y, x], ch]
            break
        # Vote: every synthesis pixel averages the source patches covering it.
        for i in range(n):
            y, x = sy[i], sx[i]
            for dy in range(-r, r + 1):
                for dx in range(-r, r + 1):
                    ty, tx = y + dy, x + dx
                    if ty < 0 or tx < 0 or ty >= h or tx >= w or not synthesis[ty, tx]:
                        continue
                    for ch in range(c):
                        acc[ty, tx, ch] += img[fy[y, x] + dy, fx[y, x] + dx, ch]
                    cnt[ty, tx] += 1.0
        for i in range(n):
            y, x = sy[i], sx[i]
            for ch in range(c):
                img[y, x, ch] = acc[y, x, ch] / cnt[y, x]
                acc[y, x, ch] = 0.0
            cnt[y, x] = 0.0
    return True


KERNELS = ((_fill, "(float32[:, :, ::1], boolean[:, ::1], boolean[:, ::1], int64, int64, int64, "
                   "float64, int64, boolean)"),)
"""The kernels ``make`` runs here and the argument types it gives them, compiled ahead
by :func:`photo3d.kernels.compile_kernels` (``tests/test_kernels.py`` checks ``make``
gives no others)."""


def exemplar_fill(
    image: np.ndarray,
    context: np.ndarray,
    synthesis: np.ndarray,
    *,
    radius: int = 2,
    iterations: int = 4,
    em_steps: int = 2,
    guide_weight: float = 0.5,
    seed: int = 0,
    copy: bool = False,
) -> np.ndarray:
    """Re-synthesise ``synthesis`` from context patches, starting from ``image``.

    Args:
        image: ``(h, w, c) float32``: the context, and a first estimate (the guide)
            under ``synthesis``; other pixels are ignored.
        context: ``(h, w) bool`` source pixels.
        synthesis: ``(h, w) bool`` pixels to re-synthesise (disjoint from ``context``).
        radius: patch radius ``r`` (patches are ``(2r+1)^2``).
        iterations: PatchMatch sweeps per EM step.
        em_steps: match + vote rounds.
        guide_weight: weight of the current estimate of synthesis pixels in the
            patch distance (known pixels weigh 1).
        seed: random search seed (results are deterministic for a seed).
        copy: in the last step each pixel copies its match's centre instead of
            averaging the overlapping patches (sharper, less smooth).

    Returns:
        ``(h, w, c) float32``: ``image`` with the synthesis region replaced (returned
        unchanged when no whole patch fits in the context).

    Example:
        >>> stripes = np.zeros((24, 24, 1), np.float32); stripes[:, ::4] = 1.0
        >>> ctx = np.ones((24, 24), bool); ctx[8:16, 8:16] = False
        >>> guide = stripes.copy(); guide[~ctx] = 0.25                 # a flat first guess
        >>> out = exemplar_fill(guide, ctx, ~ctx)
        >>> bool(np.abs(out - stripes)[~ctx].mean() < 0.1)           # the stripes return
        True
    """
    img = np.ascontiguousarray(image, np.float32).copy()
    _fill(img, np.ascontiguousarray(context), np.ascontiguousarray(synthesis), int(radius),
          int(iterations), int(em_steps), float(guide_weight), int(seed), bool(copy))
    return img
