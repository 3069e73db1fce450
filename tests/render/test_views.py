"""Novel views: geometry of camera motion, input view, dolly zoom, stereo, backends."""

import json

import numpy as np
import pytest
from conftest import exact_config, texture

import photo3d
from photo3d.camera import Camera, Intrinsics
from photo3d.errors import ConfigError, InputError
from photo3d.render.paths import STANDARD_PATHS, keyframe_path, load_path, preset_path
from photo3d.render.renderer import AUTHORS_CROP, Renderer, RenderSettings, cropped
from photo3d.render.stereo import compose, eye_cameras


def phase_shift(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """Sub-pixel (dy, dx) such that b(x) ~ a(x - d), by phase correlation."""
    win = np.outer(np.hanning(a.shape[0]), np.hanning(a.shape[1]))
    fa, fb = np.fft.fft2((a - a.mean()) * win), np.fft.fft2((b - b.mean()) * win)
    r = fb * np.conj(fa)
    corr = np.fft.ifft2(r / np.maximum(np.abs(r), 1e-12)).real
    py, px = np.unravel_index(np.argmax(corr), corr.shape)
    out = []
    for axis, p in ((0, py), (1, px)):
        n = corr.shape[axis]
        idx = [py, px]
        vals = []
        for k in (-1, 0, 1):
            idx[axis] = (p + k) % n
            vals.append(corr[tuple(idx)])
        denom = vals[0] - 2 * vals[1] + vals[2]
        frac = 0.5 * (vals[0] - vals[2]) / denom if denom != 0 else 0.0
        d = p + frac
        out.append(d - n if d > n / 2 else d)
    return out[0], out[1]


def noise(h, w, seed=0):
    """Band-limited random texture: sharp enough for phase correlation."""
    from scipy import ndimage

    rng = np.random.default_rng(seed)
    img = ndimage.gaussian_filter(rng.random((h, w, 3)), (1.2, 1.2, 0))
    img = (img - img.min()) / (img.max() - img.min())
    return img.astype(np.float32)


@pytest.fixture(scope="module")
def plane():
    img = noise(96, 128, seed=11)
    photo = photo3d.make(img, depth=np.full((96, 128), 2.0), config=exact_config(border=20))
    return photo


@pytest.mark.parametrize("t", [0.3, 0.5, -0.4])
def test_fronto_parallel_plane_moves_by_f_t_over_z(plane, t):
    z = float(plane.ldi.depth()[0])
    k = plane.ldi.intrinsics
    settings = RenderSettings(ssaa=1, backend="numba")
    with Renderer(plane.mesh(), settings) as r:
        a = r.render(Camera(k, np.eye(4))).color.mean(axis=2)
        b = r.render(Camera.translated(k, (t, 0.0, 0.0))).color.mean(axis=2)
    dy, dx = phase_shift(a[16:-16, 16:-16], b[16:-16, 16:-16])
    assert dx == pytest.approx(-k.fx * t / z, abs=0.5)
    assert dy == pytest.approx(0.0, abs=0.5)


def test_input_camera_reproduces_the_input_image(plane):
    img = np.round(noise(96, 128, seed=11) * 255) / 255
    cam = Camera(plane.ldi.intrinsics, np.eye(4))
    exact = plane.render(cam, settings=RenderSettings(ssaa=1))
    assert exact.mask.all()
    np.testing.assert_allclose(exact.color, img, atol=1e-5)
    smooth = plane.render(cam)  # default 2x supersampling: a slight box blur
    d = (smooth.color - img)[4:-4, 4:-4]
    assert 10 * np.log10(1 / np.mean(d**2)) > 30


def test_input_view_of_a_scene_with_depth_edges_is_the_photo():
    img = texture(80, 120, seed=2)
    d = np.ones((80, 120), np.float32)
    d[20:60, 30:70] = 3.0
    d[10:40, 80:110] = 2.0
    photo = photo3d.make(img, depth=d, config=exact_config(border=10, edge_dilation=2))
    view = photo.render(Camera(photo.ldi.intrinsics, np.eye(4)),
                        settings=RenderSettings(ssaa=1, fill_holes=False))
    diff = (view.color - np.round(img * 255) / 255)[4:-4, 4:-4]
    assert np.mean(diff**2) < 1e-4  # PSNR > 40 dB


def test_disocclusions_are_filled_by_the_inpainted_layer():
    img = texture(80, 120, seed=4)
    d = np.ones((80, 120), np.float32)
    d[20:60, 40:80] = 3.0  # box in front
    cfg = exact_config(border=10, synthesis_iterations=20, context_iterations=30)
    photo = photo3d.make(img, depth=d, config=cfg)
    k = photo.ldi.intrinsics
    cam = Camera.translated(k, (0.02, 0.0, 0.0))  # box moves ~ f t (3 - 1) px sideways
    with_layers = photo.render(cam, settings=RenderSettings(ssaa=1, fill_holes=False))
    stretched = photo3d.make(img, depth=d, config=cfg.with_(regions=cfg.regions.__class__(
        synthesis_iterations=0, context_iterations=0, edge_dilation=0, border=10)))
    assert with_layers.mask[10:-10, 10:-10].mean() > 0.999
    assert stretched.ldi.size < photo.ldi.size


def test_dolly_zoom_keeps_the_centre_plane_size():
    k = Intrinsics.default(200, 100)
    path = preset_path("dolly-zoom-in", k, frames=5, centre_depth=2.0)
    for cam in path:
        z_cam = -cam.pose[2, 3]  # camera centre along the optical axis
        # a 1-unit object at depth 2 spans fx / (2 - z) pixels: constant
        assert cam.intrinsics.fx / (2.0 - z_cam) == pytest.approx(k.fx / 2.0, rel=1e-9)
    assert path[0].pose[2, 3] == pytest.approx(0.05) and path[-1].pose[2, 3] == pytest.approx(
        -0.05)
    zoom = preset_path("zoom-in", k, frames=5)
    assert all(c.intrinsics == k for c in zoom)
    with pytest.raises(InputError, match="centre pixel"):
        preset_path("dolly-zoom-in", k, frames=5)


def test_dolly_zoom_render_keeps_centre_texture_scale(plane):
    k = plane.ldi.intrinsics
    z = float(plane.ldi.depth()[0])
    cams = preset_path("dolly-zoom-in", k, frames=3, centre_depth=z)
    with Renderer(plane.mesh(), RenderSettings(ssaa=1, backend="numba")) as r:
        first, last = (r.render(c).color for c in (cams[0], cams[-1]))
    np.testing.assert_allclose(first[30:66, 40:88], last[30:66, 40:88], atol=2e-3)


def test_authors_paths_have_their_shifts():
    k = Intrinsics.default(64, 48)
    circle = preset_path("circle", k, frames=240)
    t = np.array([c.pose[:3, 3] for c in circle])
    assert np.abs(t[:, 0]).max() == pytest.approx(0.015)
    assert np.abs(t[:, 1]).max() == pytest.approx(0.015, rel=1e-3)
    assert t[:, 2].min() == pytest.approx(-0.05) and t[:, 2].max() == pytest.approx(0.05)
    swing = np.array([c.pose[:3, 3] for c in preset_path("swing", k, frames=240)])
    assert not swing[:, 1].any()
    assert set(STANDARD_PATHS) == {"dolly-zoom-in", "zoom-in", "circle", "swing"}


def test_keyframes_interpolate_smoothly_and_load_from_json(tmp_path):
    k = Intrinsics.default(64, 48)
    keys = [{"time": 0, "position": [0, 0, 0], "look_at": [0, 0, 5]},
            {"time": 1, "position": [0.1, 0, 0], "look_at": [0, 0, 5], "fov": 30},
            {"time": 3, "position": [0.1, 0.1, 0.1], "look_at": [0, 0, 5]}]
    path = keyframe_path(keys, k, frames=31)
    pos = np.array([c.position for c in path])
    np.testing.assert_allclose(pos[0], [0, 0, 0], atol=1e-12)
    np.testing.assert_allclose(pos[-1], [0.1, 0.1, 0.1], atol=1e-12)
    np.testing.assert_allclose(pos[10], [0.1, 0, 0], atol=1e-12)  # t = 1 hits the keyframe
    steps = np.linalg.norm(np.diff(pos, axis=0), axis=1)
    assert steps.max() < 3 * np.median(steps)  # no jumps
    # the camera keeps looking at the target
    for cam in path:
        p = cam.pose[:3, :3] @ np.array([0, 0, 5.0]) + cam.pose[:3, 3]
        assert abs(p[0]) < 1e-9 and abs(p[1]) < 1e-9 and p[2] > 0
    (tmp_path / "p.json").write_text(json.dumps({"keyframes": keys}))
    assert len(load_path(tmp_path / "p.json", k, frames=7)) == 7
    (tmp_path / "bad.json").write_text("[{\"pos\": 1}]")
    with pytest.raises(InputError, match="bad keyframe"):
        load_path(tmp_path / "bad.json", k, frames=3)


def test_crop_is_done_by_the_intrinsics():
    k = Intrinsics.default(100, 80)
    c = cropped(k, AUTHORS_CROP)
    # the crop window's corners map to the output corners
    x0 = (k.width * 0.03 - k.cx) / k.fx * c.fx + c.cx
    x1 = (k.width * 0.97 - k.cx) / k.fx * c.fx + c.cx
    y1 = (k.height * 0.95 - k.cy) / k.fy * c.fy + c.cy
    assert (x0, x1, y1) == pytest.approx((0.0, 100.0, 80.0))


def test_stereo_eyes_see_parallax(plane):
    k = plane.ldi.intrinsics
    left, right = eye_cameras(Camera(k, np.eye(4)), 0.5)
    with Renderer(plane.mesh(), RenderSettings(ssaa=1, backend="numba")) as r:
        lv, rv = r.render(left).color, r.render(right).color
    z = float(plane.ldi.depth()[0])
    _, dx = phase_shift(lv.mean(2)[16:-16, 16:-16], rv.mean(2)[16:-16, 16:-16])
    assert dx == pytest.approx(-k.fx * 0.5 / z, abs=0.5)
    assert compose(lv, rv, "sbs").shape == (96, 256, 3)
    assert compose(lv, rv, "sbs-half").shape == (96, 128, 3)
    np.testing.assert_array_equal(compose(lv, rv, "sbs", order="rl")[:, :128], rv)
    ana = compose(lv, rv, "anaglyph")
    np.testing.assert_array_equal(ana[..., 0], lv[..., 0])
    np.testing.assert_array_equal(ana[..., 1:], rv[..., 1:])
    with pytest.raises(ConfigError):
        compose(lv, rv, "wiggle")


def test_backends_agree(plane):
    gl = pytest.importorskip("photo3d.render.gl")
    if not gl.gl_available():
        pytest.skip("no OpenGL context on this machine")
    k = plane.ldi.intrinsics
    cam = Camera.translated(k, (0.1, 0.05, -0.1))
    views = {}
    for backend in ("numba", "gl"):
        with Renderer(plane.mesh(), RenderSettings(backend=backend)) as r:
            assert r.backend == backend
            views[backend] = r.render(cam).color
    mse = np.mean((views["numba"] - views["gl"]) ** 2)
    assert 10 * np.log10(1 / mse) > 35


def test_render_settings_are_validated():
    with pytest.raises(ConfigError):
        RenderSettings(ssaa=0)
    with pytest.raises(ConfigError):
        RenderSettings(crop=(0.6, 0, 0, 0))
    with pytest.raises(ConfigError):
        RenderSettings(backend="vulkan")


def test_hidden_layer_culling_changes_nothing():
    from photo3d.render.raster import rasterize

    img = texture(60, 80, seed=9)
    d = np.ones((60, 80), np.float32)
    d[15:45, 20:50] = 3.0
    photo = photo3d.make(img, depth=d, config=exact_config(border=8, synthesis_iterations=12))
    m = photo.mesh()
    first = int(np.count_nonzero(m.faces.max(axis=1) < 60 * 80))
    assert 0 < first < len(m.faces)
    k = photo.ldi.intrinsics
    for t in ((0.0, 0.0, 0.0), (0.03, -0.01, 0.02)):
        pose = np.eye(4)
        pose[:3, 3] = t
        full = rasterize(m.vertices, m.colors, m.faces, k, pose=pose)
        culled = rasterize(m.vertices, m.colors, m.faces, k, pose=pose, first=first)
        np.testing.assert_array_equal(full.color, culled.color)
        np.testing.assert_array_equal(full.depth, culled.depth)


def test_triangles_with_huge_screen_coordinates_still_render():
    from photo3d.render.raster import rasterize

    k = Intrinsics.default(32, 24)
    # one vertex projects ~10^7 px off screen (beyond the fixed-point range)
    v = np.array([[-1, -1, 1], [1e4, 0, 1e-3 * 2], [-1, 1, 1]], np.float32)
    frag = rasterize(v, np.eye(3, dtype=np.float32), np.array([[0, 1, 2]]), k)
    xs = (v[:, 0] / v[:, 2]) * k.fx + k.cx
    assert xs.max() > 2**22
    # the triangle spans the whole left part of the view: covered, finite colours
    assert frag.mask[:, :8].all()
    assert np.isfinite(frag.color).all() and frag.color.max() <= 1.0
