"""Known answers for the numba rasterizer on synthetic scenes."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import merge, quad
from scipy.spatial import ConvexHull

from photo3d.camera import Intrinsics, unproject
from photo3d.errors import InputError
from photo3d.render import raster
from photo3d.render.raster import Fragments, rasterize

K = Intrinsics.default(64, 48)  # fx = fy = 64, principal point (32, 24)


def grid_faces(rows: int, cols: int, *, anti: bool = False, flip: bool = False) -> np.ndarray:
    """``(2 (rows-1) (cols-1), 3) int32`` triangles over a row-major vertex grid."""
    idx = np.arange(rows * cols).reshape(rows, cols)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    if anti:
        tris = [np.stack([a, b, c], 1), np.stack([b, d, c], 1)]
    else:
        tris = [np.stack([a, b, d], 1), np.stack([a, d, c], 1)]
    faces = np.concatenate(tris).astype(np.int32)
    return faces[:, ::-1].copy() if flip else faces


def look_pose(rx: float, ry: float, t: tuple[float, float, float]) -> np.ndarray:
    """Camera-from-world pose: rotation about x then y (radians), then translation."""
    cx, sx, cy, sy = np.cos(rx), np.sin(rx), np.cos(ry), np.sin(ry)
    rot_x = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    rot_y = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    pose = np.eye(4)
    pose[:3, :3] = rot_x @ rot_y
    pose[:3, 3] = t
    return pose


def to_world(points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Camera coordinates of ``pose`` -> world coordinates."""
    return (np.asarray(points, np.float64) - pose[:3, 3]) @ pose[:3, :3]


def coverage_count(vertices, colors, faces, k, *, pose=None, bands=2) -> np.ndarray:
    """``(H, W) int32`` number of triangles that cover each pixel centre."""
    v, c, scale, f, rot, trans = raster.prepare_mesh(vertices, colors, faces, pose)
    kk = np.array([k.fx, k.fy, k.cx, k.cy])
    count = np.zeros((k.height, k.width), np.int32)
    bg = np.zeros(3, np.float32)
    raster._render(v, c, scale, f, rot, trans, kk, 1e-3, k.height, k.width, bands, bg, count)
    return count


def project(points: np.ndarray, k: Intrinsics, pose: np.ndarray) -> np.ndarray:
    """``(N, 2) float64`` image coordinates of world points."""
    cam = points.astype(np.float64) @ pose[:3, :3].T + pose[:3, 3]
    return np.stack([k.fx * cam[:, 0] / cam[:, 2] + k.cx, k.fy * cam[:, 1] / cam[:, 2] + k.cy], 1)


def pixel_centres(k: Intrinsics) -> np.ndarray:
    yy, xx = np.mgrid[0 : k.height, 0 : k.width]
    return np.stack([xx.ravel() + 0.5, yy.ravel() + 0.5], 1)


def input_view_grid(depth: np.ndarray) -> np.ndarray:
    """Vertices on the pixel centres of the input view ``K`` at ``depth`` (H, W)."""
    yy, xx = np.mgrid[0 : depth.shape[0], 0 : depth.shape[1]]
    return unproject(xx.ravel(), yy.ravel(), depth.ravel(), K)


@pytest.mark.parametrize(("anti", "flip"), [(False, False), (True, False), (False, True)])
def test_input_view_reproduces_vertex_colours(anti, flip):
    rng = np.random.default_rng(0)
    vertices = input_view_grid(np.full((48, 64), 2.0))
    colors = rng.random((48 * 64, 3), dtype=np.float32)
    out = rasterize(vertices, colors, grid_faces(48, 64, anti=anti, flip=flip), K)
    assert isinstance(out, Fragments)
    assert out.color.shape == (48, 64, 3) and out.color.dtype == np.float32
    assert out.depth.dtype == np.float32 and out.mask.dtype == bool
    assert out.mask.all()
    np.testing.assert_allclose(out.color, colors.reshape(48, 64, 3), atol=1e-6, rtol=0)
    np.testing.assert_allclose(out.depth, 2.0, rtol=1e-6)


def test_input_view_covers_exactly_the_vertices_of_kept_faces():
    # Random depths and a random half of the faces: borders, holes and lone triangles.
    rng = np.random.default_rng(1)
    depth = rng.uniform(0.4, 20.0, (48, 64))
    vertices = input_view_grid(depth)
    colors = rng.random((48 * 64, 3), dtype=np.float32)
    faces = grid_faces(48, 64)
    faces = faces[rng.random(len(faces)) < 0.3]
    used = np.zeros(48 * 64, bool)
    used[faces.ravel()] = True
    out = rasterize(vertices, colors, faces, K, background=(1.0, 0.0, 1.0))
    np.testing.assert_array_equal(out.mask.ravel(), used)
    np.testing.assert_allclose(out.color.reshape(-1, 3)[used], colors[used], atol=1e-6, rtol=0)
    np.testing.assert_allclose(out.depth.ravel()[used], depth.ravel()[used], rtol=1e-6)
    assert np.all(out.color.reshape(-1, 3)[~used] == [1.0, 0.0, 1.0])
    assert np.all(np.isinf(out.depth.ravel()[~used]))


@pytest.mark.parametrize("near_first", [True, False])
def test_nearest_surface_wins_regardless_of_order(near_first):
    near = quad(-0.3, -0.3, 0.3, 0.3, 1.0, (1, 0, 0))  # pixels 12.8 .. 51.2 wide
    far = quad(-1.0, -0.2, 0.0, 0.2, 2.0, (0, 0, 1))  # pixels 0 .. 32 wide
    v, c, f = merge(near, far) if near_first else merge(far, near)
    out = rasterize(v, c, f, K)
    assert np.all(out.color[24, 20] == [1, 0, 0]) and out.depth[24, 20] == 1.0  # overlap
    assert np.all(out.color[24, 5] == [0, 0, 1]) and out.depth[24, 5] == 2.0  # far only
    assert np.all(out.color[24, 40] == [1, 0, 0])  # near only
    assert not out.mask[2, 2]


def test_perspective_correct_interpolation():
    # Plane z = 2 + 0.8 x with a colour ramp linear in 3D.
    corners = np.array([[-1, -1], [0.6, -1], [0.6, 1], [-1, 1]], np.float64)
    pts = np.stack([corners[:, 0], corners[:, 1], 2 + 0.8 * corners[:, 0]], 1)

    def ramp(p):
        return np.stack([(p[:, 0] + 1) / 1.6, (p[:, 1] + 1) / 2, (p[:, 2] - 1.2) / 1.28], 1)

    faces = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    out = rasterize(pts.astype(np.float32), ramp(pts).astype(np.float32), faces, K)
    centres = pixel_centres(K)
    rays = np.stack([(centres[:, 0] - K.cx) / K.fx, (centres[:, 1] - K.cy) / K.fy], 1)
    t = 2.0 / (1.0 - 0.8 * rays[:, 0])
    hit = np.stack([rays[:, 0] * t, rays[:, 1] * t, t], 1)
    inside = (hit[:, 0] > -0.99) & (hit[:, 0] < 0.59) & (np.abs(hit[:, 1]) < 0.99)
    assert inside.sum() > 500
    assert out.mask.ravel()[inside].all()
    got = out.color.reshape(-1, 3)[inside]
    np.testing.assert_allclose(got, ramp(hit[inside]), atol=1e-3, rtol=0)
    np.testing.assert_allclose(out.depth.ravel()[inside], t[inside], rtol=1e-5)
    # The ramp is far from linear in screen space, so affine interpolation would fail.
    row = ramp(hit.reshape(48, 64, 3)[24, [2, 20, 38]])[:, 0]
    assert abs(row[1] - (row[0] + row[2]) / 2) > 0.02


def test_camera_shift_moves_plane_by_focal_times_shift_over_depth():
    z, t = 2.0, 0.23  # shift of fx t / z = 7.36 px
    left = quad(-2.0, -2.0, 0.05, 2.0, z, (0, 0, 0))
    right = quad(0.05, -2.0, 2.0, 2.0, z, (1, 1, 1))
    v, c, f = merge(left, right)
    for shift in (0.0, t):
        pose = np.eye(4)
        pose[0, 3] = -shift  # camera centre moved to x = +shift
        out = rasterize(v, c, f, K, pose=pose, background=(0.5, 0.5, 0.5))
        assert out.mask.all()
        edge = K.fx * (0.05 - shift) / z + K.cx  # expected step position, pixels
        step = 64 - out.color[:, :, 0].sum(axis=1)  # first white column, per row
        assert np.all(np.abs(step - edge) <= 0.5), (shift, edge, step[0])


FLOOR_CASES = {
    "one behind": [[-1000, 1, 1000], [1000, 1, 1000], [0, 1, -1000]],
    "two behind": [[-1000, 1, -1000], [1000, 1, -1000], [0, 1, 1000]],
}


@pytest.mark.parametrize("case", sorted(FLOOR_CASES))
def test_near_clipping_keeps_the_visible_part_of_a_floor(case):
    v = np.array(FLOOR_CASES[case], np.float32)
    colors = ((v[:, [0, 2, 0]] + 1000) / 2000).astype(np.float32)  # linear in x and z
    out = rasterize(v, colors, np.array([[0, 1, 2]], np.int32), K)
    below = np.arange(48) + 0.5 > K.cy  # rows under the horizon see the floor
    assert out.mask[below].all() and not out.mask[~below].any()
    yy, xx = np.mgrid[24:48, 0:64]
    parallax = yy + 0.5 - K.cy  # pixels below the horizon
    # Vertices snap to 1/256 px, i.e. up to 1/512 px of parallax error in depth.
    rel = np.abs(out.depth[24:] / (K.fy / parallax) - 1)
    assert np.all(rel <= 1 / 512 / parallax + 1e-5), rel.max()
    depth = out.depth[24:].astype(np.float64)
    x = (xx + 0.5 - K.cx) / K.fx * depth
    expected = np.stack([x + 1000, depth + 1000, x + 1000], -1) / 2000
    np.testing.assert_allclose(out.color[24:], expected, atol=2e-5)


def test_triangle_behind_the_camera_is_dropped():
    v = np.array([[-1, -1, -1], [1, -1, -1], [0, 1, -2]], np.float32)
    out = rasterize(v, np.ones((3, 3), np.float32), np.array([[0, 1, 2]]), K)
    assert not out.mask.any()


def test_clipped_tessellated_floor_has_no_cracks():
    # A floor grid at y = 1 passing under and behind the camera (z from -5 to 40).
    xs, zs = np.linspace(-20.13, 19.87, 41), np.linspace(-5.07, 39.93, 10)
    zz, xx = np.meshgrid(zs, xs, indexing="ij")
    v = np.stack([xx.ravel(), np.ones(xx.size), zz.ravel()], 1).astype(np.float32)
    faces = grid_faces(len(zs), len(xs))
    colors = np.full((len(v), 3), 0.5, np.float32)
    count = coverage_count(v, colors, faces, K)
    centres = pixel_centres(K)
    dy = (centres[:, 1] - K.cy) / K.fy
    with np.errstate(divide="ignore"):
        depth = np.where(dy > 0, 1.0 / dy, np.inf)
    hx = (centres[:, 0] - K.cx) / K.fx * depth
    inside = (np.abs(hx + 0.13) < 19.9) & (depth < 39.8)
    outside = (np.abs(hx + 0.13) > 20.1) | (depth > 40.1)
    assert inside.sum() > 1000
    assert np.all(count.ravel()[inside] == 1)
    assert np.all(count.ravel()[outside] == 0)


def test_jittered_grid_matches_its_coarse_outline_exactly_once():
    # A planar grid with jittered interior vertices against the same quad as 2 triangles.
    rng = np.random.default_rng(2)
    n = 40
    s, t = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n), indexing="ij")
    jitter = rng.uniform(-0.25, 0.25, (2, n, n)) / (n - 1)
    jitter[:, [0, -1], :] = 0
    jitter[:, :, [0, -1]] = 0
    s, t = (s + jitter[0]).ravel(), (t + jitter[1]).ravel()
    # A tilted quad in the camera's view, in world coordinates of an oblique pose.
    pose = look_pose(0.3, -0.4, (0.4, 0.1, 0.5))
    origin, du, dv = to_world([[-1.0, -0.8, 3.0], [1.0, -0.5, 4.0], [-1.0, 0.8, 2.5]], pose)
    du, dv = du - origin, dv - origin
    fine = origin + s[:, None] * du + t[:, None] * dv
    coarse = origin + np.array([[0, 0], [1, 0], [1, 1], [0, 1]]) @ np.stack([du, dv])

    def ramp(p):
        return (np.clip((p - p.min(0)) / np.ptp(p, 0), 0, 1)).astype(np.float32)

    fine_out = rasterize(fine.astype(np.float32), ramp(fine), grid_faces(n, n), K, pose=pose)
    coarse_faces = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    span = np.stack([fine.min(0), fine.max(0)])
    colors = ((coarse - span[0]) / np.ptp(span, 0)).astype(np.float32)
    coarse_out = rasterize(coarse.astype(np.float32), colors, coarse_faces, K, pose=pose)
    count = coverage_count(fine.astype(np.float32), ramp(fine), grid_faces(n, n), K, pose=pose)

    # Ignore pixel centres within 0.01 px of the outline (snapping moves it by < 0.004 px).
    outline = project(coarse, K, pose)
    centres = pixel_centres(K)
    dist = np.full(len(centres), np.inf)
    for a, b in zip(outline, np.roll(outline, -1, 0), strict=True):
        h = np.clip(((centres - a) @ (b - a)) / ((b - a) @ (b - a)), 0, 1)
        dist = np.minimum(dist, np.linalg.norm(centres - a - h[:, None] * (b - a), axis=1))
    keep = (dist > 0.01).reshape(48, 64)
    assert coarse_out.mask.sum() > 800 and (~coarse_out.mask).sum() > 300
    np.testing.assert_array_equal(fine_out.mask[keep], coarse_out.mask[keep])
    np.testing.assert_array_equal(count[keep], coarse_out.mask[keep].astype(np.int32))
    both = keep & coarse_out.mask
    np.testing.assert_allclose(fine_out.depth[both], coarse_out.depth[both], rtol=1e-4)
    np.testing.assert_allclose(fine_out.color[both], coarse_out.color[both], atol=1e-4)


@pytest.mark.parametrize(("anti", "flip"), [(False, False), (True, True)])
def test_pixel_centres_on_shared_edges_are_covered_once(anti, flip):
    # Vertices on every other pixel centre: edges pass exactly through pixel centres.
    depth = np.full((24, 32), 2.0)
    yy, xx = np.mgrid[0:24, 0:32]
    v = unproject(2 * xx.ravel(), 2 * yy.ravel(), depth.ravel(), K)
    colors = np.ones((v.shape[0], 3), np.float32)
    count = coverage_count(v, colors, grid_faces(24, 32, anti=anti, flip=flip), K)
    rows, cols = np.mgrid[0:48, 0:64]
    vertex = (rows % 2 == 0) & (cols % 2 == 0) & (rows <= 46) & (cols <= 62)
    interior = (rows > 0) & (rows < 46) & (cols > 0) & (cols < 62) & ~vertex
    assert np.all(count[interior] == 1)
    assert np.all(count[vertex] >= 1)  # a vertex is covered by every triangle using it
    top_left = ((rows == 0) | (cols == 0)) & (rows <= 46) & (cols <= 62) & ~vertex
    bottom_right = ((rows == 46) & (cols > 0) | (cols == 62) & (rows > 0)) & ~vertex
    assert np.all(count[top_left] == 1) and np.all(count[bottom_right] == 0)
    assert np.all(count[(rows > 46) | (cols > 62)] == 0)


def uv_sphere(rings: int, segments: int, radius: float, centre) -> tuple[np.ndarray, np.ndarray]:
    theta = np.linspace(0, np.pi, rings + 1)[1:-1]
    phi = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack([np.sin(th) * np.cos(ph), np.cos(th), np.sin(th) * np.sin(ph)], -1)
    v = np.concatenate([[[0, 1, 0]], ring.reshape(-1, 3), [[0, -1, 0]]]) * radius + centre
    idx = 1 + np.arange((rings - 1) * segments).reshape(rings - 1, segments)
    nxt = np.roll(idx, -1, axis=1)
    faces = [np.stack([np.zeros(segments, int), nxt[0], idx[0]], 1)]
    a, b, c, d = idx[:-1], nxt[:-1], idx[1:], nxt[1:]
    faces += [
        np.stack([a.ravel(), b.ravel(), d.ravel()], 1),
        np.stack([a, d, c], -1).reshape(-1, 3),
    ]
    faces.append(np.stack([np.full(segments, len(v) - 1), idx[-1], nxt[-1]], 1))
    return v.astype(np.float32), np.concatenate(faces).astype(np.int32)


def test_sphere_is_covered_twice_inside_its_silhouette():
    pose = look_pose(0.35, 0.5, (-0.5, 0.3, 0.4))
    v, faces = uv_sphere(60, 90, 1.0, to_world([0.2, -0.1, 4.0], pose))
    colors = np.full((len(v), 3), 0.7, np.float32)
    count = coverage_count(v, colors, faces, K, pose=pose)
    hull = ConvexHull(project(v, K, pose))
    # Signed distance of pixel centres to the hull's edge lines (< 0 inside).
    dist = (pixel_centres(K) @ hull.equations[:, :2].T + hull.equations[:, 2]).max(1)
    dist = dist.reshape(48, 64)
    assert (dist < -0.01).sum() > 500
    assert np.all(count[dist < -0.01] == 2)  # front and back surface, no crack, no double
    assert np.all(count[dist > 0.01] == 0)
    out = rasterize(v, colors, faces, K, pose=pose)
    np.testing.assert_array_equal(
        out.mask[np.abs(dist) > 0.01], (dist < -0.01)[np.abs(dist) > 0.01]
    )
    for bands in (1, 3, 5, 48, 100):
        other = rasterize(v, colors, faces, K, pose=pose, bands=bands)
        for name in ("color", "depth", "mask"):
            np.testing.assert_array_equal(getattr(other, name), getattr(out, name))


def test_uint8_colours_equal_float_colours():
    rng = np.random.default_rng(3)
    vertices = input_view_grid(rng.uniform(1, 3, (48, 64)))
    u8 = rng.integers(0, 256, (48 * 64, 3), dtype=np.uint8)
    faces = grid_faces(48, 64)
    pose = look_pose(0.05, -0.08, (0.05, 0.02, 0.1))
    a = rasterize(vertices, u8, faces, K, pose=pose)
    b = rasterize(vertices, u8.astype(np.float32) / 255, faces, K, pose=pose)
    np.testing.assert_allclose(a.color, b.color, atol=1e-6)
    np.testing.assert_array_equal(a.mask, b.mask)
    assert a.color.dtype == np.float32 and a.color.max() <= 1.0


def test_empty_faces_give_the_background():
    vertices = np.zeros((3, 3), np.float32)
    for faces in (np.zeros((0, 3), np.int32), []):
        out = rasterize(vertices, np.zeros((3, 3)), faces, K, background=(0.1, 0.2, 0.3))
        assert out.color.shape == (48, 64, 3) and not out.mask.any()
        np.testing.assert_allclose(out.color, np.broadcast_to([0.1, 0.2, 0.3], (48, 64, 3)))
        assert np.all(np.isinf(out.depth))


def test_invalid_inputs_raise_input_error():
    v, c, f = quad(-1, -1, 1, 1, 2.0, (1, 1, 1))
    with pytest.raises(InputError, match="faces index vertices out of range"):
        rasterize(v, c, f + 2, K)
    with pytest.raises(InputError, match="vertices must have shape"):
        rasterize(v[:, :2], c, f, K)
    with pytest.raises(InputError, match="colors has 3 rows"):
        rasterize(v, c[:3], f, K)
    with pytest.raises(InputError, match="pose"):
        rasterize(v, c, f, K, pose=np.eye(3))
    with pytest.raises(InputError, match="non-finite"):
        rasterize(np.where(v == 1, np.nan, v), c, f, K)
    with pytest.raises(InputError, match="near"):
        rasterize(v, c, f, K, near=0.0)


def test_reused_buffers_give_the_same_frames_without_new_arrays():
    rng = np.random.default_rng(5)
    vertices = input_view_grid(rng.uniform(1, 3, (48, 64)))
    colours = rng.integers(0, 256, (48 * 64, 3), dtype=np.uint8)
    faces = grid_faces(48, 64)
    poses = [look_pose(0.02 * i, -0.03 * i, (0.04 * i, 0.0, 0.05)) for i in range(3)]
    fresh = raster.CPURasterizer(vertices, colours, faces)
    reused = raster.CPURasterizer(vertices, colours, faces, reuse=True)
    frames = [fresh.render(K, pose=p) for p in poses]
    assert frames[0].color is not frames[1].color
    previous = None
    for pose, expected in zip(poses, frames, strict=True):
        got = reused.render(K, pose=pose)
        if previous is not None:
            assert got.color is previous.color and got.depth is previous.depth
        for name in ("color", "depth", "mask"):
            np.testing.assert_array_equal(getattr(got, name), getattr(expected, name))
        previous = got
    # another size gets its own arrays
    small = Intrinsics.default(32, 24)
    got = reused.render(small, pose=poses[0])
    assert got.color.shape == (24, 32, 3)
    np.testing.assert_array_equal(got.mask, fresh.render(small, pose=poses[0]).mask)
    # another thread gets its own arrays: threads may render at once
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(1) as pool:
        other = pool.submit(reused.render, K, pose=poses[2]).result()
    mine = reused.render(K, pose=poses[1])
    assert other.color is not mine.color
    np.testing.assert_array_equal(other.color, frames[2].color)
    np.testing.assert_array_equal(mine.color, frames[1].color)


@pytest.mark.parametrize("factor", [1, 2, 3])
def test_fused_resolve_equals_rendering_then_averaging(factor):
    from photo3d.render._kernels import resolve

    rng = np.random.default_rng(6)
    vertices = input_view_grid(rng.uniform(1, 3, (48, 64)))
    colours = rng.integers(0, 256, (48 * 64, 3), dtype=np.uint8)
    faces = grid_faces(48, 64)[::3]  # holes: partly covered blocks
    pose = look_pose(0.03, -0.05, (0.05, 0.01, 0.1))
    k = Intrinsics(64.0 * factor, 64.0 * factor, 32.0 * factor, 24.0 * factor,
                   64 * factor, 48 * factor)
    r = raster.CPURasterizer(vertices, colours, faces, reuse=True)
    fused = r.render_resolved(k, factor, pose=pose)
    frag = r.render(k, pose=pose)
    separate = resolve(frag.color, frag.depth, factor)
    for got, expected in zip(fused, separate, strict=True):
        np.testing.assert_array_equal(got, expected)
    coverage = fused[1]
    assert np.any(coverage == 0) and np.any(coverage == 1)
    assert factor == 1 or np.any((coverage > 0) & (coverage < 1))
    # the mean of the covered samples, their fraction and the nearest depth
    blocks = frag.mask.reshape(48, factor, 64, factor)
    np.testing.assert_allclose(coverage, blocks.mean(axis=(1, 3)), atol=1e-6)
    near = np.where(frag.mask, frag.depth, np.inf).reshape(48, factor, 64, factor).min((1, 3))
    np.testing.assert_array_equal(fused[2], near.astype(np.float32))
    with pytest.raises(InputError, match="not a multiple"):
        r.render_resolved(Intrinsics.default(65, 48), 2)


def test_texture_lookup_is_bilinear_at_texel_centres():
    """A screen-aligned quad whose texture coordinates put texel centres on pixel
    centres shows the texture exactly; halfway between two texels, their mean."""
    from photo3d.camera import Intrinsics as K_
    from photo3d.render.raster import CPURasterizer

    tex = np.zeros((4, 4, 3), np.uint8)
    tex[..., 0] = np.arange(4) * 60  # red ramp along columns
    tex[..., 1] = (np.arange(4) * 50)[:, None]  # green ramp along rows
    k = K_(1.0, 1.0, 0.0, 0.0, 4, 4)  # pixel (u, v) = (x / z, y / z)
    # corners at pixel centres 0.5 .. 3.5 <-> texel centres (0.5 / 4 .. 3.5 / 4)
    v = np.array([[0.5, 0.5, 1], [3.5, 0.5, 1], [0.5, 3.5, 1], [3.5, 3.5, 1]], np.float32)
    uv = np.array([[0.125, 0.125, 0], [0.875, 0.125, 0], [0.125, 0.875, 0],
                   [0.875, 0.875, 0]], np.float32)
    faces = np.array([[0, 2, 1], [1, 2, 3]], np.int32)
    r = CPURasterizer(v, uv, faces, texture=tex)
    frag = r.render(k)
    got = np.rint(frag.color[:3, :3] * 255)
    np.testing.assert_array_equal(got, tex[:3, :3].astype(float))
    color, _, _ = r.render_resolved(K_(2.0, 2.0, 0.0, 0.0, 8, 8), 2)  # samples at +-0.25
    assert color[1, 1, 0] * 255 == pytest.approx(60, abs=0.6)
    with pytest.raises(InputError, match="texture"):
        CPURasterizer(v, uv, faces, texture=np.zeros((4, 4), np.uint8))
