"""Gaussian splats of a 3D photo, written as ``splats.ply``
(:mod:`photo3d.io.splat_ply`), ``splats.spz`` (:mod:`photo3d.io.spz`) and
``splats.glb`` (:mod:`photo3d.io.splat_glb`).

Every pixel of the layered depth image is covered by a splat, the input photo's and
the inpainted layers' alike, with the border. Two layouts (``density=``):

* ``"dense"``: one splat per LDI pixel. Its centre is the pixel's 3D point (the
  vertex of :mod:`photo3d.mesh.full`), its colour the pixel's, and its size the
  pixel's footprint at its depth (``z / fx`` by ``z / fy``: one pixel of the input
  view) times :data:`FOOTPRINT`, a flat disc facing the camera (the third axis
  :data:`THICKNESS` times as thick).
* ``"adaptive"`` (the default): one splat per pixel where there is texture and at
  depth edges, and fewer, larger splats where the colour is flat and the surface
  planar: the quadtree of :mod:`photo3d.export.splat_blocks` joins linked 2 x 2
  blocks, up to :data:`ADAPTIVE_LEVELS` rounds, while their colours stay within
  :data:`ADAPTIVE_COLOR` (:data:`HIDDEN_COLOR` on the inpainted layers and the
  border, which the input view does not show) and their inverse depths within
  :data:`ADAPTIVE_DEPTH` of a plane. A joined block's splat spans the block on its
  plane: anisotropic and tilted as the surface is.

The opacity of every splat comes from :func:`splat_opacity`, which takes a per-pixel
coverage: the soft silhouettes of depth edges (``LDI.alpha``; a joined block takes its
pixels' mean, and such pixels lie on edges, where blocks are hardly ever joined).
A fully covered pixel's splat is :data:`OPACITY`.

How Spark shows them, and what was tried to make it sharper: docs/outputs.md.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from photo3d.camera import Intrinsics, unproject
from photo3d.errors import ConfigError
from photo3d.export.splat_blocks import Blocks, block_gaussians, merge_blocks
from photo3d.files.atomic import atomic_path
from photo3d.io.splat_glb import write_splat_glb
from photo3d.io.splat_ply import write_splat_ply
from photo3d.io.spz import DEFAULT_VERSION
from photo3d.io.spz import write_spz as write_spz_file
from photo3d.structures.ldi import LDI
from photo3d.structures.splats import Splats

FOOTPRINT = 0.6
"""Standard deviation of a splat across the view, in pixels of the input view (of
its block's side for a joined block)."""
THICKNESS = 0.1
"""Standard deviation along the view axis (the surface's normal), relative to the
ones across it."""
OPACITY = 0.99
"""Peak opacity of a splat whose pixels are fully covered."""
DENSITIES = ("adaptive", "dense")
"""The splat layouts (``density=``, ``--splats``), the default first."""
ADAPTIVE_LEVELS = 4
"""Rounds of 2 x 2 joining: blocks up to 16 x 16 pixels in one splat."""
ADAPTIVE_COLOR = 13 / 255
"""Largest colour range (per channel, sRGB) inside a joined block of the photo."""
HIDDEN_COLOR = 32 / 255
"""The same on the inpainted layers and the extrapolated border."""
ADAPTIVE_DEPTH = 0.01
"""Largest departure of a block's inverse depth from a plane, relative: it bounds
the parallax error of a joined splat to about ``fx * t * ADAPTIVE_DEPTH / z``
pixels for a camera moved by ``t`` (under a pixel for the circle path beyond z = 1)."""

PLY_NAME, SPZ_NAME, GLB_NAME = "splats.ply", "splats.spz", "splats.glb"
_FRONT = (1,)  # LDI labels of the photo's own pixels


def build_splats(ldi: LDI, *, density: str = "adaptive",
                 alpha: np.ndarray | None = None, fit: bool = False) -> Splats:
    """The Gaussian splats of ``ldi`` (see the module doc), in the input camera's
    frame (OpenCV axes).

    Args:
        ldi: the 3D photo's layered depth image.
        density: ``"adaptive"`` (fewer, larger splats where the colour is flat and
            the surface planar) or ``"dense"`` (one splat per LDI pixel).
        alpha: ``(N,) float`` in [0, 1], each LDI pixel's coverage; None: the LDI's
            own (``ldi.alpha``: its soft silhouettes).
        fit: fit the colours to photo3d's render of the input view through Spark's
            blend of all splats (:mod:`photo3d.export.splat_fit`: sharper in splat
            viewers, about 1.2 s more on the bundled sample; the exports do, unless
            told not to).

    Returns:
        :class:`~photo3d.structures.splats.Splats`: ``ldi.size`` splats (dense), or
        fewer (adaptive), front and inpainted layers alike.

    Raises:
        ConfigError: an unknown ``density``.

    Example:
        >>> import numpy as np, photo3d
        >>> photo = photo3d.make(np.full((16, 16, 3), 0.5), depth=np.ones((16, 16)),
        ...                      config=photo3d.Config(size=None))
        >>> len(build_splats(photo.ldi, density="dense")) == photo.ldi.size
        True
        >>> len(build_splats(photo.ldi)) < photo.ldi.size / 2  # flat and grey
        True
    """
    if density not in DENSITIES:
        raise ConfigError(f"splat density must be one of {', '.join(DENSITIES)}, "
                          f"got {density!r}")
    k = ldi.intrinsics
    z = ldi.depth()
    positions = unproject(ldi.x, ldi.y, z, k)
    colors = np.asarray(ldi.color, np.float32)
    opacity = splat_opacity(ldi.size, ldi.alpha if alpha is None else alpha)
    if density == "dense":
        scales = _facing(z, k, np.ones(len(z), np.float32))
        rotations = np.tile(np.array([1, 0, 0, 0], np.float32), (len(z), 1))
        splats = Splats(positions=positions, colors=colors, opacity=opacity,
                        scales=scales, rotations=rotations)
        return _fitted(ldi, splats) if fit else splats
    front = np.isin(ldi.label, _FRONT)
    blocks = merge_blocks(ldi, positions, colors, opacity, levels=ADAPTIVE_LEVELS,
                          color_tolerance=np.where(front, ADAPTIVE_COLOR, HIDDEN_COLOR),
                          depth_tolerance=ADAPTIVE_DEPTH)
    single = blocks.level == 0
    parts = [
        _single(positions[blocks.pixel[single]], colors[blocks.pixel[single]],
                blocks.opacity[single], z[blocks.pixel[single]], k),
        _joined(blocks, ~single),
    ]
    splats = Splats(*(np.concatenate([part[i] for part in parts]) for i in range(5)))
    return _fitted(ldi, splats) if fit else splats


def _fitted(ldi: LDI, splats: Splats) -> Splats:
    """``splats`` with their colours fitted to photo3d's render of the input view
    (:mod:`photo3d.export.splat_fit`)."""
    from photo3d.camera import Camera
    from photo3d.export.splat_fit import fit_colors, input_view

    color, covered = input_view(ldi)
    return fit_colors(splats, Camera(ldi.intrinsics, np.eye(4)), color, covered)


def _single(positions: np.ndarray, colors: np.ndarray, opacity: np.ndarray,
            z: np.ndarray, k: Intrinsics) -> tuple[np.ndarray, ...]:
    """The splat arrays of single pixels: discs facing the camera."""
    rotations = np.tile(np.array([1, 0, 0, 0], np.float32), (len(z), 1))
    return positions, colors, opacity, _facing(z, k, np.ones(len(z), np.float32)), rotations


def _joined(blocks: Blocks, chosen: np.ndarray) -> tuple[np.ndarray, ...]:
    """The splat arrays of the ``chosen`` blocks: each spanning its block on its
    plane."""
    side = (1 << blocks.level[chosen].astype(np.int64))[:, None] * FOOTPRINT
    scales, rotations = block_gaussians(blocks.axis_u[chosen] * side,
                                        blocks.axis_v[chosen] * side, thickness=THICKNESS)
    return (blocks.positions[chosen], blocks.colors[chosen],
            blocks.opacity[chosen], scales, rotations)


def splat_opacity(count: int, alpha: np.ndarray | None = None) -> np.ndarray:
    """``(count,) float32`` peak opacity of the splats of ``count`` LDI pixels:
    :data:`OPACITY` times the pixels' coverage ``alpha`` (``(count,)`` in [0, 1];
    None: 1, every pixel fully covered). The one place splat opacity is decided, so
    the soft silhouettes of depth edges carry into every splat format.

    Example:
        >>> splat_opacity(2, np.array([1.0, 0.5])) / OPACITY
        array([1. , 0.5], dtype=float32)
    """
    if alpha is None:
        return np.full(count, OPACITY, np.float32)
    alpha = np.asarray(alpha, np.float32)
    if alpha.shape != (count,):
        raise ConfigError(f"alpha has shape {alpha.shape}, expected ({count},)")
    return (OPACITY * np.clip(alpha, 0, 1)).astype(np.float32)


def _facing(z: np.ndarray, k: Intrinsics, size: np.ndarray) -> np.ndarray:
    """``(M, 3) float32`` scales of discs facing the camera, ``size`` pixels wide."""
    scales = np.empty((len(z), 3), np.float32)
    scales[:, 0] = FOOTPRINT * size * z / k.fx
    scales[:, 1] = FOOTPRINT * size * z / k.fy
    scales[:, 2] = THICKNESS * scales[:, :2].mean(axis=1)
    return scales


def write_ply(ldi: LDI, path: str | Path, *, density: str = "adaptive",
              splats: Splats | None = None, fit: bool = True) -> None:
    """Write ``splats.ply``, the 3DGS PLY of ``ldi``'s splats, to ``path`` atomically.

    ``density`` and ``fit``: as :func:`build_splats` (but fitted unless ``fit`` is
    False, as ``photo3d export`` writes them); ``splats``: :func:`build_splats` of
    ``ldi`` if already built.

    Example:
        >>> import numpy as np, photo3d, pathlib, tempfile
        >>> photo = photo3d.make(np.full((8, 8, 3), 0.5), depth=np.ones((8, 8)),
        ...                      config=photo3d.Config(size=None))
        >>> path = pathlib.Path(tempfile.mkdtemp()) / PLY_NAME
        >>> write_ply(photo.ldi, path, density="dense")
        >>> from photo3d.io.splat_ply import read_splat_ply
        >>> len(read_splat_ply(path)) == photo.ldi.size
        True
    """
    splats = build_splats(ldi, density=density, fit=fit) if splats is None else splats
    with atomic_path(path) as tmp:
        write_splat_ply(tmp, splats)


def write_spz(ldi: LDI, path: str | Path, *, density: str = "adaptive",
              splats: Splats | None = None, spz_version: int = DEFAULT_VERSION,
              fit: bool = True) -> None:
    """Write ``splats.spz``, Niantic's compressed splats of ``ldi``, to ``path``
    atomically: SPZ version ``spz_version`` (3: gzip, or 4: zstd streams, see
    :mod:`photo3d.io.spz`); ``density``, ``fit`` and ``splats`` as :func:`write_ply`.

    Example:
        >>> import numpy as np, photo3d, pathlib, tempfile
        >>> photo = photo3d.make(np.full((8, 8, 3), 0.5), depth=np.ones((8, 8)),
        ...                      config=photo3d.Config(size=None))
        >>> path = pathlib.Path(tempfile.mkdtemp()) / SPZ_NAME
        >>> write_spz(photo.ldi, path, density="dense")
        >>> from photo3d.io.spz import read_spz
        >>> len(read_spz(path)) == photo.ldi.size
        True
    """
    splats = build_splats(ldi, density=density, fit=fit) if splats is None else splats
    with atomic_path(path) as tmp:
        write_spz_file(tmp, splats, version=spz_version)


def write_glb(ldi: LDI, path: str | Path, *, density: str = "adaptive",
              splats: Splats | None = None, fit: bool = True) -> None:
    """Write ``splats.glb``, the splats of ``ldi`` as glTF with
    ``KHR_gaussian_splatting``, to ``path`` atomically (the input view as its camera);
    ``density``, ``fit`` and ``splats`` as :func:`write_ply`.

    Example:
        >>> import numpy as np, photo3d, pathlib, tempfile
        >>> photo = photo3d.make(np.full((8, 8, 3), 0.5), depth=np.ones((8, 8)),
        ...                      config=photo3d.Config(size=None))
        >>> path = pathlib.Path(tempfile.mkdtemp()) / GLB_NAME
        >>> write_glb(photo.ldi, path)
        >>> path.read_bytes()[:4]
        b'glTF'
    """
    splats = build_splats(ldi, density=density, fit=fit) if splats is None else splats
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
        >>> write_spz(photo.ldi, path, density="dense")
        >>> splat_count(path) == photo.ldi.size, splat_count(path.with_suffix(".txt"))
        (True, None)
        >>> write_spz(photo.ldi, path, density="dense", spz_version=4)
        >>> splat_count(path) == photo.ldi.size
        True
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
            with open(path, "rb") as file:
                head = file.read(12)
            if head[:4] == b"NGSP":  # version 4: a plain header
                return struct.unpack("<III", head)[2]
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
