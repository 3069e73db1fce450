"""The OpenGL rasterizer against the numba rasterizer on the same synthetic scenes."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from conftest import merge, quad

pytest.importorskip("moderngl")

from photo3d.camera import Intrinsics, unproject  # noqa: E402
from photo3d.errors import InputError  # noqa: E402
from photo3d.render.gl import (  # noqa: E402
    GLRasterizer,
    gl_available,
    gl_renderer,
    is_software_renderer,
)
from photo3d.render.raster import Fragments, rasterize  # noqa: E402

pytestmark = pytest.mark.skipif(not gl_available(), reason="no OpenGL 3.3 EGL context")

K = Intrinsics.default(64, 48)  # fx = fy = 64, principal point (32, 24)


def grid_faces(rows: int, cols: int) -> np.ndarray:
    """``(2 (rows-1) (cols-1), 3) int32`` triangles over a row-major vertex grid."""
    idx = np.arange(rows * cols).reshape(rows, cols)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    return np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)]).astype(np.int32)


def look_pose(rx: float, ry: float, t: tuple[float, float, float]) -> np.ndarray:
    """Camera-from-world pose: rotation about x then y (radians), then translation."""
    cx, sx, cy, sy = np.cos(rx), np.sin(rx), np.cos(ry), np.sin(ry)
    rot_x = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    rot_y = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    pose = np.eye(4)
    pose[:3, :3] = rot_x @ rot_y
    pose[:3, 3] = t
    return pose


def textured_grid(margin: int = 1, seed: int = 0):
    """Vertices on the pixel centres of ``K`` at z = 2, ``margin`` px beyond the image."""
    rows, cols = K.height + 2 * margin, K.width + 2 * margin
    yy, xx = np.mgrid[0:rows, 0:cols] - margin
    v = unproject(xx.ravel(), yy.ravel(), np.full(xx.size, 2.0), K)
    colors = np.random.default_rng(seed).random((v.shape[0], 3), dtype=np.float32)
    return v, colors, grid_faces(rows, cols)


def jittered_grid(n: int = 30, seed: int = 1):
    """A bumpy grid with jittered vertices and random colours in front of an oblique camera."""
    rng = np.random.default_rng(seed)
    s, t = np.meshgrid(np.linspace(-1.5, 1.5, n), np.linspace(-1.2, 1.2, n), indexing="ij")
    s = s + rng.uniform(-0.3, 0.3, s.shape) * 3 / n
    t = t + rng.uniform(-0.3, 0.3, t.shape) * 3 / n
    z = 3.0 + 0.4 * np.sin(2 * s) * np.cos(3 * t) + 0.5 * s
    v = np.stack([s.ravel(), t.ravel(), z.ravel()], 1).astype(np.float32)
    colors = rng.integers(0, 256, (v.shape[0], 3), dtype=np.uint8)
    return v, colors, grid_faces(n, n)


def render_both(vertices, colors, faces, k=K, **kwargs) -> tuple[Fragments, Fragments]:
    with GLRasterizer(vertices, colors, faces) as gl:
        gpu = gl.render(k, **kwargs)
    return gpu, rasterize(vertices, colors, faces, k, **kwargs)


def assert_same_image(gpu: Fragments, cpu: Fragments, *, min_covered: int = 200) -> None:
    """PSNR > 35 dB and depth within 1e-3 where both cover; masks agree on > 99.5 %."""
    assert gpu.color.shape == cpu.color.shape and gpu.color.dtype == np.float32
    assert gpu.depth.dtype == np.float32 and gpu.mask.dtype == bool
    assert np.mean(gpu.mask == cpu.mask) > 0.995
    both = gpu.mask & cpu.mask
    assert both.sum() >= min_covered
    mse = np.mean((gpu.color[both] - cpu.color[both]) ** 2)
    assert mse == 0 or 10 * np.log10(1.0 / mse) > 35.0, mse
    np.testing.assert_allclose(gpu.depth[both], cpu.depth[both], rtol=1e-3)
    assert np.all(np.isinf(gpu.depth[~gpu.mask])) and np.all(np.isfinite(gpu.depth[gpu.mask]))


def test_input_view_reproduces_vertex_colours():
    v, colors, faces = textured_grid()
    gpu, cpu = render_both(v, colors, faces)
    expected = colors.reshape(K.height + 2, K.width + 2, 3)[1:-1, 1:-1]
    assert gpu.mask.all() and cpu.mask.all()
    np.testing.assert_allclose(gpu.color, expected, atol=1e-5)
    np.testing.assert_allclose(cpu.color, expected, atol=1e-5)
    np.testing.assert_allclose(gpu.depth, 2.0, rtol=1e-6)


def test_moved_and_rotated_grid_matches_cpu():
    v, colors, faces = textured_grid(margin=8)
    pose = look_pose(0.08, -0.12, (0.1, -0.05, 0.3))
    assert_same_image(*render_both(v, colors, faces, pose=pose, background=(1.0, 0.0, 1.0)))


@pytest.mark.parametrize("near_first", [True, False])
def test_overlapping_quads_nearest_wins(near_first):
    near = quad(-0.3, -0.3, 0.3, 0.3, 1.0, (1, 0, 0))
    far = quad(-1.0, -0.2, 0.0, 0.2, 2.0, (0, 0, 1))
    v, c, f = merge(near, far) if near_first else merge(far, near)
    gpu, cpu = render_both(v, c, f)
    assert_same_image(gpu, cpu)
    assert np.all(gpu.color[24, 20] == [1, 0, 0]) and gpu.depth[24, 20] == pytest.approx(1.0)
    assert np.all(gpu.color[24, 5] == [0, 0, 1]) and gpu.depth[24, 5] == pytest.approx(2.0)
    assert not gpu.mask[2, 2] and np.all(gpu.color[2, 2] == 0)


def test_depth_resolves_nearly_coplanar_far_surfaces():
    # 0.05 % apart at z = 20 with near = 1e-3: below a standard 24-bit z-buffer's step.
    far = quad(-20, -20, 20, 20, 20.01, (0, 0, 1))
    near = quad(-20, -20, 20, 20, 20.0, (1, 0, 0))
    gpu, cpu = render_both(*merge(far, near))
    assert gpu.mask.all() and np.all(gpu.color == [1, 0, 0])
    np.testing.assert_allclose(gpu.depth, 20.0, rtol=1e-6)
    assert_same_image(gpu, cpu)


def test_jittered_grid_from_an_oblique_pose_matches_cpu():
    v, colors, faces = jittered_grid()
    pose = look_pose(0.25, -0.35, (0.6, 0.1, 0.4))
    k = Intrinsics.default(160, 120)
    assert_same_image(*render_both(v, colors, faces, k, pose=pose), min_covered=5000)


def test_floor_crossing_the_near_plane_matches_cpu():
    xs, zs = np.linspace(-20.13, 19.87, 41), np.linspace(-5.07, 39.93, 10)
    zz, xx = np.meshgrid(zs, xs, indexing="ij")
    v = np.stack([xx.ravel(), np.ones(xx.size), zz.ravel()], 1).astype(np.float32)
    colors = ((v[:, [0, 2, 0]] + 40) / 80).astype(np.float32)
    gpu, cpu = render_both(v, colors, grid_faces(len(zs), len(xs)), near=0.5)
    assert_same_image(gpu, cpu)
    assert gpu.mask[30:].all() and not gpu.mask[:24].any()


def test_camera_shift_moves_plane_by_focal_times_shift_over_depth():
    z, t = 2.0, 0.23  # shift of fx t / z = 7.36 px
    black, white = (
        quad(-2.0, -2.0, 0.05, 2.0, z, (0, 0, 0)),
        quad(0.05, -2.0, 2.0, 2.0, z, (1, 1, 1)),
    )
    v, c, f = merge(black, white)
    with GLRasterizer(v, c, f) as gl:
        for shift in (0.0, t):
            pose = np.eye(4)
            pose[0, 3] = -shift  # camera centre moved to x = +shift
            out = gl.render(K, pose=pose, background=(0.5, 0.5, 0.5))
            assert out.mask.all()
            edge = K.fx * (0.05 - shift) / z + K.cx  # expected step position, pixels
            step = K.width - out.color[:, :, 0].sum(axis=1)  # first white column, per row
            assert np.all(np.abs(step - edge) <= 0.5), (shift, edge, step[0])


def test_uint8_and_float_colours_agree_and_sizes_change():
    v, colors, faces = jittered_grid()
    pose = look_pose(0.1, 0.2, (-0.2, 0.0, 0.2))
    with GLRasterizer(v, colors, faces) as a, GLRasterizer(v, colors / 255.0, faces) as b:
        for k in (K, Intrinsics.default(80, 50), K):  # alternate contexts and sizes
            x, y = a.render(k, pose=pose), b.render(k, pose=pose)
            assert x.color.shape == (k.height, k.width, 3)
            np.testing.assert_allclose(x.color, y.color, atol=1e-4)  # GPU unorm8 -> float
            np.testing.assert_array_equal(x.mask, y.mask)
            assert_same_image(x, rasterize(v, colors, faces, k, pose=pose))


def test_empty_faces_give_the_background():
    with GLRasterizer(np.zeros((3, 3), np.float32), np.zeros((3, 3)), []) as gl:
        out = gl.render(K, background=(0.1, 0.2, 0.3))
    assert out.color.shape == (48, 64, 3) and not out.mask.any()
    np.testing.assert_allclose(out.color, np.broadcast_to([0.1, 0.2, 0.3], (48, 64, 3)))
    assert np.all(np.isinf(out.depth))


def test_gl_available_is_a_cached_bool_and_names_the_renderer():
    assert gl_available() is True and gl_available() is True
    name = gl_renderer()
    v, c, f = quad(-1, -1, 1, 1, 2.0, (1, 1, 1))
    with GLRasterizer(v, c, f) as gl:
        assert gl.renderer == name and name
    assert isinstance(is_software_renderer(name), bool)
    assert is_software_renderer("softpipe") and is_software_renderer("Mesa llvmpipe (LLVM 15)")
    assert not is_software_renderer("AMD Radeon RX 6800 (radeonsi, navi21, LLVM 15.0.6)")


def test_render_after_release_raises():
    v, c, f = quad(-1, -1, 1, 1, 2.0, (1, 1, 1))
    gl = GLRasterizer(v, c, f)
    assert gl.render(K).mask.any()
    gl.release()
    gl.release()  # idempotent
    with pytest.raises(RuntimeError, match="released"):
        gl.render(K)
    with pytest.raises(RuntimeError, match="released"):
        _ = gl.renderer


def test_invalid_inputs_raise_input_error():
    v, c, f = quad(-1, -1, 1, 1, 2.0, (1, 1, 1))
    with pytest.raises(InputError, match="faces index vertices out of range"):
        GLRasterizer(v, c, f + 2)
    with pytest.raises(InputError, match="non-finite"):
        GLRasterizer(np.where(v == 1, np.nan, v), c, f)
    with GLRasterizer(v, c, f) as gl:
        with pytest.raises(InputError, match="pose"):
            gl.render(K, pose=np.eye(3))
        with pytest.raises(InputError, match="near"):
            gl.render(K, near=0.0)


def test_unusable_device_raises_runtime_error(monkeypatch):
    monkeypatch.delenv("GLCONTEXT_DEVICE_INDEX", raising=False)
    v, c, f = quad(-1, -1, 1, 1, 2.0, (1, 1, 1))
    with pytest.raises(RuntimeError, match="cannot create an OpenGL 3.3 EGL context") as err:
        GLRasterizer(v, c, f, device_index=999)
    assert "\n" not in str(err.value)


def test_missing_moderngl_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "moderngl", None)
    v, c, f = quad(-1, -1, 1, 1, 2.0, (1, 1, 1))
    with pytest.raises(ImportError, match=r"pip install 'photo3d\[gl\]'"):
        GLRasterizer(v, c, f)


def test_textured_mesh_matches_cpu():
    """A tilted textured quad: OpenGL (texture looked up after rasterizing) and numba agree."""
    from photo3d.render.raster import CPURasterizer

    rng = np.random.default_rng(4)
    tex = rng.integers(0, 256, (16, 20, 3), dtype=np.uint8)
    v = np.array([[-1, -0.8, 2.0], [1.2, -0.7, 3.0], [-0.9, 0.9, 2.2], [1.1, 1.0, 3.4]],
                 np.float32)
    uv = np.array([[0.05, 0.1, 0], [0.9, 0.05, 0], [0.1, 0.95, 0], [0.95, 0.9, 0]], np.float32)
    faces = np.array([[0, 2, 1], [1, 2, 3]], np.int32)
    pose = look_pose(0.05, -0.08, (0.02, -0.01, 0.0))
    with GLRasterizer(v, uv, faces, texture=tex) as gl:
        a = gl.render(K, pose=pose)
    b = CPURasterizer(v, uv, faces, texture=tex).render(K, pose=pose)
    both = a.mask & b.mask
    assert both.mean() > 0.5
    assert np.abs(a.color[both] - b.color[both]).mean() < 0.5 / 255
    # not the untextured image: the lookup happened
    untextured = CPURasterizer(v, uv, faces).render(K, pose=pose)
    assert np.abs(untextured.color[both] - b.color[both]).mean() > 0.05


@pytest.mark.parametrize("near", [1e-3, 2.9])
def test_fringe_alpha_of_the_nearest_corner_matches_the_cells(near):
    """A mesh with ``alpha``: the geometry shader's nearest-corner colour and alpha
    (fourth colour channel) equal those of the triangles' cells drawn on the CPU at
    all but a few samples (cell edges, fill rules), also with the near plane cutting
    through the grid (GL clips after the shader)."""
    from test_fringe import cells

    v, colors, faces = jittered_grid()
    alpha = np.random.default_rng(7).random(len(v), dtype=np.float32)
    pose = look_pose(0.25, -0.35, (0.6, 0.1, 0.4))
    k = Intrinsics.default(160, 120)
    with GLRasterizer(v, colors, faces, alpha=alpha) as gl:
        gpu = gl.render(k, pose=pose, near=near)
    cpu = rasterize(v, colors, faces, k, pose=pose, near=near, alpha=alpha)
    assert gpu.color.shape == (120, 160, 4)
    cv, cc, ca, cf = cells(v, colors / np.float32(255), alpha, faces)
    ref = rasterize(cv, cc, cf, k, pose=pose, near=near)
    ref_alpha = rasterize(cv, np.repeat(ca[:, None], 3, 1), cf, k, pose=pose, near=near)
    assert_same_image(Fragments(gpu.color[..., :3].copy(), gpu.depth, gpu.mask), ref,
                      min_covered=3000)
    both = gpu.mask & ref.mask
    differ = np.abs(gpu.color[..., 3] - ref_alpha.color[..., 0])[both] > 1e-6
    assert differ.mean() < 0.005, differ.mean()
    if near < 1:  # the CPU's too (it approximates the cells of clipped triangles)
        differ = np.abs(gpu.color - cpu.color).max(-1)[both & cpu.mask] > 1e-5
        assert differ.mean() < 0.005, differ.mean()
    assert not np.any(gpu.color[..., 3][~gpu.mask])
    with GLRasterizer(v, colors, faces, alpha=alpha) as gl:
        color, coverage, _ = gl.render_resolved(Intrinsics.default(160, 120), 2, pose=pose)
    assert color.shape == (60, 80, 4) and coverage.max() == 1.0


def test_renderer_draws_soft_silhouettes_with_gl_as_with_numba():
    """``Renderer`` with a fringe (soft silhouettes) on OpenGL: the same view as numba."""
    import photo3d
    from photo3d.camera import Camera
    from photo3d.config import Config
    from photo3d.render.renderer import Renderer, RenderSettings

    rng = np.random.default_rng(0)
    image = (0.35 + 0.1 * rng.random((48, 64, 1))) * np.array([0.6, 1.0, 0.8], np.float32)
    image[:, 30:34] = (0.9, 0.1, 0.1)
    depth = np.full((48, 64), 6.0, np.float32)
    depth[:, 28:36] = 2.0
    config = Config(size=None, depth_kind="depth", spatial_scale=1.0, edges="soft")
    photo = photo3d.make(image.astype(np.float32), depth=depth, config=config)
    camera = Camera.translated(photo.ldi.intrinsics, (0.3, 0.05, 0.0))
    views = {}
    for backend in ("numba", "gl"):
        with Renderer(photo.mesh(), RenderSettings(backend=backend)) as renderer:
            views[backend] = renderer.render(camera).color
    mse = np.mean((views["gl"] - views["numba"]) ** 2)
    assert mse == 0 or 10 * np.log10(1.0 / mse) > 40.0, mse
