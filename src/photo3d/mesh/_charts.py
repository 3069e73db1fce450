"""Numba kernel of :mod:`photo3d.mesh.light`: texture charts for faces of hidden layers."""

from __future__ import annotations

import numpy as np
from numba import njit


def claim_faces(faces, pos, rank, images, n_layers):
    """Give every leftover face a layer image holding its three pixels
    (:func:`_claim_faces`).

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

    Raises:
        ValueError: ``images`` has no room for a new layer a face needs.

    Example:
        >>> images = np.full((2, 3), -1, np.int32)
        >>> images[0] = [0, 1, 2]
        >>> faces = np.array([[0, 1, 3]], np.int32)
        >>> pos, rank = np.array([0, 1, 2, 2]), np.array([0, 0, 0, 1])
        >>> layer, n = claim_faces(faces, pos, rank, images, 1)
        >>> layer.tolist(), n, images[1].tolist()
        ([1], 2, [0, 1, 3])
    """
    layer = np.empty(len(faces), np.int64)  # here: each allocation in a kernel compiles
    n_layers = _claim_faces(faces, pos, rank, images, n_layers, layer)
    if n_layers < 0:
        raise ValueError("no free layer image for a face")
    return layer, n_layers


@njit(cache=True, nogil=True)
def _claim_faces(faces, pos, rank, images, n_layers, layer):
    """:func:`claim_faces` into ``layer (F,) int64``; returns ``n_layers``, -1 if a face
    found no room."""
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
            return -1
        if chosen == n_layers:
            n_layers += 1
        for c in range(3):
            images[chosen, pos[faces[f, c]]] = faces[f, c]
        layer[f] = chosen
    return n_layers


def fill_charts(src, colors):
    """``(C, S, S, 3) uint8`` chart texels from pixel indices ``src (C, S, S) int32``
    (-1: none) and ``colors (N, 3) uint8``: holes take the mean of their known
    8-neighbours, twice (each round from the previous one), then the chart's mean.

    Example:
        >>> src = np.array([[[0, -1], [-1, -1]]], np.int32)
        >>> fill_charts(src, np.array([[10, 20, 30]], np.uint8))[0, 1, 1].tolist()
        [10, 20, 30]
    """
    s = src.shape[1]
    out = np.empty((*src.shape, 3), np.uint8)  # here: each allocation in a kernel compiles
    _fill_charts(src, colors, out, np.empty((2, s, s, 3)), np.empty((2, s, s), np.bool_))
    return out


@njit(cache=True, nogil=True)
def _fill_charts(src, colors, out, values, flags):
    """:func:`fill_charts` into ``out``; ``values (2, S, S, 3) float64`` and ``flags
    (2, S, S) bool``: scratch."""
    n, s = src.shape[0], src.shape[1]
    val, new = values[0], values[1]
    known, grown = flags[0], flags[1]
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
        mean0 = mean1 = mean2 = 0.0
        for y in range(s):
            for x in range(s):
                if known[y, x]:
                    cnt += 1
                    mean0 += val[y, x, 0]
                    mean1 += val[y, x, 1]
                    mean2 += val[y, x, 2]
        for y in range(s):
            for x in range(s):
                if not known[y, x]:
                    val[y, x, 0] = mean0 / max(cnt, 1)
                    val[y, x, 1] = mean1 / max(cnt, 1)
                    val[y, x, 2] = mean2 / max(cnt, 1)
                for ch in range(3):
                    out[c, y, x, ch] = np.uint8(min(max(np.rint(val[y, x, ch]), 0.0), 255.0))


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
    # two kernels around NumPy's unique: numba's np.unique would compile a sort (1 s);
    # the arrays are allocated here: each allocation in a kernel compiles
    first = np.full(n_pixels, -1, np.int64)
    span = int(chart.max()) + 2 if len(chart) else 1
    keys = np.unique(_pixel_charts(faces, chart, first, span))
    vid = np.full(n_pixels, -1, np.int64)
    pixel = np.empty(n_pixels + len(keys), np.int64)
    vchart = np.empty(n_pixels + len(keys), np.int64)
    corners = np.empty(faces.shape, np.int64)
    n_v = _chart_corners(faces, chart, first, keys, span, vid, pixel, vchart, corners)
    return corners, pixel[:n_v].copy(), vchart[:n_v].copy()  # not views: free the rest


@njit(cache=True, nogil=True)
def _pixel_charts(faces, chart, first, span):
    """Fill ``first (N,) int64`` (-1 on entry) with each pixel's chart + 1 (-1: in no
    face, -2: in several charts); returns ``(K,) int64`` the key ``pixel * span +
    chart + 1`` of every face corner at a pixel in several charts."""
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
    j = 0
    for f in range(len(faces)):
        for c in range(3):
            p = faces[f, c]
            if first[p] == -2:
                keys[j] = p * span + chart[f] + 1
                j += 1
    return keys


@njit(cache=True, nogil=True)
def _chart_corners(faces, chart, first, keys, span, vid, pixel, vchart, corners):
    """:func:`chart_vertices` from :func:`_pixel_charts`' ``first`` and its ``keys``
    sorted without repeats, into ``corners``, ``pixel[:n_v]`` and ``vchart[:n_v]``
    (``vid (N,) int64``: -1, the vertex of a one-chart pixel or the first of a
    several-chart pixel's); returns ``n_v``."""
    n_v = 0
    k = 0
    for p in range(len(first)):
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
    for f in range(len(faces)):
        for c in range(3):
            p = faces[f, c]
            v = vid[p]
            if first[p] == -2:
                while vchart[v] != chart[f] + 1:
                    v += 1
            corners[f, c] = v
    return n_v


def pixel_ranks(pos, n_positions):
    """``(N,) int64`` how many pixels before each one (in LDI order) share its position
    (``pos (N,) int64`` in ``[0, n_positions)``).

    Example:
        >>> pixel_ranks(np.array([2, 0, 2, 2, 0]), 3).tolist()
        [0, 0, 1, 2, 1]
    """
    rank = np.empty(len(pos), np.int64)  # here: each allocation in a kernel compiles
    _pixel_ranks(np.ascontiguousarray(pos, np.int64), np.zeros(n_positions, np.int64), rank)
    return rank


@njit(cache=True, nogil=True)
def _pixel_ranks(pos, seen, rank):
    """:func:`pixel_ranks` into ``rank``; ``seen (n_positions,) int64`` zeros."""
    for i in range(len(pos)):
        rank[i] = seen[pos[i]]
        seen[pos[i]] += 1


KERNELS = (
    (_pixel_ranks, "(int64[::1], int64[::1], int64[::1])"),
    (_claim_faces, "(int32[:, ::1], int64[::1], int64[::1], int32[:, ::1], int64, int64[::1])"),
    (_pixel_charts, "(int64[:, ::1], int64[::1], int64[::1], int64)"),
    (_chart_corners, "(int64[:, ::1], int64[::1], int64[::1], int64[::1], int64, int64[::1], "
                     "int64[::1], int64[::1], int64[:, ::1])"),
    (_fill_charts, "(int32[:, :, ::1], uint8[:, ::1], uint8[:, :, :, ::1], float64[:, :, :, ::1], "
                   "boolean[:, :, ::1])"),
)
"""The kernels ``make`` runs here and the argument types it gives them, compiled ahead
by :func:`photo3d.kernels.compile_kernels` (``tests/test_kernels.py`` checks ``make``
gives no others)."""
