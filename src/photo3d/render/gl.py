"""OpenGL rasterizer (moderngl, headless EGL) with the results of :func:`raster.rasterize`.

Conventions are those of :mod:`photo3d.camera` and :mod:`photo3d.render.raster`:
OpenCV camera axes, pose = camera-from-world 4x4, pixel ``(y, x)`` sampled at its
centre ``(x + 0.5, y + 0.5)``; the result is the same :class:`Fragments`.

How it maps onto OpenGL:

* The clip matrix sends image coordinates ``(u, v) = (fx x / z + cx, fy y / z + cy)``
  to window coordinates ``(u, v)`` unchanged, so GL's pixel centres are the CPU
  rasterizer's sample points and GL's row 0 (read back first) is image row 0: the
  y flip happens in the matrix, no row flip is needed on read-back.
* One ``RGBA32F`` colour attachment holds ``(r, g, b, camera z)`` (cleared to the
  background and a huge z that becomes ``+inf``); no blending, no multisampling.
* Visibility: depth test LESS (the first of equal surfaces wins, as on the CPU), no
  culling. Triangles are clipped by GL at ``near``; the far plane is the farthest
  corner of the mesh's bounding box. moderngl only offers 24-bit depth attachments,
  so the fragment shader writes a *logarithmic* depth
  ``ln(z / near) / ln(far / near)``: a constant relative resolution of about
  ``ln(far / near) / 2**24`` (6e-7 for near 1e-3, far 20), where a standard
  projection with near 1e-3 would resolve only 0.1 % at z = 20.
* A mesh with a vertex coverage (``alpha``, the soft silhouettes' fringe) is drawn
  through a geometry shader that hands each fragment its triangle's three colours
  and alphas (flat) and its perspective-correct barycentric weights; the fragment
  takes the colour and alpha of the corner of largest weight, as the CPU rasterizer
  does, the alpha into a second ``R32F`` attachment (the result's fourth colour
  channel). GL clips after the geometry shader, so a triangle crossing the near
  plane keeps its corners' cells.
* Known differences from the CPU rasterizer: a pixel centre exactly on a triangle
  edge or vertex follows the GPU's own fill rule (so the right and bottom border of
  a mesh whose vertices lie on pixel centres may stay uncovered, where the CPU
  covers them), and vertices are transformed in float32 on the GPU.

Choosing a backend: :func:`gl_available` says whether an EGL context can be
created; :func:`gl_renderer` / :attr:`GLRasterizer.renderer` name the device, and
:func:`is_software_renderer` spots llvmpipe, softpipe and other CPU renderers,
slower here than numba (DESIGN sec. 8). Prefer OpenGL only when
``gl_available() and not is_software_renderer(gl_renderer())``.
Debian packages for EGL: ``libegl1`` (pulls ``libegl-mesa0``, ``libgbm1``),
``libgl1`` (glcontext loads ``libGL.so.1``), ``libgl1-mesa-dri`` (llvmpipe / Mesa GPU
drivers).
"""

from __future__ import annotations

import functools
import itertools
import math
import re

import numpy as np

from photo3d.camera import Intrinsics
from photo3d.errors import InputError, require
from photo3d.render.raster import Fragments, check_alpha, check_texture, prepare_mesh

__all__ = ["GLRasterizer", "gl_available", "gl_renderer", "is_software_renderer"]

_EMPTY_Z = 1e38  # cleared camera z; becomes +inf
_SOFTWARE = re.compile(r"llvmpipe|softpipe|swrast|software|swiftshader|lavapipe|basic render")

_VERTEX_SHADER = """
#version 330
uniform mat4 view;      // camera-from-world
uniform vec4 k_ndc;     // 2 fx / W, 2 fy / H, 2 cx / W - 1, 2 cy / H - 1
uniform vec2 clip_z;    // z_clip = clip_z.x * z + clip_z.y (GL near/far planes)
in vec3 in_position;
in vec3 in_color;
out vec3 v_color;
out float v_z;
void main() {
    vec4 c = view * vec4(in_position, 1.0);
    v_color = in_color;
    v_z = c.z;
    gl_Position = vec4(k_ndc.x * c.x + k_ndc.z * c.z, k_ndc.y * c.y + k_ndc.w * c.z,
                       clip_z.x * c.z + clip_z.y, c.z);
}
"""

_FRAGMENT_SHADER = """
#version 330
uniform vec2 log_z;     // ln(near), 1 / ln(far / near)
in vec3 v_color;
in float v_z;
out vec4 f_out;
void main() {
    f_out = vec4(clamp(v_color, 0.0, 1.0), v_z);
    gl_FragDepth = (log(v_z) - log_z.x) * log_z.y;
}
"""


_VERTEX_SHADER_ALPHA = """
#version 330
uniform mat4 view;
uniform vec4 k_ndc;
uniform vec2 clip_z;
in vec3 in_position;
in vec3 in_color;
in float in_alpha;
out vec3 v_color;
out float v_z;
out float v_alpha;
void main() {
    vec4 c = view * vec4(in_position, 1.0);
    v_color = in_color;
    v_z = c.z;
    v_alpha = in_alpha;
    gl_Position = vec4(k_ndc.x * c.x + k_ndc.z * c.z, k_ndc.y * c.y + k_ndc.w * c.z,
                       clip_z.x * c.z + clip_z.y, c.z);
}
"""

_GEOMETRY_SHADER_ALPHA = """
#version 330
layout(triangles) in;
layout(triangle_strip, max_vertices = 3) out;
in vec3 v_color[];
in float v_z[];
in float v_alpha[];
out float g_z;
out vec3 g_weight;      // barycentric weights, perspective-correct: e_i at corner i
flat out vec4 g_c0;     // the three corners' colour and alpha
flat out vec4 g_c1;
flat out vec4 g_c2;
void main() {
    for (int i = 0; i < 3; ++i) {
        gl_Position = gl_in[i].gl_Position;
        g_z = v_z[i];
        g_weight = vec3(i == 0, i == 1, i == 2);
        g_c0 = vec4(v_color[0], v_alpha[0]);
        g_c1 = vec4(v_color[1], v_alpha[1]);
        g_c2 = vec4(v_color[2], v_alpha[2]);
        EmitVertex();
    }
    EndPrimitive();
}
"""

_FRAGMENT_SHADER_ALPHA = """
#version 330
uniform vec2 log_z;
in float g_z;
in vec3 g_weight;
flat in vec4 g_c0;
flat in vec4 g_c1;
flat in vec4 g_c2;
layout(location = 0) out vec4 f_out;
layout(location = 1) out float f_alpha;
void main() {
    // the corner of largest weight (ties to the lower index, as on the CPU)
    vec4 c = (g_weight.x >= g_weight.y && g_weight.x >= g_weight.z) ? g_c0
             : (g_weight.y >= g_weight.z ? g_c1 : g_c2);
    f_out = vec4(clamp(c.rgb, 0.0, 1.0), g_z);
    f_alpha = c.a;
    gl_FragDepth = (log(g_z) - log_z.x) * log_z.y;
}
"""


def is_software_renderer(name: str) -> bool:
    """True if a ``GL_RENDERER`` string names a CPU renderer (llvmpipe, softpipe, ...).

    Example:
        >>> is_software_renderer("llvmpipe (LLVM 15.0.6, 256 bits)")
        True
        >>> is_software_renderer("NVIDIA GeForce RTX 3060/PCIe/SSE2")
        False
    """
    return bool(_SOFTWARE.search(name.lower()))


def _moderngl():
    return require("moderngl", "gl", purpose="the OpenGL renderer")


def _create_context(device_index: int | None):
    """A standalone EGL context with OpenGL >= 3.3 core, or RuntimeError."""
    moderngl = _moderngl()
    kwargs = {} if device_index is None else {"device_index": int(device_index)}
    try:
        return moderngl.create_standalone_context(backend="egl", require=330, **kwargs)
    except Exception as err:  # glcontext raises bare Exception; re-raised, not swallowed
        detail = " ".join(str(err).split()) or type(err).__name__
        raise RuntimeError(f"cannot create an OpenGL 3.3 EGL context: {detail}") from err


@functools.cache
def gl_renderer() -> str | None:
    """``GL_RENDERER`` of the default EGL device, or None without a usable context.

    Cached; never raises.
    """
    try:
        ctx = _create_context(None)
    except (ImportError, RuntimeError):
        return None
    try:
        return str(ctx.info["GL_RENDERER"])
    finally:
        ctx.release()


def gl_available() -> bool:
    """True if moderngl can create a standalone OpenGL 3.3 EGL context (cached)."""
    return gl_renderer() is not None


def _check_view(intrinsics: Intrinsics, pose, near: float, background):
    """Validate the view arguments of :meth:`GLRasterizer.render` (public edge)."""
    if int(intrinsics.height) <= 0 or int(intrinsics.width) <= 0:
        size = f"{intrinsics.width}x{intrinsics.height}"
        raise InputError(f"intrinsics size must be positive, got {size}")
    if not near > 0:
        raise InputError(f"near must be > 0, got {near}")
    pose = np.eye(4) if pose is None else np.asarray(pose, np.float64)
    if pose.shape != (4, 4) or not np.all(np.isfinite(pose)):
        raise InputError(f"pose must be a finite 4x4 camera-from-world matrix, got {pose.shape}")
    bg = np.asarray(background, np.float64)
    if bg.shape != (3,):
        raise InputError(f"background must be an RGB triple, got shape {bg.shape}")
    return pose, bg


def _projection(k: Intrinsics, near: float, far: float) -> dict[str, tuple[float, ...]]:
    """Shader uniforms mapping camera points to GL clip space and log depth.

    Window coordinates equal image coordinates ``(fx x / z + cx, fy y / z + cy)``:
    ``x_ndc = 2 u / W - 1`` and ``y_ndc = 2 v / H - 1`` (no y flip, so GL row 0 is
    image row 0); ``z_ndc`` is -1 at ``near`` and +1 at ``far`` (GL clips there).
    """
    w, h = int(k.width), int(k.height)
    return {
        "k_ndc": (2 * k.fx / w, 2 * k.fy / h, 2 * k.cx / w - 1, 2 * k.cy / h - 1),
        "clip_z": ((far + near) / (far - near), -2 * far * near / (far - near)),
        "log_z": (math.log(near), 1.0 / math.log(far / near)),
    }


def _upload(ctx, array: np.ndarray):
    """A GL buffer holding ``array`` (GL buffers cannot be empty)."""
    buffer = ctx.buffer(reserve=max(array.nbytes, 4))
    buffer.write(np.ascontiguousarray(array).tobytes())
    return buffer


class GLRasterizer:
    """Upload a mesh once, render many views (same results as :func:`raster.rasterize`).

    Args:
        vertices: ``(N, 3) float32`` world coordinates (OpenCV axes); uploaded once.
        colors: ``(N, 3)`` float32 in [0, 1] or uint8 vertex colours.
        faces: ``(M, 3)`` integer vertex indices, either winding (no culling).
        device_index: EGL device to use; None = the default (or
            ``GLCONTEXT_DEVICE_INDEX``, which takes precedence when set).
        texture: ``(T, U, 3) uint8`` sRGB; then ``colors`` are texture coordinates
            ``(u, v, 0)`` rendered into the float target and looked up on the CPU
            afterwards (deferred texturing, as the numba rasterizer does).
        alpha: ``(N,) float32`` vertex coverage in [0, 1] (vertex colours only): each
            sample takes the colour and alpha of its triangle's corner nearest to it,
            the alpha as a fourth colour channel (as
            :class:`~photo3d.render.raster.CPURasterizer`).

    Raises:
        MissingExtra: moderngl is not installed (extra ``gl``; an ImportError too).
        RuntimeError: no OpenGL 3.3 context can be created (use the CPU rasterizer).
        InputError: invalid mesh arrays.

    Usage (``release()`` frees the context; without it GL memory stays allocated)::

        with GLRasterizer(vertices, colors, faces) as gl:
            frames = [gl.render(intrinsics, pose=pose) for pose in poses]
    """

    def __init__(self, vertices, colors, faces, *, device_index: int | None = None,
                 texture: np.ndarray | None = None, alpha: np.ndarray | None = None):
        vertices, colors, scale, faces, _, _ = prepare_mesh(vertices, colors, faces, None)
        alpha = check_alpha(alpha, len(vertices), texture)
        self._alpha = alpha.shape[0] > 0
        self._texture = check_texture(texture)
        self._packed = None  # the texture as the CPU lookup reads it, on first use
        if not np.all(np.isfinite(vertices)):
            raise InputError("vertices have non-finite coordinates")
        bounds = np.stack([vertices.min(0), vertices.max(0)]) if len(vertices) else np.zeros((2, 3))
        self._corners = np.array(list(itertools.product(*bounds.T)), np.float64)  # (8, 3)
        self._n_indices = faces.size
        self._ctx = ctx = _create_context(device_index)
        self._fbo = None
        try:
            with ctx:
                if self._alpha:
                    self._prog = ctx.program(
                        vertex_shader=_VERTEX_SHADER_ALPHA,
                        geometry_shader=_GEOMETRY_SHADER_ALPHA,
                        fragment_shader=_FRAGMENT_SHADER_ALPHA,
                    )
                else:
                    self._prog = ctx.program(
                        vertex_shader=_VERTEX_SHADER, fragment_shader=_FRAGMENT_SHADER
                    )
                self._buffers = [
                    _upload(ctx, vertices),
                    _upload(ctx, colors),
                    _upload(ctx, faces.astype(np.uint32)),
                ]
                color_format = "3f1" if scale != 1.0 else "3f4"
                attributes = [
                    (self._buffers[0], "3f4", "in_position"),
                    (self._buffers[1], color_format, "in_color"),
                ]
                if self._alpha:
                    self._buffers.append(_upload(ctx, alpha))
                    attributes.append((self._buffers[3], "f4", "in_alpha"))
                self._vao = ctx.vertex_array(
                    self._prog, attributes, index_buffer=self._buffers[2],
                    index_element_size=4,
                )
        except Exception:
            ctx.release()
            raise

    @property
    def renderer(self) -> str:
        """``GL_RENDERER`` of the context, e.g. ``'llvmpipe (LLVM 15.0.6, 256 bits)'``."""
        with self._live() as ctx:
            return str(ctx.info["GL_RENDERER"])

    def _live(self):
        if self._ctx is None:
            raise RuntimeError("GLRasterizer was released; create a new one to render")
        return self._ctx

    def _framebuffer(self, width: int, height: int):
        """The ``width x height`` framebuffer, re-created only when the size changes."""
        if self._fbo is None or self._fbo.size != (width, height):
            self._release_fbo()
            size = (width, height)
            attachments = [self._ctx.texture(size, 4, dtype="f4")]
            if self._alpha:
                attachments.append(self._ctx.texture(size, 1, dtype="f4"))
            self._fbo = self._ctx.framebuffer(attachments, self._ctx.depth_texture(size))
        return self._fbo

    def render(
        self,
        intrinsics: Intrinsics,
        *,
        pose: np.ndarray | None = None,
        near: float = 1e-3,
        background: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> Fragments:
        """Render the mesh; arguments and result as :func:`raster.rasterize`.

        Returns:
            :class:`Fragments` of shape ``(intrinsics.height, intrinsics.width)``:
            ``color (H, W, 3) float32`` in [0, 1] (``(H, W, 4)`` with ``alpha``, 0
            where empty), ``depth (H, W) float32`` camera z (``+inf`` where empty),
            ``mask (H, W) bool``.
        """
        ctx = self._live()
        pose, bg = _check_view(intrinsics, pose, near, background)
        height, width = int(intrinsics.height), int(intrinsics.width)
        far = max(float((self._corners @ pose[2, :3]).max() + pose[2, 3]) * 1.01, 2.0 * near)
        with ctx:
            fbo = self._framebuffer(width, height)
            fbo.use()
            ctx.enable_only(_moderngl().DEPTH_TEST)
            ctx.depth_func = "<"
            fbo.clear(*bg, _EMPTY_Z, depth=1.0)
            self._prog["view"].write(pose.T.astype(np.float32).tobytes())
            for name, value in _projection(intrinsics, near, far).items():
                self._prog[name].value = value
            if self._n_indices:
                self._vao.render(vertices=self._n_indices)
            out = np.empty((height, width, 4), np.float32)
            fbo.read_into(out, components=4, dtype="f4")
            if self._alpha:
                alpha = np.empty((height, width), np.float32)
                fbo.read_into(alpha, components=1, attachment=1, dtype="f4")
        depth = out[:, :, 3]
        mask = depth < _EMPTY_Z * 0.5
        depth = np.where(mask, depth, np.float32(np.inf))
        if self._alpha:  # (r, g, b, alpha): the alpha over the camera z
            out[:, :, 3] = np.where(mask, alpha, np.float32(0.0))
            return Fragments(color=out, depth=depth, mask=mask)
        color = self._textured(np.ascontiguousarray(out[:, :, :3]), depth)
        return Fragments(color=color, depth=depth, mask=mask)

    def render_resolved(self, intrinsics: Intrinsics, factor: int, *, pose=None,
                        near: float = 1e-3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`render` then the supersampling resolve; as
        :meth:`photo3d.render.raster.CPURasterizer.render_resolved`."""
        from photo3d.render._kernels import resolve

        frag = self.render(intrinsics, pose=pose, near=near)
        return resolve(frag.color, frag.depth, int(factor))

    def _textured(self, color: np.ndarray, depth: np.ndarray) -> np.ndarray:
        """Deferred texturing on the CPU (the same lookup as the numba rasterizer)."""
        if self._texture.shape[0] == 0:
            return color
        from photo3d.render._kernels import apply_texture, pack_texture

        if self._packed is None:
            self._packed = pack_texture(self._texture)
        return apply_texture(color, depth, self._packed)

    def _release_fbo(self) -> None:
        if self._fbo is not None:
            for attachment in (*self._fbo.color_attachments, self._fbo.depth_attachment):
                attachment.release()
            self._fbo.release()
            self._fbo = None

    def release(self) -> None:
        """Free the GL objects and the context; later calls to :meth:`render` raise."""
        if self._ctx is None:
            return
        with self._ctx:
            self._release_fbo()
            for obj in (self._vao, self._prog, *self._buffers):
                obj.release()
        self._ctx.release()
        self._ctx = None

    def __enter__(self) -> GLRasterizer:
        return self

    def __exit__(self, *exc) -> None:
        self.release()
