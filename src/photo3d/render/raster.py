"""CPU z-buffer rasterizer for vertex-coloured triangle meshes (numba).

Conventions are those of :mod:`photo3d.camera`: OpenCV camera axes, pose =
camera-from-world 4x4, pixel ``(y, x)`` sampled at its centre ``(x + 0.5, y + 0.5)``.

How it works:

* Vertices are transformed, projected and snapped to a 1/256 px grid once
  (:mod:`photo3d.render._clip`); triangles crossing the near plane are clipped
  (Sutherland-Hodgman, up to two triangles), triangles entirely behind it dropped.
  Snapping moves a vertex by at most 1/512 px (invisible, but depth on a plane seen
  at a grazing angle inherits that much parallax error).
* The image is cut into a few horizontal bands rendered in parallel; each band scans
  every triangle and rasterizes it inside its bounding box clamped to the band (on
  each row of a wide box, only between the triangle's edges).
* Coverage uses float64 edge functions, evaluated with each edge's end points in a
  canonical order so two triangles sharing an edge get exactly opposite values.
  A pixel centre exactly on an edge belongs to one triangle only (top-left rule:
  the triangle whose inward edge normal points to +x, or to +y for a horizontal
  edge), except a pixel centre exactly on a *vertex*, which every triangle using
  that vertex covers (they agree on its value). So a closed mesh has no cracks and
  no double edges, and the input view of a photo3d mesh, whose vertices sit on pixel
  centres, reproduces every vertex colour, also along the mesh borders.
* Colour and depth are interpolated perspective-correctly (``c/z`` and ``1/z`` are
  linear in screen space); the nearest surface wins, ties keep the first triangle.
* A mesh with a vertex coverage (``alpha``, the soft silhouettes' fringe) is not
  interpolated: each sample takes the colour and alpha (a fourth channel) of its
  triangle's corner with the largest perspective-correct barycentric weight, so both
  are constant over each vertex's footprint (the corner's cell: bounded by the lines
  from the triangle's edge midpoints to its centroid), as a pixel of the photo is.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from photo3d.camera import Intrinsics
from photo3d.errors import InputError
from photo3d.parallel import threads
from photo3d.render._clip import clip_near, project_vertices
from photo3d.render._kernels import (
    BLOCK,
    block_bounds,
    block_vertices,
    pack_texture,
    raster_frame,
)

__all__ = ["CPURasterizer", "Fragments", "rasterize"]


@dataclass(frozen=True)
class Fragments:
    """Result of :func:`rasterize`.

    Attributes:
        color: ``(H, W, 3) float32`` in [0, 1]; the background colour where nothing
            was hit. ``(H, W, 4)`` for a mesh with ``alpha``: the nearest corner's
            colour and, fourth, its alpha (0 where nothing was hit).
        depth: ``(H, W) float32`` camera z of the nearest surface, ``+inf`` where
            nothing was hit.
        mask: ``(H, W) bool``, True where a triangle covered the pixel centre.
    """

    color: np.ndarray
    depth: np.ndarray
    mask: np.ndarray


_NO_COUNT = np.zeros((0, 0), np.int32)
_NO_TEXTURE = np.zeros((0, 0, 3), np.uint8)
_NO_PACKED = np.zeros((0, 0), np.uint32)
_NO_ALPHA = np.zeros(0, np.float32)


def _check_array(name: str, array: np.ndarray, shape: str) -> None:
    if array.ndim != 2 or array.shape[1] != 3:
        raise InputError(f"{name} must have shape {shape}, got {array.shape}")


def prepare_mesh(vertices, colors, faces, pose):
    """Validate the mesh and pose given to :func:`rasterize` (or to
    :class:`~photo3d.render.gl.GLRasterizer`) and convert them to what the
    rasterizers take.

    Args:
        vertices: ``(N, 3)`` float, camera-space or world coordinates.
        colors: ``(N, 3)`` uint8, or float in [0, 1] (or texture coordinates
            ``(u, v, 0)`` for a textured mesh).
        faces: ``(M, 3)`` integer vertex indices (``[]`` for none).
        pose: ``(4, 4)`` camera-from-world matrix, or None for the identity.

    Returns:
        ``(vertices (N, 3) float32, colors (N, 3) uint8 | float32, scale, faces (M, 3)
        int32, rotation (3, 3) float64, translation (3,) float64)``, all C-contiguous;
        ``colors * scale`` is in [0, 1] (``scale`` is ``1 / 255`` for uint8, else 1).

    Raises:
        InputError: a shape, dtype or index is wrong (the message names the array).

    Example:
        >>> v, c, scale, f, rot, trans = prepare_mesh(np.zeros((3, 3)), np.zeros((3, 3),
        ...                                           np.uint8), [[0, 1, 2]], None)
        >>> v.dtype, f.dtype, round(scale * 255), rot.shape, trans.shape
        (dtype('float32'), dtype('int32'), 1, (3, 3), (3,))
    """
    vertices = np.ascontiguousarray(vertices, np.float32)
    colors = np.asarray(colors)
    faces = np.asarray(faces)
    _check_array("vertices", vertices, "(N, 3)")
    _check_array("colors", colors, "(N, 3)")
    if faces.size == 0:  # also [] (float64)
        faces = np.zeros((0, 3), np.int32)
    _check_array("faces", faces, "(M, 3)")
    if colors.shape[0] != vertices.shape[0]:
        raise InputError(f"colors has {colors.shape[0]} rows but vertices has {vertices.shape[0]}")
    if colors.dtype == np.uint8:
        colors, scale = np.ascontiguousarray(colors), 1.0 / 255.0
    elif np.issubdtype(colors.dtype, np.floating):
        colors, scale = np.ascontiguousarray(colors, np.float32), 1.0
    else:
        raise InputError(f"colors must be float32 in [0, 1] or uint8, got {colors.dtype}")
    if not np.issubdtype(faces.dtype, np.integer):
        raise InputError(f"faces must be integer vertex indices, got {faces.dtype}")
    faces = np.ascontiguousarray(faces, np.int32)
    if len(faces) and (faces.min() < 0 or faces.max() >= len(vertices)):
        raise InputError(
            f"faces index vertices out of range [0, {len(vertices)}): "
            f"min {faces.min()}, max {faces.max()}"
        )
    rot, trans = _check_pose(pose)
    return vertices, colors, scale, faces, rot, trans


def _check_pose(pose) -> tuple[np.ndarray, np.ndarray]:
    """``(rotation (3, 3), translation (3,))`` of a camera-from-world pose (None: identity)."""
    pose = np.eye(4) if pose is None else np.asarray(pose, np.float64)
    if pose.shape != (4, 4) or not np.all(np.isfinite(pose)):
        raise InputError(f"pose must be a finite 4x4 camera-from-world matrix, got {pose.shape}")
    return np.ascontiguousarray(pose[:3, :3]), np.ascontiguousarray(pose[:3, 3])


def check_alpha(alpha, n: int, texture: np.ndarray | None = None) -> np.ndarray:
    """A vertex coverage as the rasterizers take it: ``(n,) float32`` in [0, 1]
    C-contiguous, or ``(0,)`` for None.

    Raises:
        InputError: not ``n`` values, or given with a texture (not supported).

    Example:
        >>> check_alpha(None, 3).shape, check_alpha([1, 0.5, 2], 3).tolist()
        ((0,), [1.0, 0.5, 1.0])
    """
    if alpha is None:
        return _NO_ALPHA
    if texture is not None and np.size(texture):
        raise InputError("alpha is not supported with a texture (vertex colours only)")
    alpha = np.asarray(alpha, np.float32)
    if alpha.shape != (n,):
        raise InputError(f"alpha must have shape ({n},) like vertices, got {alpha.shape}")
    return np.ascontiguousarray(np.clip(alpha, 0.0, 1.0))


def check_texture(texture) -> np.ndarray:
    """A texture as the rasterizers take it: ``(T, U, 3) uint8`` C-contiguous, or
    ``(0, 0, 3)`` for None (no texture: vertex colours).

    Raises:
        InputError: not ``(T >= 2, U >= 2, 3) uint8``.

    Example:
        >>> check_texture(None).shape, check_texture(np.zeros((2, 4, 3), np.uint8)).shape
        ((0, 0, 3), (2, 4, 3))
    """
    if texture is None:
        return _NO_TEXTURE
    texture = np.ascontiguousarray(texture)
    if texture.ndim != 3 or texture.shape[2] != 3 or texture.dtype != np.uint8 or min(
            texture.shape[:2]) < 2:
        raise InputError(f"texture must be (T >= 2, U >= 2, 3) uint8, got {texture.shape} "
                         f"{texture.dtype}")
    return texture


def default_bands() -> int:
    """Number of row bands: one per thread of the caller's budget
    (:func:`~photo3d.parallel.threads`), between 2 and 4 (DESIGN sec. 8)."""
    return min(4, max(2, threads()))


def rasterize(
    vertices: np.ndarray,
    colors: np.ndarray,
    faces: np.ndarray,
    intrinsics: Intrinsics,
    *,
    pose: np.ndarray | None = None,
    near: float = 1e-3,
    background: tuple[float, float, float] = (0.0, 0.0, 0.0),
    bands: int | None = None,
    first: int | None = None,
    alpha: np.ndarray | None = None,
) -> Fragments:
    """Render a vertex-coloured triangle mesh from a pinhole camera.

    The first call compiles the numba kernels (cached on disk afterwards).

    Args:
        vertices: ``(N, 3) float32`` world coordinates (OpenCV axes; the input view's
            camera is the identity).
        colors: ``(N, 3)`` float32 in [0, 1] or uint8 vertex colours.
        faces: ``(M, 3) int32`` vertex indices, either winding (no culling).
        intrinsics: camera intrinsics; also the output size ``width x height``.
        pose: ``(4, 4)`` camera-from-world matrix; None is the identity.
        near: near-plane depth, > 0; triangles crossing it are clipped.
        background: RGB in [0, 1] of pixels that nothing covers.
        bands: number of row bands rendered in parallel; None = :func:`default_bands`.
        first: draw ``faces[:first]`` first and cull later faces hidden behind them
            (hierarchical z, same image, less work when the first faces are the
            visible layer: photo3d meshes list the input layer first). None: all.
        alpha: ``(N,) float32`` vertex coverage in [0, 1], drawn as the fourth
            channel of ``color``, with the colours, as the nearest corner's (see the
            module), or None.

    Returns:
        :class:`Fragments` of shape ``(intrinsics.height, intrinsics.width)``.

    Example:
        >>> k = Intrinsics.default(4, 4)
        >>> v = np.array([[-9, -9, 1], [9, -9, 1], [0, 9, 1]], np.float32)
        >>> f = rasterize(v, np.ones((3, 3), np.float32), np.array([[0, 1, 2]]), k)
        >>> f.mask.all(), float(f.depth[0, 0]), f.color[0, 0].tolist()
        (np.True_, 1.0, [1.0, 1.0, 1.0])
    """
    prepared = prepare_mesh(vertices, colors, faces, pose)
    height, width = int(intrinsics.height), int(intrinsics.width)
    if height <= 0 or width <= 0:
        raise InputError(f"intrinsics size must be positive, got {width}x{height}")
    if not near > 0:
        raise InputError(f"near must be > 0, got {near}")
    bands = default_bands() if bands is None else int(bands)
    if bands < 1:
        raise InputError(f"bands must be >= 1, got {bands}")
    bg = np.asarray(background, np.float32)
    if bg.shape != (3,):
        raise InputError(f"background must be an RGB triple, got shape {bg.shape}")
    k = np.array([intrinsics.fx, intrinsics.fy, intrinsics.cx, intrinsics.cy], np.float64)
    image = (height, width, min(bands, height), bg, _NO_COUNT)
    n_first = len(prepared[3]) if first is None else int(np.clip(first, 0, len(prepared[3])))
    color, depth, mask = _render(*prepared, k, float(near), *image, n_first=n_first,
                                 alpha=check_alpha(alpha, len(prepared[0])))
    return Fragments(color=color, depth=depth, mask=mask)


class _Buffers:
    """Output arrays kept from one frame to the next, by name.

    A 2560x1440 frame is ~63 MB of colour, depth and mask; allocating it per frame
    costs page faults (the kernel zeroes every page) worth ~18 % of the render."""

    def __init__(self) -> None:
        self._arrays: dict[str, np.ndarray] = {}

    def get(self, name: str, shape: tuple[int, ...], dtype) -> np.ndarray:
        array = self._arrays.get(name)
        if array is None or array.shape != shape or array.dtype != dtype:
            array = self._arrays[name] = np.empty(shape, dtype)
        return array


def _render(vertices, colors, scale, faces, rot, trans, k, near, height, width, bands, bg, count,
            n_first=None, buffers: _Buffers | None = None, blocks=None, factor: int = 0,
            texture: np.ndarray = _NO_PACKED, smooth: float = 0.0, rgb8: bool = False,
            alpha: np.ndarray = _NO_ALPHA, under: tuple | None = None):
    """Vertex stage, clipping and rasterization on validated inputs (``blocks``:
    :func:`block_vertices` of ``faces``, computed when None). ``factor > 0``: return
    the supersampling resolve ``(color, coverage, depth)`` at ``1 / factor`` the size
    (fresh arrays) instead of the samples; ``smooth``: the depth-edge blend of
    :meth:`CPURasterizer.render_edges` (``factor`` 1), which with ``rgb8`` also returns
    the colours in 8 bits (a fresh ``(H, W, 3) uint8``, fourth). ``texture``: ``(T, U)
    uint32`` (:func:`~photo3d.render._kernels.pack_texture`) when ``colors`` are
    texture coordinates ``(u, v, 0)``. ``alpha``: ``(N,) float32`` (:func:`check_alpha`)
    adds a fourth channel to the colours, or ``(0,)``. ``under``: ``(color (H, W, 3)
    float32, depth (H, W) float32, rgb (H, W, 3) | (0, 0, 3) uint8)`` of a frame drawn
    before, which the result (``factor`` 1, ``alpha``) is blended over in place
    instead of being returned (:meth:`CPURasterizer.blend_edges`)."""
    n_first = len(faces) if n_first is None else n_first
    blocks = block_vertices(faces, BLOCK) if blocks is None else blocks
    buffers = buffers or _Buffers()
    sv = buffers.get("sv", (len(vertices), 3), np.float32)
    sv, n_behind, n_bad = project_vertices(vertices, rot, trans, k, near, sv)
    if n_bad:
        raise InputError(f"{n_bad} vertices have non-finite coordinates")
    if n_behind:
        xsv, xcol, xfaces, xalpha = clip_near(sv, faces, vertices, colors, scale, rot, trans, k,
                                              near, alpha)
    else:
        xsv, xcol = np.empty((0, 3), np.float32), np.empty((0, 3), np.float32)
        xfaces, xalpha = np.empty((0, 3), np.int32), _NO_ALPHA
    image = (height, width, bands, bg, count)
    bounds = block_bounds(sv, *blocks)
    channels = 4 if alpha.shape[0] else 3
    out = (buffers.get("color", (height, width, channels), np.float32),
           buffers.get("depth", (height, width), np.float32),
           buffers.get("mask", (0, 0) if factor else (height, width), np.bool_))
    small = (height // factor, width // factor) if factor else (0, 0)
    if under is not None:
        resolved = (under[0], np.empty((0, 0), np.float32), under[1])
        rgb = under[2]
    else:
        resolved = (np.empty((*small, channels), np.float32), np.empty(small, np.float32),
                    np.empty(small, np.float32))
        rgb = np.empty((height, width, 3) if rgb8 and factor == 1 else (0, 0, 3), np.uint8)
    frame = raster_frame(sv, colors, scale, faces, n_first, bounds, BLOCK, xsv, xcol, xfaces,
                         *image, *out, factor, *resolved, texture, float(smooth), rgb, alpha,
                         xalpha, under is not None)
    if under is not None:
        return None
    if rgb.size:
        return (*resolved, rgb)
    return resolved if factor else frame


class CPURasterizer:
    """:func:`rasterize` for many views of one mesh: inputs are checked once.

    The same interface as :class:`photo3d.render.gl.GLRasterizer`.

    Example:
        >>> v = np.array([[-9, -9, 1], [9, -9, 1], [0, 9, 1]], np.float32)
        >>> r = CPURasterizer(v, np.ones((3, 3), np.float32), np.array([[0, 1, 2]]))
        >>> bool(r.render(Intrinsics.default(4, 4)).mask.all())
        True
    """

    renderer = "numba (CPU)"

    def __init__(self, vertices, colors, faces, *, first: int | None = None,
                 reuse: bool = False, texture: np.ndarray | None = None,
                 alpha: np.ndarray | None = None) -> None:
        """``first``: see :func:`rasterize`. ``reuse``: return the same arrays from every
        :meth:`render` call (each call overwrites the previous result): no
        allocation per frame, for callers that consume a frame before the next.
        ``texture``: ``(T, U, 3) uint8`` sRGB; then ``colors`` are ``(N, 3) float32``
        texture coordinates ``(u, v, 0)`` (glTF convention, origin top-left).
        ``alpha``: ``(N,) float32`` vertex coverage in [0, 1] (vertex colours only):
        each sample takes the colour and alpha of its triangle's corner nearest to
        it, the alpha as a fourth colour channel (see the module)."""
        self._prepared = prepare_mesh(vertices, colors, faces, None)[:4]
        self._alpha = check_alpha(alpha, len(self._prepared[0]), texture)
        self._texture = pack_texture(check_texture(texture))
        n = len(self._prepared[3])
        self._first = n if first is None else int(np.clip(first, 0, n))
        self._local = threading.local() if reuse else None  # buffers: one set a thread
        self._blocks = block_vertices(self._prepared[3], BLOCK)

    @property
    def _buffers(self) -> _Buffers | None:
        """The calling thread's output arrays (``reuse``), so threads may render at once."""
        if self._local is None:
            return None
        buffers = getattr(self._local, "buffers", None)
        if buffers is None:
            buffers = self._local.buffers = _Buffers()
        return buffers

    def render(self, intrinsics: Intrinsics, *, pose=None, near: float = 1e-3,
               background=(0.0, 0.0, 0.0)) -> Fragments:
        """Render one view; see :func:`rasterize` for the arguments."""
        view = self._view(intrinsics, pose, near)
        color, depth, mask = _render(
            *self._prepared, *view, min(default_bands(), view[-2]),
            np.asarray(background, np.float32), _NO_COUNT, n_first=self._first,
            buffers=self._buffers, blocks=self._blocks, texture=self._texture, alpha=self._alpha,
        )
        return Fragments(color=color, depth=depth, mask=mask)

    @staticmethod
    def _view(intrinsics: Intrinsics, pose, near: float) -> tuple:
        """``(rot, trans, k, near, height, width)`` of a checked view."""
        rot, trans = _check_pose(pose)
        if not near > 0:
            raise InputError(f"near must be > 0, got {near}")
        k = np.array([intrinsics.fx, intrinsics.fy, intrinsics.cx, intrinsics.cy], np.float64)
        return rot, trans, k, float(near), int(intrinsics.height), int(intrinsics.width)

    def render_resolved(self, intrinsics: Intrinsics, factor: int, *, pose=None,
                        near: float = 1e-3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Render at ``intrinsics`` (size a multiple of ``factor``) and average each
        ``factor x factor`` block of samples, fused into the rasterizer's bands.

        Returns:
            ``(color (h, w, 3), coverage (h, w), depth (h, w))`` float32 at ``1 /
            factor`` the size: the mean colour of the covered samples (0 where none),
            the covered fraction and the nearest depth (inf where none); ``color`` is
            ``(h, w, 4)`` with ``alpha`` (its mean over the covered samples too).

        Example:
            >>> v = np.array([[-9, -9, 1], [9, -9, 1], [0, 9, 1]], np.float32)
            >>> r = CPURasterizer(v, np.ones((3, 3), np.float32), np.array([[0, 1, 2]]))
            >>> color, coverage, depth = r.render_resolved(Intrinsics.default(8, 8), 2)
            >>> color.shape, float(coverage.min()), float(depth.max())
            ((4, 4, 3), 1.0, 1.0)
        """
        view = self._view(intrinsics, pose, near)
        factor, height, width = int(factor), view[-2], view[-1]
        if factor < 1 or height % factor or width % factor:
            raise InputError(f"size {width}x{height} is not a multiple of factor {factor}")
        return _render(
            *self._prepared, *view, min(default_bands(), height // factor),
            np.zeros(3, np.float32), _NO_COUNT, n_first=self._first, buffers=self._buffers,
            blocks=self._blocks, factor=factor, texture=self._texture, alpha=self._alpha,
        )

    def render_edges(self, intrinsics: Intrinsics, *, pose=None, near: float = 1e-3,
                     tolerance: float = 0.03, rgb8: bool = False) -> tuple[np.ndarray, ...]:
        """One sample per pixel, antialiased at depth edges: :meth:`render_resolved`
        with ``factor = 1``, except that a pixel with a 4-neighbour more than
        ``tolerance`` (relative) nearer or farther mixes in
        :data:`~photo3d.render._kernels.EDGE_BLEND` of that neighbour's colour, the
        share 2x2 supersampling gives it on average, for a quarter of its work.

        Returns:
            ``(color (H, W, 3), coverage (H, W), depth (H, W))`` float32 at the size
            of ``intrinsics``; coverage is 0 or 1; ``color`` is ``(H, W, 4)`` with
            ``alpha`` (blended at depth edges like the colours). With ``rgb8``, a
            fourth array: the colours as ``(H, W, 3) uint8`` (black where coverage is
            0), made in the same pass.

        Example:
            >>> v = np.array([[-9, -9, 1], [9, -9, 2], [0, 9, 1]], np.float32)
            >>> r = CPURasterizer(v, np.eye(3, dtype=np.float32), np.array([[0, 1, 2]]))
            >>> color, coverage, depth = r.render_edges(Intrinsics.default(4, 4))
            >>> color.shape, float(coverage.min())
            ((4, 4, 3), 1.0)
        """
        view = self._view(intrinsics, pose, near)
        return _render(
            *self._prepared, *view, min(default_bands(), view[-2]), np.zeros(3, np.float32),
            _NO_COUNT, n_first=self._first, buffers=self._buffers, blocks=self._blocks,
            factor=1, texture=self._texture, smooth=max(float(tolerance), 0.0), rgb8=rgb8,
            alpha=self._alpha,
        )

    def blend_edges(self, intrinsics: Intrinsics, color: np.ndarray, depth: np.ndarray, *,
                    pose=None, near: float = 1e-3, tolerance: float = 0.03,
                    rgb: np.ndarray | None = None) -> None:
        """:meth:`render_edges` of a mesh with ``alpha`` (the soft silhouettes' fringe),
        blended in the same pass over a frame drawn before, in place: where the mesh
        covers a pixel at or in front of ``depth`` (within 0.1 %), ``a`` of its colour
        over ``color`` (``a``: its alpha), and ``depth`` the nearer; the other pixels
        are not touched. The same frame as :func:`~photo3d.render._resolve.blend_fringe`
        of :meth:`render_edges`'s result, without the fringe's own frame.

        Args:
            color: ``(H, W, 3) float32`` C-contiguous, the size of ``intrinsics``.
            depth: ``(H, W) float32`` its camera z (``inf`` where empty).
            rgb: ``(H, W, 3) uint8`` the frame's colours in 8 bits, whose blended
                pixels are written again (as ``to_rgb8``), or None.

        Example:
            >>> v = np.array([[-9, -9, 1], [9, -9, 1], [0, 9, 1]], np.float32)
            >>> r = CPURasterizer(v, np.ones((3, 3), np.float32), np.array([[0, 1, 2]]),
            ...                   alpha=np.full(3, 0.25, np.float32))
            >>> color, depth = np.zeros((4, 4, 3), np.float32), np.full((4, 4), 2.0, np.float32)
            >>> r.blend_edges(Intrinsics.default(4, 4), color, depth)
            >>> float(color[0, 0, 0]), float(depth[0, 0])
            (0.25, 1.0)
        """
        view = self._view(intrinsics, pose, near)
        height, width = view[-2], view[-1]
        if self._alpha.shape[0] == 0:
            raise InputError("blend_edges needs a mesh with alpha")
        rgb = np.zeros((0, 0, 3), np.uint8) if rgb is None else rgb
        for name, array, shape, dtype in (("color", color, (height, width, 3), np.float32),
                                          ("depth", depth, (height, width), np.float32),
                                          ("rgb", rgb, (height, width, 3), np.uint8)):
            if name == "rgb" and array.size == 0:
                continue
            if (array.shape != shape or array.dtype != dtype
                    or not array.flags.c_contiguous or not array.flags.writeable):
                raise InputError(f"{name} must be a writeable C-contiguous {shape} "
                                 f"{np.dtype(dtype).name} array, got {array.shape} {array.dtype}")
        _render(*self._prepared, *view, min(default_bands(), height), np.zeros(3, np.float32),
                _NO_COUNT, n_first=self._first, buffers=self._buffers, blocks=self._blocks,
                factor=1, texture=self._texture, smooth=max(float(tolerance), 0.0),
                alpha=self._alpha, under=(color, depth, rgb))

    def release(self) -> None:
        """Nothing to release (symmetry with the OpenGL rasterizer)."""

    def __enter__(self) -> CPURasterizer:
        return self

    def __exit__(self, *exc) -> None:
        self.release()
