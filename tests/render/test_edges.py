"""One sample per pixel antialiased at depth edges (the videos' renderer path), row spans
of large triangles and per-tile culling of hidden ones, against the reference paths."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import exact_config, texture
from test_raster import K, coverage_count, input_view_grid, look_pose

import photo3d
from photo3d.camera import Camera, Intrinsics
from photo3d.errors import ConfigError
from photo3d.render._kernels import EDGE_BLEND
from photo3d.render.raster import CPURasterizer, rasterize
from photo3d.render.renderer import AUTHORS_CROP, Renderer, RenderSettings, video_settings


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    return float(10 * np.log10(1.0 / np.mean((a.astype(np.float64) - b) ** 2)))


def test_large_triangles_cover_exactly_the_pixel_centres_inside_them():
    """Rows of wide triangles are scanned only between their edges: the coverage still
    equals a point-in-triangle test at every pixel centre off the edges."""
    rng = np.random.default_rng(11)
    centres = np.stack(np.meshgrid(np.arange(64) + 0.5, np.arange(48) + 0.5), -1)
    for _ in range(40):
        corners = rng.uniform([-20, -15], [84, 63], (3, 2))  # often wider than the image
        depth = rng.uniform(1.0, 3.0, 3)
        v = np.column_stack([(corners - [K.cx, K.cy]) / K.fx * depth[:, None], depth])
        count = coverage_count(v.astype(np.float32), np.ones((3, 3), np.float32),
                               np.array([[0, 1, 2]], np.int32), K)
        a, b, c = (np.round(p * 256) / 256 for p in corners)  # the rasterizer's snapping
        edge = [(q[0] - p[0]) * (centres[..., 1] - p[1]) - (q[1] - p[1]) * (centres[..., 0] - p[0])
                for p, q in ((b, c), (c, a), (a, b))]
        area = edge[0] + edge[1] + edge[2]
        signs = np.stack(edge) * np.sign(area)
        length = [np.hypot(*(q - p)) for p, q in ((b, c), (c, a), (a, b))]
        off_edges = np.all(np.abs(np.stack(edge)) > 1e-3 * np.array(length)[:, None, None], 0)
        inside = np.all(signs > 0, 0)
        assert np.array_equal(count[off_edges], inside[off_edges].astype(np.int32))


def test_hidden_large_triangles_skipped_per_tile_change_nothing():
    """Large triangles drawn after the first faces are skipped tile by tile where
    those are nearer: the image is that of drawing everything."""
    from test_raster import grid_faces

    rng = np.random.default_rng(12)
    depth = np.full((48, 64), 2.0)
    depth[:, 30:] = 1.2  # a depth step
    near = input_view_grid(depth)
    grid = grid_faces(48, 64)
    near_faces = grid[(near[grid][..., 0] / near[grid][..., 2]).max(1) < (50 - K.cx) / K.fx]
    # a large slanted quad: behind the grid on the left, in front of it on the right,
    # alone in the grid's gap at the right border
    corners = np.array([[-10, -10], [74, -10], [-10, 58], [74, 58]], np.float64)
    z = np.array([4.0, 1.0, 4.0, 1.0])
    far = np.column_stack([(corners - [K.cx, K.cy]) / K.fx * z[:, None], z])
    vertices = np.concatenate([near, far]).astype(np.float32)
    n = len(near)
    faces = np.concatenate([near_faces, [[n, n + 1, n + 2], [n + 1, n + 3, n + 2]]])
    colours = rng.uniform(0, 1, (len(vertices), 3)).astype(np.float32)
    for t in ((0.0, 0.0, 0.0), (0.05, -0.02, 0.1)):
        pose = look_pose(0.01, -0.02, t)
        every = rasterize(vertices, colours, faces, K, pose=pose)
        culled = rasterize(vertices, colours, faces, K, pose=pose, first=len(near_faces))
        grid_z = rasterize(vertices, colours, near_faces, K, pose=pose).depth
        quad_z = rasterize(vertices, colours, faces[len(near_faces):], K, pose=pose).depth
        assert ((quad_z < grid_z) & (grid_z < np.inf)).sum() > 100  # in front of the grid
        assert (quad_z > grid_z).sum() > 300  # behind it: culled
        np.testing.assert_array_equal(every.color, culled.color)
        np.testing.assert_array_equal(every.depth, culled.depth)


def _scene(textured: bool):
    """A far plane and a nearer slanted square in front of it: vertices, colours or
    texture coordinates, faces, texture."""
    far = np.array([[-4, -3, 5], [4, -3, 5], [-4, 3, 5], [4, 3, 5]], np.float32)
    near = np.array([[-0.8, -0.9, 2.0], [0.9, -0.7, 2.1], [-0.7, 0.8, 2.0], [0.8, 0.9, 2.2]],
                    np.float32)
    vertices = np.concatenate([near, far])
    faces = np.array([[0, 1, 2], [1, 3, 2], [4, 5, 6], [5, 7, 6]], np.int32)
    if not textured:
        colours = np.array([[0.9, 0.2, 0.1]] * 4 + [[0.1, 0.3, 0.8]] * 4, np.float32)
        return vertices, colours, faces, None
    tex = (texture(16, 32, seed=3) * 255).astype(np.uint8)
    uv = np.zeros((8, 3), np.float32)
    uv[:4, :2] = [[0.1, 0.1], [0.4, 0.1], [0.1, 0.9], [0.4, 0.9]]
    uv[4:, :2] = [[0.6, 0.1], [0.9, 0.1], [0.6, 0.9], [0.9, 0.9]]
    return vertices, uv, faces, tex


@pytest.mark.parametrize("textured", [False, True])
def test_edges_without_a_tolerance_are_the_one_sample_render(textured):
    vertices, colours, faces, tex = _scene(textured)
    r = CPURasterizer(vertices, colours, faces, texture=tex)
    pose = look_pose(0.02, 0.05, (0.1, 0.0, 0.0))
    for got, expected in zip(r.render_edges(K, pose=pose, tolerance=0.0),
                             r.render_resolved(K, 1, pose=pose), strict=True):
        np.testing.assert_array_equal(got, expected)


def test_pixels_across_a_depth_edge_take_an_eighth_of_each_neighbour():
    vertices, colours, faces, _ = _scene(False)
    r = CPURasterizer(vertices, colours, faces)
    plain, _, depth = r.render_resolved(K, 1)
    smooth, coverage, depth2 = r.render_edges(K, tolerance=0.03)
    np.testing.assert_array_equal(depth, depth2)
    assert coverage.min() == 1.0
    near = depth < 3
    pad = np.pad(near, 1, mode="edge")
    neighbours = [pad[:-2, 1:-1], pad[2:, 1:-1], pad[1:-1, :-2], pad[1:-1, 2:]]
    across = sum((n != near).astype(int) for n in neighbours)
    assert (across > 0).sum() > 50
    other = np.where(near[..., None], colours[4], colours[0])
    assert EDGE_BLEND == 1 / 8
    expected = plain + across[..., None] * (other - plain) / 8
    np.testing.assert_allclose(smooth, expected, atol=1e-6)


@pytest.mark.parametrize("textured", [False, True])
def test_edge_blend_is_nearer_to_supersampling_than_one_sample(textured):
    vertices, colours, faces, tex = _scene(textured)
    r = CPURasterizer(vertices, colours, faces, texture=tex)
    pose = look_pose(0.03, -0.04, (0.05, 0.02, 0.0))
    big = Intrinsics(K.fx * 4, K.fy * 4, K.cx * 4, K.cy * 4, K.width * 4, K.height * 4)
    reference = r.render_resolved(big, 4, pose=pose)[0]
    one = r.render_resolved(K, 1, pose=pose)[0]
    edges = r.render_edges(K, pose=pose)[0]
    assert psnr(edges, reference) > psnr(one, reference) + 1.0


def test_textured_meshes_take_the_edges_path_unless_asked_otherwise():
    vertices, uv, faces, tex = _scene(True)
    from photo3d.structures.mesh import TexturedMesh

    mesh = TexturedMesh(vertices=vertices, uv=uv[:, :2].copy(), texture=tex,
                        labels=np.ones(8, np.uint8), faces=faces, n_input=2, width=64,
                        height=48, hfov=1.0, vfov=0.8)
    cam = Camera(K, look_pose(0.02, 0.05, (0.1, 0.0, 0.0)))

    def view(antialias):
        settings = RenderSettings(backend="numba", antialias=antialias)
        with Renderer(mesh, settings) as renderer:
            return renderer.render(cam).color

    auto, edges, full = view("auto"), view("edges"), view("full")
    np.testing.assert_array_equal(auto, edges)
    assert not np.array_equal(auto, full)
    assert psnr(auto, full) > 30
    with pytest.raises(ConfigError, match="antialias"):
        RenderSettings(antialias="msaa")


def test_video_path_agrees_with_the_full_mesh_supersampled():
    """The light mesh at one sample per pixel, antialiased at depth edges (what videos
    use), against the full mesh with 2x2 samples (what they used before)."""
    img = texture(60, 80, seed=4)
    depth = np.ones((60, 80), np.float32)
    depth[15:45, 25:55] = 2.5  # a near box: depth edges and a disocclusion
    photo = photo3d.make(img, depth=depth, config=exact_config(border=6))
    k = photo.ldi.intrinsics
    settings = video_settings(backend="numba")
    reference = RenderSettings(ssaa=2, antialias="full", crop=AUTHORS_CROP, backend="numba")
    with Renderer(photo.light_mesh(), settings) as fast, \
            Renderer(photo.mesh(), reference) as slow:
        for t in ((0.0, 0.0, 0.0), (0.02, -0.01, 0.03), (-0.03, 0.0, -0.02)):
            pose = np.eye(4)
            pose[:3, 3] = t
            a, b = fast.render(Camera(k, pose)).color, slow.render(Camera(k, pose)).color
            assert psnr(a, b) > 30


@pytest.mark.parametrize("fill", [True, False])
def test_video_frames_in_8_bits_are_the_render_in_8_bits(fill):
    """``render_rgb8`` (8-bit colours written by the rasterizer, holes converted after
    the fill) gives the frame ``to_rgb8(render().color)`` gives, holes included."""
    from photo3d.render._resolve import to_rgb8

    img = texture(60, 80, seed=5)
    depth = np.ones((60, 80), np.float32)
    depth[15:45, 25:55] = 2.5
    photo = photo3d.make(img, depth=depth, config=exact_config(border=6))
    settings = video_settings(backend="numba", fill_holes=fill)
    with Renderer(photo.light_mesh(), settings) as renderer:
        for t in ((0.0, 0.0, 0.0), (0.06, -0.03, 0.05)):
            pose = np.eye(4)
            pose[:3, 3] = t
            camera = Camera(photo.ldi.intrinsics, pose)
            rgb = renderer.render_rgb8(camera)
            view = renderer.render(camera)
            assert rgb.dtype == np.uint8 and rgb.shape == view.color.shape
            diff = np.abs(rgb.astype(int) - to_rgb8(view.color))
            assert diff.max() <= 1 and np.mean(diff > 0) < 1e-3
            if t[0]:
                assert not view.mask.all()  # holes were filled (or shown) in both
