"""Gaussian splats of a 3D photo: one Gaussian per LDI pixel, written as
``splats.ply`` (:mod:`photo3d.io.splat_ply`), ``splats.spz`` (:mod:`photo3d.io.spz`)
and ``splats.glb`` (:mod:`photo3d.io.splat_glb`).

Every pixel of the layered depth image becomes a splat, the input photo's and the
inpainted layers' alike, with the border: its centre is the pixel's 3D point (the
vertex of :mod:`photo3d.mesh.full`), its colour the pixel's, and its size the
pixel's footprint at its depth (``z / fx`` by ``z / fy``: one pixel of the input
view) times :data:`FOOTPRINT`, a flat disc facing the camera (the third axis
:data:`THICKNESS` times as thick). Seen from the input camera the splats of
neighbouring pixels overlap as the mesh's triangles join them; opacity is
:data:`OPACITY` (times the LDI pixel's alpha: a soft silhouette's fringe is translucent),
so the splats nearest the camera hide what lies behind them.

``merge=True`` joins, in up to :data:`MERGE_LEVELS` rounds, the linked 2 x 2 blocks
of a flat, smooth area (colours within :data:`MERGE_COLOR`, depths planar and
within :data:`MERGE_DEPTH` of each other, relatively) into one splat twice as large:
fewer splats where they add nothing. On the bundled sample: see docs/outputs.md.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from photo3d.camera import unproject
from photo3d.files.atomic import atomic_path
from photo3d.io.splat_glb import write_splat_glb
from photo3d.io.splat_ply import write_splat_ply
from photo3d.io.spz import write_spz as write_spz_file
from photo3d.structures.ldi import LDI
from photo3d.structures.splats import Splats

FOOTPRINT = 0.6
"""Standard deviation of a splat across the view, in pixels of the input view."""
THICKNESS = 0.1
"""Standard deviation along the view axis, relative to the one across it."""
OPACITY = 0.99
"""Peak opacity of every splat."""
MERGE_LEVELS = 3
"""Rounds of 2 x 2 merging (``merge=True``): up to 8 x 8 pixels in one splat."""
MERGE_COLOR = 6 / 255
"""Largest colour range (per channel, sRGB) inside a merged block."""
MERGE_DEPTH = 0.01
"""Largest depth range inside a merged block, relative to its depth, and largest
departure of its corners from a plane (``|z00 + z11 - z01 - z10| / z``). It bounds
the parallax error of the merged splat: at most ``fx * t * MERGE_DEPTH / z`` pixels
for a camera moved by ``t`` (under a pixel for the circle path beyond z = 1)."""

SHARPEN = 1.5

PLY_NAME, SPZ_NAME, GLB_NAME = "splats.ply", "splats.spz", "splats.glb"
_RIGHT, _DOWN = 1, 3


def build_splats(ldi: LDI, *, merge: bool = False) -> Splats:
    """The Gaussian splats of ``ldi`` (see the module doc), in the input camera's
    frame (OpenCV axes).

    Args:
        ldi: the 3D photo's layered depth image.
        merge: join flat, smooth 2 x 2 blocks into larger splats (fewer splats).

    Returns:
        :class:`~photo3d.structures.splats.Splats` with ``ldi.size`` splats (fewer
        with ``merge``), front and inpainted layers alike.

    Example:
        >>> import numpy as np, photo3d
        >>> photo = photo3d.make(np.full((16, 16, 3), 0.5), depth=np.ones((16, 16)),
        ...                      config=photo3d.Config(size=None))
        >>> len(build_splats(photo.ldi)) == photo.ldi.size
        True
        >>> len(build_splats(photo.ldi, merge=True)) < photo.ldi.size / 2  # flat and grey
        True
    """
    k = ldi.intrinsics
    z = ldi.depth()
    positions = unproject(ldi.x, ldi.y, z, k)
    colors = np.asarray(ldi.color, np.float32)
    size = np.ones(len(z), np.float32)  # side of the block a splat stands for, pixels
    alpha = np.asarray(ldi.alpha, np.float32)  # soft silhouettes: opacity * coverage
    if merge:
        positions, colors, z, size, alpha = _merge(ldi, positions, colors, z)
    scales = np.empty((len(z), 3), np.float32)
    scales[:, 0] = FOOTPRINT * size * z / k.fx
    scales[:, 1] = FOOTPRINT * size * z / k.fy
    scales[:, 2] = THICKNESS * scales[:, :2].mean(axis=1)
    rotations = np.zeros((len(z), 4), np.float32)
    rotations[:, 0] = 1.0
    return Splats(positions=positions, colors=colors,
                  opacity=(OPACITY * alpha).astype(np.float32), scales=scales,
                  rotations=rotations)


def write_ply(ldi: LDI, path: str | Path, *, merge: bool = False,
              splats: Splats | None = None) -> None:
    """Write ``splats.ply``, the 3DGS PLY of ``ldi``'s splats, to ``path`` atomically.

    ``splats``: :func:`build_splats` of ``ldi`` (with ``merge``) if already built.

    Example:
        >>> import numpy as np, photo3d, pathlib, tempfile
        >>> photo = photo3d.make(np.full((8, 8, 3), 0.5), depth=np.ones((8, 8)),
        ...                      config=photo3d.Config(size=None))
        >>> path = pathlib.Path(tempfile.mkdtemp()) / PLY_NAME
        >>> write_ply(photo.ldi, path)
        >>> from photo3d.io.splat_ply import read_splat_ply
        >>> len(read_splat_ply(path)) == photo.ldi.size
        True
    """
    splats = build_splats(ldi, merge=merge) if splats is None else splats
    with atomic_path(path) as tmp:
        write_splat_ply(tmp, splats)


def write_spz(ldi: LDI, path: str | Path, *, merge: bool = False,
              splats: Splats | None = None) -> None:
    """Write ``splats.spz``, Niantic's compressed splats of ``ldi``, to ``path``
    atomically (version 2, see :mod:`photo3d.io.spz`); ``splats`` as :func:`write_ply`.

    Example:
        >>> import numpy as np, photo3d, pathlib, tempfile
        >>> photo = photo3d.make(np.full((8, 8, 3), 0.5), depth=np.ones((8, 8)),
        ...                      config=photo3d.Config(size=None))
        >>> path = pathlib.Path(tempfile.mkdtemp()) / SPZ_NAME
        >>> write_spz(photo.ldi, path)
        >>> from photo3d.io.spz import read_spz
        >>> len(read_spz(path)) == photo.ldi.size
        True
    """
    splats = build_splats(ldi, merge=merge) if splats is None else splats
    with atomic_path(path) as tmp:
        write_spz_file(tmp, splats)


def write_glb(ldi: LDI, path: str | Path, *, merge: bool = False,
              splats: Splats | None = None) -> None:
    """Write ``splats.glb``, the splats of ``ldi`` as glTF with
    ``KHR_gaussian_splatting``, to ``path`` atomically (the input view as its camera);
    ``splats`` as :func:`write_ply`.

    Example:
        >>> import numpy as np, photo3d, pathlib, tempfile
        >>> photo = photo3d.make(np.full((8, 8, 3), 0.5), depth=np.ones((8, 8)),
        ...                      config=photo3d.Config(size=None))
        >>> path = pathlib.Path(tempfile.mkdtemp()) / GLB_NAME
        >>> write_glb(photo.ldi, path)
        >>> path.read_bytes()[:4]
        b'glTF'
    """
    splats = build_splats(ldi, merge=merge) if splats is None else splats
    with atomic_path(path) as tmp:
        write_splat_glb(tmp, splats, intrinsics=ldi.intrinsics)


def splat_count(path: str | Path) -> int | None:
    """The number of splats in a ``.ply``, ``.spz`` or ``.glb`` splat file, read from
    its header; None for another file or one that is not a splat file.

    Example:
        >>> import numpy as np, photo3d, pathlib, tempfile
        >>> photo = photo3d.make(np.full((8, 8, 3), 0.5), depth=np.ones((8, 8)),
        ...                      config=photo3d.Config(size=None))
        >>> path = pathlib.Path(tempfile.mkdtemp()) / SPZ_NAME
        >>> write_spz(photo.ldi, path)
        >>> splat_count(path) == photo.ldi.size, splat_count(path.with_suffix(".txt"))
        (True, None)
    """
    import gzip
    import struct

    from photo3d.errors import InputError
    from photo3d.io.glb import read_chunks
    from photo3d.io.splat_glb import EXTENSION

    path = Path(path)
    try:
        if path.suffix == ".ply":
            with open(path, "rb") as file:
                head = file.read(4096).split(b"end_header")[0].decode("ascii", "replace")
            words = [line.split() for line in head.splitlines()]
            return next(int(w[2]) for w in words if w[:2] == ["element", "vertex"])
        if path.suffix == ".spz":
            with gzip.open(path, "rb") as file:
                return struct.unpack("<III", file.read(12))[2]
        if path.suffix == ".glb":
            document = read_chunks(path)[0]
            primitive = document["meshes"][0]["primitives"][0]
            if EXTENSION in primitive.get("extensions", {}):
                return int(document["accessors"][primitive["attributes"]["POSITION"]]["count"])
    except (OSError, InputError, EOFError, StopIteration, ValueError, KeyError,
            IndexError, TypeError, struct.error):
        return None
    return None


def _merge(ldi: LDI, positions: np.ndarray, colors: np.ndarray,
           z: np.ndarray) -> tuple[np.ndarray, ...]:
    """Join flat, smooth, linked 2 x 2 blocks, :data:`MERGE_LEVELS` times.

    A block at level ``L`` is ``2**L`` pixels on a side, anchored at its top-left
    pixel, whose lattice position is a multiple of ``2**L``; four blocks of level
    ``L - 1`` become one when their anchors are linked as a square (walking the LDI's
    links ``2**(L - 1)`` steps right and down) and the union is flat and smooth.

    Returns the positions, colours, depths, block sides (pixels) and alphas of the
    splats (a block with a soft silhouette's pixel is never joined).
    """
    n = ldi.size
    links = ldi.links
    b = ldi.border
    block = np.zeros(n, np.int32)  # level of the block a pixel anchors; -1: absorbed
    pos = positions.astype(np.float64)
    col = colors.astype(np.float64)
    lo_c, hi_c = col.copy(), col.copy()
    lo_z, hi_z = z.astype(np.float64), z.astype(np.float64)
    for level in range(1, MERGE_LEVELS + 1):
        step, side = 1 << (level - 1), 1 << level
        p = np.flatnonzero((block == level - 1) & ((ldi.y + b) % side == 0)
                           & ((ldi.x + b) % side == 0))
        q = _walk(links, p, _RIGHT, step)
        r = _walk(links, p, _DOWN, step)
        s = _walk(links, q, _DOWN, step)
        ok = (q >= 0) & (r >= 0) & (s >= 0)
        p, q, r, s = p[ok], q[ok], r[ok], s[ok]
        ok = (_walk(links, r, _RIGHT, step) == s) & (block[q] == level - 1) \
            & (block[r] == level - 1) & (block[s] == level - 1)
        p, q, r, s = p[ok], q[ok], r[ok], s[ok]
        quad = np.stack([p, q, r, s])
        c_range = hi_c[quad].max(axis=0) - lo_c[quad].min(axis=0)
        zs = (lo_z[quad] + hi_z[quad]) / 2
        limit = MERGE_DEPTH * zs.mean(axis=0)
        flat = (np.abs(zs[0] + zs[3] - zs[1] - zs[2]) <= limit) & (
            hi_z[quad].max(axis=0) - lo_z[quad].min(axis=0) <= limit)
        ok = flat & (c_range.max(axis=1) <= MERGE_COLOR) & (ldi.alpha[quad].min(axis=0) >= 1.0)
        p, quad = p[ok], quad[:, ok]
        pos[p] = pos[quad].mean(axis=0)
        col[p] = col[quad].mean(axis=0)
        lo_c[p], hi_c[p] = lo_c[quad].min(axis=0), hi_c[quad].max(axis=0)
        lo_z[p], hi_z[p] = lo_z[quad].min(axis=0), hi_z[quad].max(axis=0)
        block[quad[1:].ravel()] = -1
        block[p] = level
        if len(p) == 0:
            break
    keep = np.flatnonzero(block >= 0)
    z_out = pos[keep, 2]
    return (pos[keep].astype(np.float32), col[keep].astype(np.float32),
            z_out.astype(np.float32), (1 << block[keep]).astype(np.float32),
            np.asarray(ldi.alpha, np.float32)[keep])


def _walk(links: np.ndarray, start: np.ndarray, direction: int, steps: int) -> np.ndarray:
    """The pixels ``steps`` links from ``start`` in ``direction`` (-1 where a link
    is missing)."""
    at = start.copy()
    for _ in range(steps):
        good = at >= 0
        at[good] = links[at[good], direction]
    return at
