"""Novel views of a mesh: settings + rasterizer backend + supersampling and holes.

The renderer composes three parts (pytorch3d's layout): :class:`RenderSettings`, a
rasterizer backend (``numba``: :func:`photo3d.render.raster.rasterize` on the CPU;
``gl``: :class:`photo3d.render.gl.GLRasterizer` through moderngl) and the shading
done here: supersampling anti-aliasing (render ``ssaa`` times larger, average
``ssaa x ssaa`` blocks; or, for the light textured mesh videos are drawn from, one
sample per pixel blended across depth edges, see :attr:`RenderSettings.antialias`),
the border crop of the authors' videos (done exactly by changing the intrinsics, not
by resampling the image) and holes (pixels no triangle reached) filled from their
surroundings or shown in a neutral colour.

``backend="auto"`` takes OpenGL only when it runs on real GPU hardware; on a
software OpenGL driver (Mesa llvmpipe / softpipe) the numba rasterizer is faster
here (benchmarks/RESULTS.md, rendering), so it is used instead.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from photo3d.camera import Camera, Intrinsics, check_intrinsics
from photo3d.errors import ConfigError, InputError, require
from photo3d.files.stop import check
from photo3d.holes import fill_holes
from photo3d.parallel import thread_safe_kernels, threads
from photo3d.render._resolve import (
    blend_fringe,
    grow_fill,
    grow_fill_far,
    holes_to_rgb8,
    to_rgb8,
)
from photo3d.structures.mesh import Mesh, TexturedMesh

_NO_RGB = np.zeros((0, 0, 3), np.uint8)

AUTHORS_CROP = (0.03, 0.03, 0.05, 0.03)
"""Border crop of the authors' videos: top, left, bottom, right fractions."""

EDGE_TOLERANCE = 0.03
"""Relative depth difference between neighbouring pixels that ``antialias="edges"``
smooths (a depth discontinuity)."""


def video_settings(*, crop: bool = True, **changes) -> RenderSettings:
    """The settings videos are rendered with: :data:`AUTHORS_CROP` (``crop=False``: none)
    and ``changes`` (fields of :class:`RenderSettings`). ``make``, ``render`` and the UI
    take their videos' settings from here.

    Example:
        >>> video_settings().crop, video_settings(crop=False, ssaa=1).ssaa
        ((0.03, 0.03, 0.05, 0.03), 1)
    """
    return RenderSettings(crop=AUTHORS_CROP if crop else (0.0, 0.0, 0.0, 0.0), **changes)


@dataclass(frozen=True)
class RenderSettings:
    """How views are rendered."""

    ssaa: int = 2
    """Supersampling factor per axis (1 = off)."""
    antialias: str = "auto"
    """How, when ``ssaa > 1``: ``full`` takes ``ssaa x ssaa`` samples in every pixel;
    ``edges`` one sample per pixel, and a pixel next to a depth discontinuity (a
    neighbour more than :data:`EDGE_TOLERANCE` nearer or farther) mixes in the share
    of that neighbour's colour 2x2 supersampling gives it on average (a quarter of
    the work at 2x; :meth:`~photo3d.render.raster.CPURasterizer.render_edges`);
    ``auto``: ``edges`` for a textured mesh (the light mesh videos are drawn from:
    its texture lookup already filters the inside of its triangles), ``full`` for a
    vertex-coloured one. The OpenGL backend always supersamples every pixel."""
    crop: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    """Fractions of the view cut away (top, left, bottom, right) before it fills the
    output; :data:`AUTHORS_CROP` reproduces the authors' videos."""
    fill_holes: bool = True
    """Fill pixels no triangle covers from their surroundings (else ``background``)."""
    hole_fill: str = "far"
    """How: ``far`` (the farther side of each hole first, up to 32 px, since what the
    camera uncovers lies behind what surrounds it) or ``both`` (both sides alike, up
    to 8 px, as before); a smooth pyramid fill takes what is left."""
    background: tuple[float, float, float] = (0.5, 0.5, 0.5)
    """Colour of uncovered pixels when ``fill_holes`` is off."""
    near: float = 1e-3
    """Near clipping plane (depth units)."""
    backend: str = "auto"
    """``auto``, ``numba`` or ``gl``."""

    def __post_init__(self) -> None:
        if not (_whole(self.ssaa) and 1 <= self.ssaa <= 8):
            raise ConfigError(f"ssaa must be a whole number between 1 and 8, got {self.ssaa!r}")
        if not (_numbers(self.crop, 4) and all(0 <= c < 0.5 for c in self.crop)):
            raise ConfigError(f"crop must be 4 fractions in [0, 0.5), got {self.crop!r}")
        if not (_numbers(self.background, 3) and all(0 <= c <= 1 for c in self.background)):
            raise ConfigError(f"background must be an RGB triple in [0, 1], "
                              f"got {self.background!r}")
        if not (_numbers((self.near,), 1) and 0 < self.near < float("inf")):
            raise ConfigError(f"near must be a finite number > 0, got {self.near!r}")
        if not isinstance(self.fill_holes, bool):
            raise ConfigError(f"fill_holes must be True or False, got {self.fill_holes!r}")
        object.__setattr__(self, "crop", tuple(self.crop))
        object.__setattr__(self, "background", tuple(self.background))
        if self.antialias not in ("auto", "full", "edges"):
            raise ConfigError(f"antialias must be auto, full or edges, got {self.antialias!r}")
        if self.hole_fill not in ("far", "both"):
            raise ConfigError(f"hole_fill must be far or both, got {self.hole_fill!r}")
        if self.backend not in ("auto", "numba", "gl"):
            raise ConfigError(f"backend must be auto, numba or gl, got {self.backend!r}")


def _whole(value: object) -> bool:
    """``value`` is an integer (not a bool)."""
    return isinstance(value, int | np.integer) and not isinstance(value, bool)


def _numbers(values: object, n: int) -> bool:
    """``values`` is a sequence of ``n`` real numbers (not bools, not NaN)."""
    return (isinstance(values, tuple | list | np.ndarray) and len(values) == n
            and all(isinstance(v, int | float | np.integer | np.floating)
                    and not isinstance(v, bool) and v == v for v in values))


@dataclass(frozen=True)
class View:
    """A rendered view.

    Attributes:
        color: ``(H, W, 3) float32`` in [0, 1].
        depth: ``(H, W) float32`` camera z (from the supersampled pixel nearest the
            centre of each output pixel), ``+inf`` where nothing was hit.
        mask: ``(H, W) bool`` True where triangles covered the whole pixel.
    """

    color: np.ndarray
    depth: np.ndarray
    mask: np.ndarray


def cropped(k: Intrinsics, crop: tuple[float, float, float, float]) -> Intrinsics:
    """Intrinsics whose image is the ``crop`` window of ``k`` stretched to the same size.

    Example:
        >>> k = cropped(Intrinsics.default(100, 100), (0.1, 0.1, 0.1, 0.1))
        >>> k.fx, k.cx
        (125.0, 50.0)
    """
    top, left, bottom, right = crop
    sx, sy = 1.0 / (1.0 - left - right), 1.0 / (1.0 - top - bottom)
    return replace(k, fx=k.fx * sx, fy=k.fy * sy, cx=(k.cx - left * k.width) * sx,
                   cy=(k.cy - top * k.height) * sy)


def output_intrinsics(k: Intrinsics, width: int, height: int) -> Intrinsics:
    """The input camera for an output of another size or shape.

    The input image is scaled to *cover* the output (like CSS ``object-fit: cover``):
    an output of another aspect ratio shows the middle of the photo, never beyond it.

    Example:
        >>> k = output_intrinsics(Intrinsics.default(200, 100), 400, 400)
        >>> k.fx, k.cx, k.cy
        (800.0, 200.0, 200.0)
    """
    s = max(width / k.width, height / k.height)
    return Intrinsics(k.fx * s, k.fy * s, k.cx * s + (width - k.width * s) / 2.0,
                      k.cy * s + (height - k.height * s) / 2.0, int(width), int(height))


class Renderer:
    """Render views of one mesh with one backend (uploads the mesh once).

    Example:
        >>> from photo3d.stages.ldi import from_image
        >>> from photo3d.mesh.full import build_mesh
        >>> mesh = build_mesh(from_image(np.full((8, 8, 3), 0.5, np.float32),
        ...                              np.ones((8, 8), np.float32)))
        >>> view = Renderer(mesh, RenderSettings(backend="numba")).render(
        ...     Camera(Intrinsics.default(8, 8), np.eye(4)))
        >>> view.color.shape, round(float(view.color[4, 4, 0]), 3)
        ((8, 8, 3), 0.502)
    """

    def __init__(self, mesh: Mesh | TexturedMesh, settings: RenderSettings | None = None
                 ) -> None:
        """``mesh``: a vertex-coloured :class:`~photo3d.structures.mesh.Mesh` or a
        :class:`~photo3d.structures.mesh.TexturedMesh` (drawn with its texture)."""
        if not isinstance(mesh, Mesh | TexturedMesh):
            raise InputError(f"mesh must be a photo3d Mesh or TexturedMesh "
                             f"(Photo3D.mesh(), .light_mesh()), got a {type(mesh).__name__}")
        if settings is not None and not isinstance(settings, RenderSettings):
            raise ConfigError(f"settings must be a RenderSettings or None, got a "
                              f"{type(settings).__name__}")
        self.settings = settings or RenderSettings()
        self.mesh = mesh
        texture = None
        if isinstance(mesh, TexturedMesh):
            overlay = mesh.overlay
        else:
            mesh, overlay = mesh.split_fringe()
        if isinstance(mesh, TexturedMesh):
            self._vertices, uv, _, self._faces = mesh.checked()
            self._colors = np.zeros((len(uv), 3), np.float32)
            self._colors[:, :2] = uv
            texture = np.asarray(mesh.texture)
            first = int(mesh.n_input)
        else:
            self._vertices, self._colors, _, self._faces = mesh.checked()
            # photo3d meshes list the faces of the input layer first (build_mesh):
            # drawing those first lets hidden layers be culled cheaply.
            n_input = mesh.width * mesh.height
            first = int(np.count_nonzero(self._faces.max(axis=1) < n_input))
        self.backend = select_backend(self.settings.backend)
        if self.backend == "gl":
            from photo3d.render.gl import GLRasterizer

            self._raster = GLRasterizer(self._vertices, self._colors, self._faces,
                                        texture=texture)
        else:
            from photo3d.render.raster import CPURasterizer

            self._raster = CPURasterizer(self._vertices, self._colors, self._faces, first=first,
                                         reuse=True,  # frames are resolved into new arrays
                                         texture=texture)
        antialias = self.settings.antialias
        if antialias == "auto":
            antialias = "edges" if texture is not None else "full"
        self._edges = self.backend == "numba" and antialias == "edges" and self.settings.ssaa > 1
        self._overlay = None if overlay is None else self._rasterizer(overlay)

    def _rasterizer(self, fringe: Mesh):
        """A rasterizer of this renderer's backend for the fringe mesh ``fringe``: its
        colours and, as a fourth channel, its alpha in one pass, each sample taking
        those of its triangle's corner of largest barycentric weight, so each pixel's
        footprint carries its own colour and alpha, as in the photo (alpha
        interpolated from one pixel centre to the next faded a silhouette's
        outermost opaque pixel halfway toward its transparent neighbour;
        ``docs/edges.md``)."""
        vertices, colors, _, faces = fringe.checked()
        alpha = np.ones(len(vertices), np.float32) if fringe.alpha is None else fringe.alpha
        if self.backend == "gl":
            from photo3d.render.gl import GLRasterizer

            return GLRasterizer(vertices, colors, faces, alpha=alpha)
        from photo3d.render.raster import CPURasterizer

        return CPURasterizer(vertices, colors, faces, reuse=True, alpha=alpha)

    def close(self) -> None:
        """Release GPU resources (if any)."""
        self._raster.release()
        if self._overlay is not None:
            self._overlay.release()

    def __enter__(self) -> Renderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def render(self, camera: Camera) -> View:
        """Render ``camera`` (its intrinsics give the output size). In a worker thread,
        raises the interruption first once a signal asked the process to stop
        (:func:`photo3d.files.stop.check`: each view is a chunk of the work)."""
        check()
        k = self._intrinsics(camera)
        color, coverage, depth = self._draw(self._raster, k, camera.pose)
        color = self._holes(color, coverage, depth)
        if self._overlay is not None:
            color, depth = self._blend(color, depth, k, camera.pose)
        return View(color=np.clip(color, 0.0, 1.0, out=color), depth=depth,
                    mask=coverage >= 1.0)

    def _draw(self, raster, k: Intrinsics, pose) -> tuple[np.ndarray, ...]:
        """``(color, coverage, depth)`` of ``raster`` at ``k``'s size (the settings'
        antialiasing)."""
        s = self.settings
        f = s.ssaa
        if self._edges:
            return raster.render_edges(k, pose=pose, near=s.near, tolerance=EDGE_TOLERANCE)
        big = Intrinsics(k.fx * f, k.fy * f, k.cx * f, k.cy * f, k.width * f, k.height * f)
        return raster.render_resolved(big, f, pose=pose, near=s.near)

    def _blend(self, color: np.ndarray, depth: np.ndarray, k: Intrinsics, pose,
               rgb: np.ndarray = _NO_RGB) -> tuple[np.ndarray, np.ndarray]:
        """``color`` with the soft silhouettes' fringe blended over it where the fringe
        is in front: ``a * fringe + (1 - a) * color``, ``a`` the fringe's alpha (its
        nearest corner's, drawn in the same pass as its colours) times twice its
        coverage of the pixel, at most 1
        (:func:`~photo3d.render._resolve.blend_fringe`); and the nearer depth.
        ``rgb``: the frame in 8 bits, whose blended pixels are written again. With
        ``antialias`` ``edges`` on the CPU the blend is fused into the fringe's pass
        (:meth:`~photo3d.render.raster.CPURasterizer.blend_edges`), in place."""
        color = np.ascontiguousarray(color, np.float32)
        if self._edges:  # the rasterizer's resolved frames are new arrays: in place
            depth = np.ascontiguousarray(depth, np.float32)
            self._overlay.blend_edges(k, color, depth, pose=pose, near=self.settings.near,
                                      tolerance=EDGE_TOLERANCE, rgb=rgb)
            return color, depth
        f_color, f_coverage, f_depth = self._draw(self._overlay, k, pose)
        depth = np.array(depth, np.float32)  # a new array: the rasterizer may reuse its own
        blend_fringe(color, depth, f_color, f_coverage, f_depth, rgb)
        return color, depth

    def render_rgb8(self, camera: Camera) -> np.ndarray:
        """``render(camera).color`` in 8 bits (``to_rgb8``): a new ``(H, W, 3) uint8``
        array. With ``antialias`` ``edges`` on the CPU the rasterizer writes the 8-bit
        colours in the pass that blends the edges, and only the filled holes and the
        pixels the soft silhouettes' fringe is blended into are converted afterwards
        (a video frame: one pass over the image less).

        Example:
            >>> from photo3d.stages.ldi import from_image
            >>> from photo3d.mesh.full import build_mesh
            >>> mesh = build_mesh(from_image(np.full((8, 8, 3), 0.5, np.float32),
            ...                              np.ones((8, 8), np.float32)))
            >>> rgb = Renderer(mesh, RenderSettings(backend="numba")).render_rgb8(
            ...     Camera(Intrinsics.default(8, 8), np.eye(4)))
            >>> rgb.shape, rgb.dtype, int(rgb[4, 4, 0])
            ((8, 8, 3), dtype('uint8'), 128)
        """
        if not self._edges:
            return to_rgb8(self.render(camera).color)
        check()
        k = self._intrinsics(camera)
        color, coverage, depth, rgb = self._raster.render_edges(
            k, pose=camera.pose, near=self.settings.near, tolerance=EDGE_TOLERANCE, rgb8=True)
        color = self._holes(color, coverage, depth)
        holes_to_rgb8(color, coverage, rgb)
        if self._overlay is not None:
            self._blend(color, depth, k, camera.pose, rgb)
        return rgb

    def frame_workers(self) -> int:
        """How many frames :func:`~photo3d.render.animate.render_frames` renders at
        once with this renderer: 2 with the CPU rasterizer when the caller's budget
        (:func:`~photo3d.parallel.threads`) is two threads or more and numba has a
        threading layer that runs parallel kernels of several threads at
        once (:func:`~photo3d.parallel.thread_safe_kernels`), each frame then on half the
        calling thread's budget; else 1. Two frames at once keep both cores busy where
        one frame's bands wait for the slower band (the video encoder shares a core).

        Example:
            >>> from photo3d.mesh.full import build_mesh
            >>> from photo3d.stages.ldi import from_image
            >>> mesh = build_mesh(from_image(np.ones((8, 8, 3), np.float32),
            ...                              np.ones((8, 8), np.float32)))
            >>> Renderer(mesh, RenderSettings(backend="numba")).frame_workers() in (1, 2)
            True
        """
        if self.backend != "numba" or threads() < 2:
            return 1
        return 2 if thread_safe_kernels() else 1

    def _intrinsics(self, camera: Camera) -> Intrinsics:
        """``camera``'s intrinsics with the settings' crop (the drawn view), once
        :func:`check_camera` accepts it."""
        check_camera(camera)
        crop = self.settings.crop
        return cropped(camera.intrinsics, crop) if any(crop) else camera.intrinsics

    def _holes(self, color: np.ndarray, coverage: np.ndarray, depth: np.ndarray) -> np.ndarray:
        """``color`` with the pixels of ``coverage < 1`` filled (``fill_holes``) or mixed
        with the background; may be ``color`` itself, changed in place."""
        s = self.settings
        if not s.fill_holes:
            bg = np.asarray(s.background, np.float32)
            return color * coverage[..., None] + bg * (1.0 - coverage[..., None])
        if s.hole_fill == "far":
            left = grow_fill_far(color, coverage, depth, 32, 0.05)
        else:
            left = grow_fill(color, coverage, 8)
        if left:  # large holes left: smooth pyramid fill
            color = fill_holes(color, np.where(coverage >= 1.0, 1.0, coverage))
        return color


def check_camera(camera: Camera) -> None:
    """Refuse what :meth:`Renderer.render` cannot draw: no :class:`Camera`, an output
    size that is not whole pixels > 0, a focal length that is not finite and
    positive, or a principal point that is not finite. (The memory a view needs is
    the 3D photo's to check, :meth:`photo3d.Photo3D.render`, with the one memory
    model of :mod:`photo3d.resources`, a layer above this one.)

    Raises:
        InputError: the camera, naming what is wrong.

    Example:
        >>> check_camera(Camera(Intrinsics.default(64, 48), np.eye(4)))
        >>> check_camera(Camera(Intrinsics(0.0, 0.0, 32.0, 24.0, 64, 48), np.eye(4)))
        ... # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        photo3d.errors.InputError: camera intrinsics need finite fx, fy > 0 and a finite ...
    """
    if not isinstance(camera, Camera) or not isinstance(camera.intrinsics, Intrinsics):
        raise InputError(f"camera must be a photo3d.camera.Camera (Intrinsics and a pose), "
                         f"got a {type(camera).__name__}")
    k = camera.intrinsics
    width, height = k.width, k.height
    if not all(isinstance(v, int | np.integer) and not isinstance(v, bool) and v > 0
               for v in (width, height)):
        raise InputError(f"camera size must be whole pixels > 0, got width={width!r}, "
                         f"height={height!r}")
    check_intrinsics(k, "camera intrinsics")


def select_backend(name: str) -> str:
    """The rasterizer ``Renderer`` uses for ``name`` (``auto``, ``numba`` or ``gl``).

    Raises:
        ImportError: ``gl`` without moderngl (names the ``gl`` extra).
        ConfigError: ``gl`` and no OpenGL context can be made.

    Example:
        >>> select_backend("numba")
        'numba'
    """
    if name == "numba":
        return "numba"
    if name == "gl":
        require("moderngl", "gl", purpose="--backend gl")
    try:
        from photo3d.render.gl import gl_available, gl_renderer, is_software_renderer
    except ImportError:
        if name == "gl":
            raise
        return "numba"
    if name == "gl":
        if not gl_available():
            raise ConfigError("backend 'gl' requested but no OpenGL context can be made "
                              "(needs libEGL and a Mesa or GPU driver; --backend numba "
                              "works everywhere)")
        return "gl"
    if gl_available() and not is_software_renderer(gl_renderer() or ""):
        return "gl"
    return "numba"
