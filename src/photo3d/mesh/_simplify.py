"""Edge-collapse simplification to an absolute error bound for :mod:`photo3d.mesh.light`.

A numba port of the edge-collapse simplifier of meshoptimizer
(``meshopt_simplifyWithAttributes`` with ``meshopt_SimplifyErrorAbsolute`` and
vertex locks, positions only; zeux/meshoptimizer, Copyright (c) 2016-2025 Arseny
Kapoulkine, MIT licence, reproduced in THIRD_PARTY_NOTICES.md): it ships with
photo3d, so the light mesh needs no compiler and no private API of a binding.

How it works (as in meshoptimizer): every vertex gets a kind from the topology
(manifold; border: on one open-edge loop; seam: one of two vertices at one place,
each on an open loop that the other closes, i.e. a texture seam; locked: anything
else, or locked by the caller). A vertex is collapsed onto a neighbour (it is
removed and its triangles go to the neighbour, which stays where it is); borders and
seams only collapse along their own loop, a seam together with its partner. The cost
of a collapse is the quadric error of the moved vertex at its new place: the
weighted mean of the squared distances to the planes of the triangles it has
gathered (weight ``sqrt(area)``) and, for border and seam edges, to the planes
through the edge perpendicular to them (border weight 10). Passes collapse the
cheapest edges first, at most one per vertex and pass, without flipping a triangle,
until no collapse is cheaper than ``max_error ** 2``.

Not in meshoptimizer (``drift=True``, what the light mesh uses): no collapse may
make an edge along which the texture drifts by more than ``max_error``, i.e. where
the photo's pixel positions, interpolated linearly in 3D as the renderer does, part
from where the input view sees them. Large triangles on surfaces slanted in depth
keep their size down: on the sample (32 frames of the four paths at 640x360) 4.6 %
more triangles than without it and frames 3.5 dB closer to the full mesh's, where
meshoptimizer needed 10 % more triangles (a 0.45 px bound) for 1.6 dB.
"""

from __future__ import annotations

import numpy as np

from photo3d.mesh._collapse import collapse_part
from photo3d.parallel import map_ordered

_TILE_FACES = 200_000  # fewer faces than this are simplified in one piece
_TILES = 4  # vertical strips of equal face counts, simplified on the budget's threads



def simplify(points: np.ndarray, faces: np.ndarray, max_error: float, *,
             position: np.ndarray | None = None, lock: np.ndarray | None = None,
             drift: bool = False) -> np.ndarray:
    """``(F', 3) int64`` faces of ``points`` simplified by edge collapses.

    Vertices keep their places; open borders and texture seams (vertices sharing a
    position) collapse only along themselves; the surface moves by about
    ``max_error`` at most (root mean square over the planes a vertex gathered).

    Four vertical strips of equal face counts are simplified by up to four threads (the
    numba kernel runs without the GIL), with the vertices strips share locked so they
    still meet without cracks: on the sample 0.57 s against 1.3 s for one piece, for
    6 % more triangles. The strips depend only on the mesh, so the result does not
    depend on the machine.

    Args:
        points: ``(N, 3) float`` vertex positions.
        faces: ``(F, 3) int`` vertex indices.
        max_error: the bound, in the units of ``points``; <= 0 returns ``faces``.
        position: ``(N,) int`` the same id for vertices at the same place (seams);
            None: vertices with equal ``points`` rows.
        lock: ``(N,) bool`` vertices that must stay (None: none).
        drift: ``points`` are ``(column, row, v)`` with ``v`` proportional to inverse
            depth (> 0), the pixel positions are the texture coordinates, and the
            texture must not drift by more than ``max_error`` either: no collapse
            may make an edge along which the photo and the texture the renderer
            interpolates (linearly in 3D) part by more than that.

    Example:
        >>> yy, xx = np.mgrid[0:4, 0:4]
        >>> points = np.stack([xx.ravel(), yy.ravel(), np.zeros(16)], 1)
        >>> q = (np.arange(3)[:, None] * 4 + np.arange(3)).ravel()
        >>> faces = np.concatenate([np.stack([q, q + 4, q + 1], 1),
        ...                         np.stack([q + 1, q + 4, q + 5], 1)])
        >>> len(faces), len(simplify(points, faces, 0.1))
        (18, 2)
    """
    if max_error <= 0 or not len(faces):
        return faces
    points = np.ascontiguousarray(points, np.float64)
    faces = np.ascontiguousarray(faces, np.int64)
    if position is None:
        position = np.unique(points, axis=0, return_inverse=True)[1].ravel()
    first = np.full(int(position.max()) + 1, len(points), np.int64)
    np.minimum.at(first, position, np.arange(len(points)))
    leader = first[position]  # the lowest vertex at each vertex's place
    limit = float(max_error) ** 2
    bound = float(max_error) if drift else 0.0  # on the texture drift; 0: none
    lock = np.zeros(len(points), np.bool_) if lock is None else np.array(lock, np.bool_)
    if len(faces) < _TILE_FACES:
        return collapse_part(points, faces, leader, lock, limit, bound)
    x = points[:, 0]
    cuts = np.quantile(x[faces[:, 0]], np.linspace(0, 1, _TILES + 1)[1:-1])
    side = np.searchsorted(cuts, x, side="right")  # strip of each vertex
    tile = side[faces[:, 0]]
    lock[faces[side[faces] != tile[:, None]]] = True  # used by faces of two strips
    parts = list(map_ordered(
        lambda t: collapse_part(points, faces[tile == t], leader, lock, limit, bound),
        range(_TILES), name="simplify"))
    return np.concatenate(parts)
