"""Looking Glass quilts (issue 37 item 6): the layout Looking Glass software reads
(view 0 bottom-left, left to right then bottom to top, the name's columns, rows and
aspect), views across the display's cone with the focal plane held in place, and
the presets' table."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest
from PIL import Image

import photo3d
from photo3d.errors import ConfigError, OutputError
from photo3d.export.quilt import (
    BASELINE,
    DEFAULT,
    PRESETS,
    QuiltPreset,
    focus_depth,
    quilt_cameras,
    quilt_filename,
    tile_intrinsics,
    write_quilt,
)

NEAR, MIDDLE, FAR = 1.0, 0.5, 0.0  # normalised disparities: z = 1/3, 2/3 and 20
SMALL = QuiltPreset("small", "a test display", 4, 3, 4 * 96, 3 * 128, 0.75, 40.0)


@pytest.fixture(scope="module")
def photo():
    """A striped wall (most of the photo, so the focus plane) below a far band, with
    a red square in front of it, in the middle."""
    x = np.arange(64) / 64
    image = np.empty((48, 64, 3), np.float32)
    image[:] = np.stack([0.3 + 0.2 * np.sin(16 * np.pi * x), 0.45 + 0.3 * np.cos(10 * np.pi * x),
                         0.5 + 0.3 * np.sin(6 * np.pi * x)], axis=1)
    disparity = np.full((48, 64), MIDDLE, np.float32)
    disparity[:8] = FAR
    image[:8] = (0.2, 0.6, 0.3)
    image[16:32, 24:40] = (0.9, 0.1, 0.1)
    disparity[16:32, 24:40] = NEAR
    return photo3d.make(image, depth=disparity,
                        config=photo3d.Config(size=None, inpainter="diffusion"))


def tiles(quilt: np.ndarray, preset: QuiltPreset) -> list[np.ndarray]:
    """The views of a quilt image, view 0 first (bottom-left, then right, then up)."""
    th, tw = quilt.shape[0] // preset.rows, quilt.shape[1] // preset.columns
    return [quilt[(preset.rows - 1 - i // preset.columns) * th:][:th,
                  (i % preset.columns) * tw:][:, :tw] for i in range(preset.views)]


def red_centre_x(tile: np.ndarray) -> float:
    red = (tile[..., 0] > 170) & (tile[..., 1] < 90) & (tile[..., 2] < 90)
    assert red.sum() > 100, "the near square is missing from a view"
    return float(np.nonzero(red)[1].mean())


def test_views_are_laid_out_left_to_right_then_bottom_to_top(photo, tmp_path):
    """View 0, the leftmost camera, is the bottom-left tile: the near square moves
    right to left across the views, by what the cameras' baseline gives it."""
    path = tmp_path / quilt_filename(photo.ldi, SMALL)
    write_quilt(photo.ldi, path, preset=SMALL, backend="numba")
    with Image.open(path) as image:
        quilt = np.asarray(image)
    assert path.name == "quilt_qs4x3a0.75.png" and quilt.shape == (384, 384, 3)
    views = tiles(quilt, SMALL)
    assert all(v.std() > 10 for v in views)  # every tile holds a picture
    xs = [red_centre_x(v) for v in views]
    assert all(a > b for a, b in zip(xs, xs[1:], strict=False))  # a near object moves left
    # the whole shift, view 0 to the last: fx * baseline * (1/z_near - 1/z_focus)
    z_near, z_focus = float(photo.ldi.mapping.depth(np.float32(NEAR))), focus_depth(photo.ldi)
    fx = tile_intrinsics(photo.ldi.intrinsics, SMALL).fx
    expected = fx * BASELINE * (1 / z_near - 1 / z_focus)
    assert xs[0] - xs[-1] == pytest.approx(expected, rel=0.1)
    # the wall (the focus plane) stays put: the first and last views agree there
    assert z_focus == pytest.approx(2 / 3, rel=1e-3)
    wall = np.s_[-24:, :24]
    assert np.abs(views[0][wall].astype(int) - views[-1][wall]).mean() < 3


def test_the_png_holds_each_cameras_view_in_its_tile(photo, tmp_path):
    """The file, read by Pillow, is the views of :func:`quilt_cameras` (rendered here
    one by one) laid out from the bottom-left tile, exactly."""
    from photo3d.mesh.light import build_light_mesh
    from photo3d.render.renderer import Renderer, RenderSettings

    mesh = build_light_mesh(photo.ldi)
    seen = []
    write_quilt(photo.ldi, tmp_path / "q.png", preset=SMALL, mesh=mesh, backend="numba",
                progress=lambda done, total: seen.append((done, total)))
    assert seen == [(i + 1, 12) for i in range(12)]
    with Image.open(tmp_path / "q.png") as image:
        views = tiles(np.asarray(image), SMALL)
    with Renderer(mesh, RenderSettings(ssaa=1, backend="numba")) as renderer:
        for view, camera in zip(views, quilt_cameras(photo.ldi, SMALL), strict=True):
            expected = (renderer.render(camera).color * 255 + 0.5).astype(np.uint8)
            np.testing.assert_array_equal(view, expected)


def test_the_focal_plane_projects_to_the_same_pixel_in_every_view(photo):
    cameras = quilt_cameras(photo.ldi, PRESETS["go"], focus=2.0)
    assert len(cameras) == 66
    point = np.array([0.3, -0.2, 2.0, 1.0])  # on the focal plane
    near = np.array([0.3, -0.2, 1.0, 1.0])
    seen, moved = [], []
    for camera in cameras:
        k = camera.intrinsics
        for p, out in ((point, seen), (near, moved)):
            x, y, z = (camera.pose @ p)[:3]
            out.append((k.fx * x / z + k.cx, k.fy * y / z + k.cy))
        assert np.allclose(camera.pose[:3, :3], np.eye(3))  # moved, never turned
    np.testing.assert_allclose(seen, [seen[0]] * len(seen), atol=1e-9)
    assert moved[0][0] > moved[-1][0]
    xs = np.array([c.position[0] for c in cameras])  # equal angle steps over the cone
    angles = np.degrees(np.arctan(xs / xs[-1] * math.tan(math.radians(27))))
    np.testing.assert_allclose(np.diff(angles), 54 / 65)


def test_default_preset_and_its_name(photo, tmp_path):
    assert DEFAULT is PRESETS["portrait"]
    name = quilt_filename(photo.ldi)
    assert name == "quilt_qs8x6a0.75.png"
    write_quilt(photo.ldi, tmp_path / name, backend="numba")
    with Image.open(tmp_path / name) as image:
        assert image.size == (3360, 3360) and image.format == "PNG"
        quilt = np.asarray(image)
    views = tiles(quilt, DEFAULT)
    assert len(views) == 48 and views[0].shape == (560, 420, 3)
    xs = [red_centre_x(v) for v in views]
    assert xs[0] > xs[24] > xs[-1]
    assert os.listdir(tmp_path) == [name]  # no temporary file left


def test_uncropped_views_keep_the_whole_photo(photo, tmp_path):
    name = quilt_filename(photo.ldi, SMALL, crop=False)
    assert name == "quilt_qs4x3a1.3333.png"
    write_quilt(photo.ldi, tmp_path / name, preset=SMALL, crop=False, baseline=0.0,
                backend="numba")
    with Image.open(tmp_path / name) as image:
        quilt = np.asarray(image)
    views = tiles(quilt, SMALL)
    th, tw = views[0].shape[:2]
    assert tw / th == pytest.approx(64 / 48, rel=0.02)
    assert tw * th == pytest.approx(96 * 128, rel=0.02)
    # no baseline: every view is the input view, the whole photo (the square's centre
    # is the frame's centre, its side a quarter of the width)
    assert all(np.array_equal(v, views[0]) for v in views)
    red = views[0][..., 0] > 170
    assert np.nonzero(red)[1].mean() == pytest.approx(tw / 2, abs=1.5)
    assert red.any(axis=0).sum() == pytest.approx(tw / 4, abs=2)


def test_presets_table():
    for p in PRESETS.values():
        assert p.views == p.columns * p.rows
        assert p.tile[0] * p.columns <= p.width and p.tile[1] * p.rows <= p.height
        assert 35 <= p.view_cone <= 60
    assert (PRESETS["go"].columns, PRESETS["go"].rows, PRESETS["go"].aspect) == (11, 6, 0.5625)
    assert PRESETS["16in"].views == 49 and PRESETS["65in"].views == 72
    with pytest.raises(ConfigError):
        QuiltPreset("one", "one view", 1, 1, 10, 10, 1.0, 40.0)


def test_bad_options_are_refused_before_rendering(photo, tmp_path):
    with pytest.raises(ConfigError, match="baseline"):
        write_quilt(photo.ldi, tmp_path / "q.png", preset=SMALL, baseline=-0.01)
    with pytest.raises(ConfigError, match="focus"):
        write_quilt(photo.ldi, tmp_path / "q.png", preset=SMALL, focus=0.0)
    (tmp_path / "folder.png").mkdir()
    with pytest.raises(OutputError):
        write_quilt(photo.ldi, tmp_path / "folder.png", preset=SMALL)
    assert sorted(os.listdir(tmp_path)) == ["folder.png"]
