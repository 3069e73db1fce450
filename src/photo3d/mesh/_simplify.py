"""meshoptimizer's edge-collapse simplification for :mod:`photo3d.mesh.light`, in strips.

Called through ctypes (``meshopt_simplifyWithAttributes``, for its vertex locks),
which is why ``meshoptimizer`` is capped below 0.3 in ``pyproject.toml``.
"""

from __future__ import annotations

import ctypes
import functools
from concurrent.futures import ThreadPoolExecutor

import numpy as np

_TILE_FACES = 200_000  # fewer faces than this are simplified in one piece
_TILES = 4  # vertical strips of equal face counts; 2 threads


def simplify(points: np.ndarray, faces: np.ndarray, max_error: float) -> np.ndarray:
    """``(F', 3) int64`` faces of ``points (N, 3)`` simplified by edge collapses
    (meshoptimizer: vertices keep their places; open borders and texture seams,
    i.e. vertices sharing a position, collapse only along themselves).

    Four vertical strips of equal face counts are simplified by two threads
    (meshoptimizer's C code runs without the GIL), with the vertices strips share
    locked so they still meet without cracks: on the sample 2.5 times faster than one
    piece for 5 % more triangles (smaller pieces also stay in the cache). The strips
    depend only on the mesh, so the result does not depend on the machine.
    """
    if max_error <= 0 or not len(faces):
        return faces
    points = np.ascontiguousarray(points, np.float32)
    if len(faces) < _TILE_FACES:
        return _simplify_part(points, faces, None, max_error)
    x = points[:, 0]
    cuts = np.quantile(x[faces[:, 0]], np.linspace(0, 1, _TILES + 1)[1:-1])
    side = np.searchsorted(cuts, x, side="right")  # tile of each vertex
    tile = side[faces[:, 0]]
    lock = np.zeros(len(points), np.uint8)
    lock[faces[side[faces] != tile[:, None]]] = 1  # used by faces of two strips
    with ThreadPoolExecutor(max_workers=2) as pool:
        parts = list(pool.map(lambda t: _simplify_part(points, faces[tile == t], lock,
                                                       max_error), range(_TILES)))
    return np.concatenate(parts)


def _simplify_part(points: np.ndarray, faces: np.ndarray, lock: np.ndarray | None,
                   max_error: float) -> np.ndarray:
    """meshoptimizer's ``meshopt_simplifyWithAttributes`` (no attributes) on ``faces``
    of the vertex buffer ``points``, with the vertices where ``lock`` is 1 fixed
    (None: none)."""
    fn = _simplifier()
    import meshoptimizer

    indices = np.ascontiguousarray(faces.ravel(), np.uint32)
    out = np.empty_like(indices)
    options = meshoptimizer.SIMPLIFY_ERROR_ABSOLUTE
    if lock is not None:
        options |= meshoptimizer.SIMPLIFY_SPARSE  # faces use a part of the vertex buffer
    uint_p, float_p = ctypes.POINTER(ctypes.c_uint), ctypes.POINTER(ctypes.c_float)
    n = fn(out.ctypes.data_as(uint_p), indices.ctypes.data_as(uint_p), len(indices),
           points.ctypes.data_as(float_p), len(points), points.strides[0], None, 0, None, 0,
           None if lock is None else lock.ctypes.data_as(ctypes.POINTER(ctypes.c_ubyte)), 0,
           max_error, options, None)
    return out[:n].reshape(-1, 3).astype(np.int64)


@functools.cache
def _simplifier():
    """``meshopt_simplifyWithAttributes`` of meshoptimizer's library, with its C
    signature declared (the Python wrapper declares none for it; a private function
    object, so the wrapper's own declarations stay as they are)."""
    try:
        from meshoptimizer._loader import lib
    except ImportError as err:  # pragma: no cover - core dependency
        raise ImportError("the light mesh needs meshoptimizer: pip install meshoptimizer") from err
    fn = lib["meshopt_simplifyWithAttributes"]
    uint_p, float_p = ctypes.POINTER(ctypes.c_uint), ctypes.POINTER(ctypes.c_float)
    size, byte_p = ctypes.c_size_t, ctypes.POINTER(ctypes.c_ubyte)
    fn.restype = size
    fn.argtypes = [uint_p, uint_p, size, float_p, size, size, float_p, size, float_p, size,
                   byte_p, size, ctypes.c_float, ctypes.c_uint, float_p]
    return fn
