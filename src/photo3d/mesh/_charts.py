"""Numba kernel of :mod:`photo3d.mesh.light`: texture charts for faces of hidden layers."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def claim_faces(faces, pos, rank, images, n_layers):
    """Give every leftover face a layer image holding its three pixels.

    Args:
        faces: ``(F, 3) int64`` pixel indices.
        pos: ``(N,) int64`` flat lattice position of each pixel.
        rank: ``(N,) int64`` each pixel's own layer.
        images: ``(L, P) int32`` pixel at each position of each layer image (-1
            free); updated in place with the claimed positions. ``L`` must leave room
            for new layers beyond ``n_layers``.
        n_layers: layers in use.

    Returns:
        ``(layer (F,) int64, n_layers)``; a face whose pixels fit no layer gets a
        new one.
    """
    layer = np.empty(len(faces), np.int64)
    for f in range(len(faces)):
        first = max(rank[faces[f, 0]], rank[faces[f, 1]], rank[faces[f, 2]])
        chosen = -1
        for j in range(n_layers + 1):
            k = (first + j) % (n_layers + 1)
            if k >= images.shape[0]:
                continue
            ok = True
            for c in range(3):
                p = faces[f, c]
                q = images[k, pos[p]]
                if q >= 0 and q != p:
                    ok = False
            if ok:
                chosen = k
                break
        if chosen < 0:
            raise ValueError("no free layer image for a face")
        if chosen == n_layers:
            n_layers += 1
        for c in range(3):
            images[chosen, pos[faces[f, c]]] = faces[f, c]
        layer[f] = chosen
    return layer, n_layers


@njit(cache=True, nogil=True)
def fill_charts(src, colors):
    """``(C, S, S, 3) uint8`` chart texels from pixel indices ``src (C, S, S)`` (-1:
    none) and ``colors (N, 3) uint8``: holes take the mean of their known
    8-neighbours, twice (each round from the previous one), then the chart's mean."""
    n, s = src.shape[0], src.shape[1]
    out = np.zeros((n, s, s, 3), np.uint8)
    val = np.zeros((s, s, 3), np.float64)
    known = np.zeros((s, s), np.bool_)
    grown = np.zeros((s, s), np.bool_)
    new = np.zeros((s, s, 3), np.float64)
    for c in range(n):
        for y in range(s):
            for x in range(s):
                p = src[c, y, x]
                known[y, x] = p >= 0
                for ch in range(3):
                    val[y, x, ch] = colors[p, ch] if p >= 0 else 0.0
        for _ in range(2):
            for y in range(s):
                for x in range(s):
                    grown[y, x] = False
                    if known[y, x]:
                        continue
                    cnt = 0
                    acc0 = acc1 = acc2 = 0.0
                    for yy in range(max(y - 1, 0), min(y + 2, s)):
                        for xx in range(max(x - 1, 0), min(x + 2, s)):
                            if known[yy, xx]:
                                cnt += 1
                                acc0 += val[yy, xx, 0]
                                acc1 += val[yy, xx, 1]
                                acc2 += val[yy, xx, 2]
                    if cnt:
                        grown[y, x] = True
                        new[y, x, 0] = acc0 / cnt
                        new[y, x, 1] = acc1 / cnt
                        new[y, x, 2] = acc2 / cnt
            for y in range(s):
                for x in range(s):
                    if grown[y, x]:
                        known[y, x] = True
                        for ch in range(3):
                            val[y, x, ch] = new[y, x, ch]
        cnt = 0
        mean = np.zeros(3)
        for y in range(s):
            for x in range(s):
                if known[y, x]:
                    cnt += 1
                    for ch in range(3):
                        mean[ch] += val[y, x, ch]
        for y in range(s):
            for x in range(s):
                for ch in range(3):
                    v = val[y, x, ch] if known[y, x] else mean[ch] / max(cnt, 1)
                    out[c, y, x, ch] = np.uint8(min(max(np.rint(v), 0.0), 255.0))
    return out


def chart_vertices(faces, chart, n_pixels):
    """One vertex per (pixel, chart) that the faces use: texture seams split vertices.

    Args:
        faces: ``(F, 3) int64`` pixel indices.
        chart: ``(F,) int64`` chart of each face (-1: the input layer's photo).
        n_pixels: number of LDI pixels.

    Returns:
        ``(corners (F, 3) int64, pixel (V,) int64, vchart (V,) int64)``: the vertex of
        each face corner, and each vertex's pixel and chart + 1, vertices sorted by
        ``(pixel, chart)`` (what ``np.unique`` of the pair keys gives, at a fraction
        of its time: most pixels are in one chart, and only the others are sorted).
    """
    # two kernels around NumPy's unique: numba's np.unique would compile a sort (1 s)
    first, keys, span = _pixel_charts(faces, chart, n_pixels)
    return _chart_corners(faces, chart, first, np.unique(keys), span)


@njit(cache=True, nogil=True)
def _pixel_charts(faces, chart, n_pixels):
    """``(first (N,) int64, keys (K,) int64, span)``: each pixel's chart + 1 (-1: in
    no face, -2: in several charts), and the key ``pixel * span + chart + 1`` of every
    face corner at a pixel in several charts."""
    first = np.full(n_pixels, -1, np.int64)
    n_multi = 0
    for f in range(len(faces)):
        for c in range(3):
            p = faces[f, c]
            if first[p] == -1:
                first[p] = chart[f] + 1
            elif first[p] >= 0 and first[p] != chart[f] + 1:
                first[p] = -2
    for f in range(len(faces)):
        for c in range(3):
            if first[faces[f, c]] == -2:
                n_multi += 1
    keys = np.empty(n_multi, np.int64)
    span = chart.max() + 2 if len(chart) else 1
    j = 0
    for f in range(len(faces)):
        for c in range(3):
            p = faces[f, c]
            if first[p] == -2:
                keys[j] = p * span + chart[f] + 1
                j += 1
    return first, keys, span


@njit(cache=True, nogil=True)
def _chart_corners(faces, chart, first, keys, span):
    """:func:`chart_vertices` from :func:`_pixel_charts`' ``first`` and ``span`` and
    its ``keys`` sorted without repeats."""
    n_pixels = len(first)
    vid = np.full(n_pixels, -1, np.int64)  # the vertex of a one-chart pixel, or the
    n_v = 0                                 # first of a several-chart pixel's
    k = 0
    pixel = np.empty(n_pixels + len(keys), np.int64)
    vchart = np.empty(n_pixels + len(keys), np.int64)
    for p in range(n_pixels):
        if first[p] >= 0:
            vid[p] = n_v
            pixel[n_v], vchart[n_v] = p, first[p]
            n_v += 1
        elif first[p] == -2:
            vid[p] = n_v
            while k < len(keys) and keys[k] // span == p:
                pixel[n_v], vchart[n_v] = p, keys[k] % span
                n_v += 1
                k += 1
    corners = np.empty(faces.shape, np.int64)
    for f in range(len(faces)):
        for c in range(3):
            p = faces[f, c]
            v = vid[p]
            if first[p] == -2:
                while vchart[v] != chart[f] + 1:
                    v += 1
            corners[f, c] = v
    return corners, pixel[:n_v].copy(), vchart[:n_v].copy()


@njit(cache=True, nogil=True)
def pixel_ranks(pos, n_positions):
    """``(N,) int64`` how many pixels before each one (in LDI order) share its position."""
    seen = np.zeros(n_positions, np.int64)
    rank = np.empty(len(pos), np.int64)
    for i in range(len(pos)):
        rank[i] = seen[pos[i]]
        seen[pos[i]] += 1
    return rank


KERNELS = (
    (pixel_ranks, "(int64[::1], int64)"),
    (claim_faces, "(int32[:, ::1], int64[::1], int64[::1], int32[:, ::1], int64)"),
    (_pixel_charts, "(int64[:, ::1], int64[::1], int64)"),
    (_chart_corners, "(int64[:, ::1], int64[::1], int64[::1], int64[::1], int64)"),
    (fill_charts, "(int32[:, :, ::1], uint8[:, ::1])"),
)
"""The kernels ``make`` runs here and the argument types it gives them, compiled ahead
by :func:`photo3d.kernels.compile_kernels` (``tests/test_kernels.py`` checks ``make``
gives no others)."""
