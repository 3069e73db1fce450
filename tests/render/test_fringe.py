"""The soft silhouettes' fringe drawn in one pass: each sample takes the colour and
alpha of its triangle's corner of largest barycentric weight (the corner's cell),
against the cells split out explicitly and drawn twice, colours then alpha (how the
renderer drew it before, then with interpolated colours)."""

from __future__ import annotations

import numpy as np
import pytest
from test_raster import K, grid_faces, input_view_grid, look_pose

import photo3d
from photo3d.camera import Camera, Intrinsics
from photo3d.config import Config
from photo3d.errors import InputError
from photo3d.render._resolve import blend_fringe, to_rgb8
from photo3d.render.raster import CPURasterizer, rasterize
from photo3d.render.renderer import Renderer, video_settings


def cells(vertices, colors, alpha, faces):
    """Each triangle split at its edges' midpoints and centroid into its corners' cells
    (two triangles each), every cell with its corner's colour and alpha (what
    ``Mesh.cells`` did for the alpha): ``(vertices (18 M, 3), colors (18 M, 3)
    float32, alpha (18 M,), faces (6 M, 3))``."""
    v = vertices[faces]  # (M, 3, 3)
    centre = v.mean(axis=1)
    out_v, out_c, out_a = [], [], []
    for i in range(3):
        nxt, prev = (i + 1) % 3, (i + 2) % 3
        to_next, to_prev = (v[:, i] + v[:, nxt]) / 2, (v[:, i] + v[:, prev]) / 2
        out_v += [np.stack([v[:, i], to_next, centre], 1),
                  np.stack([v[:, i], centre, to_prev], 1)]
        out_c += [np.repeat(colors[faces[:, i]][:, None], 3, 1)] * 2
        out_a += [np.repeat(alpha[faces[:, i]][:, None], 3, 1)] * 2
    n = 6 * len(faces)
    return (np.concatenate(out_v).reshape(-1, 3).astype(np.float32),
            np.concatenate(out_c).reshape(-1, 3).astype(np.float32),
            np.concatenate(out_a).reshape(-1).astype(np.float32),
            np.arange(3 * n, dtype=np.int32).reshape(-1, 3))


def bumpy_grid(n: int = 24, seed: int = 4):
    """A bumpy, jittered grid with random colours and alphas, in front of ``K``."""
    rng = np.random.default_rng(seed)
    s, t = np.meshgrid(np.linspace(-1.2, 1.2, n), np.linspace(-0.9, 0.9, n), indexing="xy")
    s = s + rng.uniform(-0.3, 0.3, s.shape) * 2.4 / n
    t = t + rng.uniform(-0.3, 0.3, t.shape) * 1.8 / n
    z = 2.5 + 0.4 * np.sin(2 * s) * np.cos(3 * t) + rng.uniform(0, 0.05, s.shape)
    v = np.stack([s, t, z], -1).reshape(-1, 3).astype(np.float32)
    colors = rng.random((len(v), 3), dtype=np.float32)
    alpha = rng.random(len(v), dtype=np.float32)
    return v, colors, alpha, grid_faces(n, n)


def test_nearest_corner_is_each_pixels_own_at_the_input_camera():
    """Vertices on pixel centres: every sample within half a pixel of a vertex (one
    sample a pixel, or the 2 x 2 supersamples at a quarter pixel) takes exactly that
    vertex's colour and alpha (interpolated, each supersample would mix in its
    neighbours' by a quarter)."""
    rng = np.random.default_rng(2)
    depth = 2.0 + 0.5 * rng.random((K.height, K.width))
    v = input_view_grid(depth).astype(np.float32)
    colors = rng.random((len(v), 3), dtype=np.float32)
    alpha = rng.random(len(v), dtype=np.float32)
    frag = rasterize(v, colors, grid_faces(K.height, K.width), K, alpha=alpha)
    assert frag.color.shape == (K.height, K.width, 4) and frag.mask.all()
    assert np.array_equal(frag.color[..., 3], alpha.reshape(K.height, K.width))
    assert np.allclose(frag.color[..., :3], colors.reshape(K.height, K.width, 3), atol=1e-6)
    r = CPURasterizer(v, colors, grid_faces(K.height, K.width), alpha=alpha)
    big = Intrinsics(2 * K.fx, 2 * K.fy, 2 * K.cx, 2 * K.cy, 2 * K.width, 2 * K.height)
    color, coverage, _ = r.render_resolved(big, 2)
    inner = (slice(1, -1), slice(1, -1))  # the border pixels are covered in part
    assert coverage[inner].min() == 1.0
    assert np.allclose(color[..., 3][inner], alpha.reshape(K.height, K.width)[inner], atol=1e-6)
    assert np.allclose(color[..., :3][inner], colors.reshape(K.height, K.width, 3)[inner],
                       atol=1e-6)


@pytest.mark.parametrize("pose", [np.eye(4), look_pose(0.15, -0.25, (0.3, -0.1, 0.4))])
def test_one_pass_draws_the_image_of_the_cells_drawn_twice(pose):
    """The fringe drawn unsplit with the nearest corner's colour and alpha equals its
    cells drawn twice (colours, then alpha as grey), sample for sample: the same
    coverage and depth, and the same colours and alpha except at a few samples on a
    cell's edge (the cells' midpoints are snapped to the 1/256 px grid on their
    own)."""
    v, colors, alpha, faces = bumpy_grid()
    frag = rasterize(v, colors, faces, K, pose=pose, alpha=alpha)
    cv, cc, ca, cf = cells(v, colors, alpha, faces)
    ref = rasterize(cv, cc, cf, K, pose=pose)
    ref_alpha = rasterize(cv, np.repeat(ca[:, None], 3, 1), cf, K, pose=pose).color[..., 0]
    both = frag.mask & ref.mask
    assert frag.mask.sum() > 0.5 * frag.mask.size
    assert (frag.mask != ref.mask).sum() <= 0.002 * frag.mask.size
    assert np.allclose(frag.depth[both], ref.depth[both], rtol=1e-4)
    differ = np.abs(frag.color[..., 3] - ref_alpha)[both] > 1e-6
    assert differ.mean() < 0.005, differ.mean()
    same = both & (np.abs(frag.color[..., 3] - ref_alpha) <= 1e-6)
    assert np.abs(frag.color[..., :3][same] - ref.color[same]).max() < 1e-6
    assert not np.any(frag.color[..., 3][~frag.mask])  # no fringe: alpha 0


def test_alpha_is_averaged_with_supersampling_and_blended_at_depth_edges():
    """``render_resolved`` averages the alpha of the covered samples like the colours;
    ``render_edges`` carries it through its depth-edge blend like a colour channel."""
    v, colors, alpha, faces = bumpy_grid(seed=5)
    r = CPURasterizer(v, colors, faces, alpha=alpha)
    big = Intrinsics(2 * K.fx, 2 * K.fy, 2 * K.cx, 2 * K.cy, 2 * K.width, 2 * K.height)
    samples = rasterize(v, colors, faces, big, alpha=alpha)
    color, coverage, _ = r.render_resolved(big, 2)
    a = np.where(samples.mask, samples.color[..., 3], 0.0).reshape(K.height, 2, K.width, 2)
    n = samples.mask.reshape(K.height, 2, K.width, 2).sum(axis=(1, 3))
    mean = np.where(n > 0, a.sum(axis=(1, 3)) / np.maximum(n, 1), 0.0)
    assert np.allclose(color[..., 3], mean, atol=1e-6)
    assert np.allclose(coverage, n / 4)
    edges = r.render_edges(K, tolerance=0.01)[0]
    plain = r.render_edges(K, tolerance=0.0)[0]
    moved = np.abs(edges[..., :3] - plain[..., :3]).max(-1) > 0
    assert moved.any()  # the bumps have depth edges at this tolerance
    assert np.abs(edges[..., 3] - plain[..., 3])[~moved].max() == 0.0


def test_alpha_is_checked():
    v, colors, alpha, faces = bumpy_grid(n=4)
    with pytest.raises(InputError, match="alpha must have shape"):
        CPURasterizer(v, colors, faces, alpha=alpha[:-1])
    with pytest.raises(InputError, match="texture"):
        CPURasterizer(v, colors, faces, alpha=alpha, texture=np.zeros((2, 2, 3), np.uint8))


def test_a_frame_with_a_fringe_keeps_the_8_bit_path():
    """``render_rgb8`` of a light mesh with soft silhouettes gives ``render``'s colours
    in 8 bits: the fringe is blended into the 8-bit frame where it is drawn."""
    rng = np.random.default_rng(0)
    h, w = 48, 64
    image = np.empty((h, w, 3), np.float32)
    image[:] = (0.35 + 0.1 * rng.random((h, w, 1))) * np.array([0.6, 1.0, 0.8], np.float32)
    image[:, 30:34] = (0.9, 0.1, 0.1)
    depth = np.full((h, w), 6.0, np.float32)
    depth[:, 28:36] = 2.0
    config = Config(size=None, depth_kind="depth", spatial_scale=1.0, edges="soft")
    photo = photo3d.make(image, depth=depth, config=config)
    light = photo.light_mesh()
    assert light.overlay is not None
    camera = Camera.translated(photo.ldi.intrinsics, (0.05, 0.02, 0.0))
    with Renderer(light, video_settings(backend="numba")) as renderer:
        rgb = renderer.render_rgb8(camera)
        view = renderer.render(camera)
    assert np.array_equal(rgb, to_rgb8(view.color))
    with Renderer(light, video_settings(backend="numba")) as hard:
        hard._overlay = None
        opaque = hard.render_rgb8(camera)
    assert (np.abs(rgb.astype(int) - opaque).max(-1) > 8).sum() > 10  # the fringe is drawn


def test_the_fused_blend_equals_blending_the_fringes_own_frame():
    """``blend_edges`` (the videos' path) gives the frame ``blend_fringe`` makes of
    ``render_edges``'s result, in float and in 8 bits, and touches no other pixel."""
    v, colors, alpha, faces = bumpy_grid(seed=6)
    alpha[::3] = 0.0  # transparent corners: not blended
    r = CPURasterizer(v, colors, faces, alpha=alpha)
    rng = np.random.default_rng(1)
    under = rng.random((K.height, K.width, 3), dtype=np.float32)
    depth = np.full((K.height, K.width), 2.6, np.float32)  # the bumps cross it
    depth[:, :8] = np.inf  # a hole
    rgb = to_rgb8(under)
    f_color, f_coverage, f_depth = r.render_edges(K, tolerance=0.03)
    expected, expected_depth, expected_rgb = under.copy(), depth.copy(), rgb.copy()
    blend_fringe(expected, expected_depth, f_color, f_coverage, f_depth, expected_rgb)
    changed = np.any(expected != under, axis=-1)
    assert 0.1 < changed.mean() < 0.9
    r.blend_edges(K, under, depth, tolerance=0.03, rgb=rgb)
    assert np.allclose(under, expected, atol=1e-6)
    assert np.array_equal(depth, expected_depth)
    assert np.array_equal(rgb, expected_rgb)
    assert np.array_equal(rgb, to_rgb8(under))
    with pytest.raises(InputError, match="color must be"):
        r.blend_edges(K, under[:-1], depth)
