"""The planar-block merge that runs before the simplifier (photo3d.mesh._planar)."""

from __future__ import annotations

from collections import Counter

import numpy as np

from photo3d.mesh.full import build_mesh
from photo3d.mesh.light import _merge_planar
from photo3d.stages.ldi import from_image


def _merged(disparity: np.ndarray, eps: float):
    """(faces before, faces after, pixel x, pixel y) for a one-layer LDI."""
    ldi = from_image(np.full((*disparity.shape, 3), 0.5, np.float32),
                     disparity.astype(np.float32))
    full = build_mesh(ldi)
    rows, cols = ldi.lattice_shape
    pos = ldi.positions()
    images = np.full((1, rows * cols), -1, np.int32)
    images[0, pos] = np.arange(ldi.size)
    faces = full.faces.astype(np.int64)
    value = 100.0 / full.vertices[:, 2]
    out, layer = _merge_planar(faces, np.zeros(len(faces), np.int64), pos, (rows, cols),
                               images, value, eps)
    assert (layer == 0).all()
    py, px = np.divmod(pos, cols)
    return faces, out, px, py


def _signed_areas(faces, px, py):
    a, b, c = faces[:, 0], faces[:, 1], faces[:, 2]
    return 0.5 * ((px[b] - px[a]) * (py[c] - py[a]) - (py[b] - py[a]) * (px[c] - px[a]))


def _open_edges(faces):
    """Undirected edges used by one face only: the outline of the mesh."""
    count = Counter()
    for f in faces:
        for i in range(3):
            count[tuple(sorted((int(f[i]), int(f[(i + 1) % 3]))))] += 1
    return {e for e, n in count.items() if n == 1}


def test_planar_blocks_become_fans_with_the_same_outline_and_winding():
    """A tilted plane with a depth step: far fewer triangles, same covered area, one
    winding, and the same outline: open edges only along the old outline, of the same
    total length (a crack or T-junction inside would add open edges)."""
    yy, xx = np.mgrid[0:70, 0:90].astype(np.float64)
    disparity = 0.5 + 0.003 * xx + 0.002 * yy  # linear in the image: a plane in 3D
    disparity[:, 45:] *= 0.5  # a depth edge: the mesh splits there
    before, after, px, py = _merged(disparity, 0.01)
    assert len(after) < len(before) / 3
    area_before, area_after = _signed_areas(before, px, py), _signed_areas(after, px, py)
    assert np.all(np.sign(area_after) == np.sign(area_before[0]))
    assert np.all(area_after != 0)
    assert abs(area_after.sum() - area_before.sum()) < 1e-6
    open_before, open_after = _open_edges(before), _open_edges(after)
    on_outline = {v for e in open_before for v in e}
    assert {v for e in open_after for v in e} <= on_outline
    assert len(open_after) < len(open_before)  # collinear outline pixels dropped

    def length(edges):
        return sum(np.hypot(px[a] - px[b], py[a] - py[b]) for a, b in edges)

    assert abs(length(open_after) - length(open_before)) < 1e-9


def test_neighbouring_blocks_share_their_edges_without_middle_pixels():
    """A whole plane: the blocks' fans keep only pixels that are some block's corner
    (or a kept face's vertex), and every inner edge is shared by two faces."""
    yy, xx = np.mgrid[0:65, 0:65].astype(np.float64)
    before, after, px, py = _merged(0.5 + 0.002 * xx + 0.001 * yy, 0.01)
    # 64 x 64 quads: four 32-blocks, each a fan from its centre to its 4 corners
    # plus the corners of its neighbours that lie on its border (none here)
    assert len(after) == 4 * 4
    assert len(_open_edges(after)) == 8


def test_curved_surfaces_are_left_alone():
    """Random depth is planar nowhere: every face is kept as it is."""
    disparity = 0.5 + 0.5 * np.random.default_rng(0).random((40, 50))
    before, after, _, _ = _merged(disparity, 0.01)
    np.testing.assert_array_equal(np.sort(after, axis=0), np.sort(before, axis=0))
