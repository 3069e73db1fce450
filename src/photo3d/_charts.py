"""Numba kernel of :mod:`photo3d.light`: texture charts for faces of hidden layers."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
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
