"""Mistakes a Python user makes with photo3d's public API (wrong types, shapes, sizes):
each is one :class:`~photo3d.errors.Photo3DError` naming the parameter, raised before
the work, never a traceback from deep inside, a huge allocation or a wrong result."""

from __future__ import annotations

import numpy as np
import pytest

from photo3d.camera import Camera, Intrinsics
from photo3d.errors import ConfigError, InputError
from photo3d.mesh.full import build_mesh
from photo3d.render.renderer import Renderer, RenderSettings
from photo3d.stages.ldi import from_image


@pytest.fixture(scope="module")
def renderer() -> Renderer:
    """A CPU renderer of an 8x8 grey plane."""
    mesh = build_mesh(from_image(np.full((8, 8, 3), 0.5, np.float32),
                                 np.ones((8, 8), np.float32)))
    return Renderer(mesh, RenderSettings(backend="numba"))


@pytest.mark.parametrize("camera, message", [
    (None, "camera must be a photo3d.camera.Camera"),
    (Camera((8, 8, 4, 4), np.eye(4)), "camera must be a photo3d.camera.Camera"),
    (Camera(Intrinsics.default(0, 0), np.eye(4)), "camera size must be whole pixels > 0"),
    (Camera(Intrinsics(8.0, 8.0, 4.0, 4.0, -5, 8), np.eye(4)), "width=-5"),
    (Camera(Intrinsics(8.0, 8.0, 4.0, 4.0, 7.5, 8), np.eye(4)), "width=7.5"),
    (Camera(Intrinsics(np.nan, 8.0, 4.0, 4.0, 8, 8), np.eye(4)), "fx=nan"),
    (Camera(Intrinsics(0.0, 0.0, 4.0, 4.0, 8, 8), np.eye(4)), "fx=0, fy=0"),
    (Camera(Intrinsics(-8.0, -8.0, 4.0, 4.0, 8, 8), np.eye(4)), "fx=-8"),
])
def test_render_refuses_what_is_no_camera(renderer, camera, message):
    # an empty (0, 0, 3) view, a black one (focal 0 or NaN), one upside down (focal < 0),
    # an AttributeError or numpy's "negative dimensions"
    with pytest.raises(InputError, match=message):
        renderer.render(camera)
    with pytest.raises(InputError, match=message):
        renderer.render_rgb8(camera)


def test_render_refuses_a_view_beyond_the_available_memory(monkeypatch):
    # 100000x100000 at ssaa 2 allocated 447 GiB (a MemoryError, or the OOM killer)
    import photo3d

    photo = photo3d.make(np.full((16, 16, 3), 0.5), depth=np.ones((16, 16)),
                         config=photo3d.Config(size=None))
    monkeypatch.setattr("photo3d.resources.model.available_memory", lambda: 2_000_000_000)
    with pytest.raises(ConfigError, match="100000x100000"):
        photo.render(Camera(Intrinsics.default(100000, 100000), np.eye(4)))
    assert photo.render(Camera(Intrinsics.default(8, 8), np.eye(4))).color.shape == (8, 8, 3)


def _huge(shape: tuple[int, ...], value, dtype) -> np.ndarray:
    """A read-only array of ``shape`` that takes no memory (one value broadcast)."""
    return np.broadcast_to(np.array(value, dtype), shape)


@pytest.mark.parametrize("image, depth, message", [
    (_huge((60000, 90000, 3), 128, np.uint8), np.ones((32, 48), np.float32),
     "the image's 90000x60000 pixels"),
    (np.zeros((32, 48, 3), np.uint8), _huge((100000, 150000), 1.0, np.float32),
     "depth's 150000x100000 values"),
])
def test_make_refuses_arrays_beyond_the_available_memory(monkeypatch, image, depth, message):
    # an array is converted to float32 before make's own check: 65 GB (image) or 60 GB
    # (depth) were allocated (a MemoryError, or the OOM killer)
    import photo3d

    monkeypatch.setattr("photo3d.io.limits.available_memory", lambda: 2_000_000_000)
    with pytest.raises(InputError, match=f"{message} needs about"):
        photo3d.make(image, depth=depth, config=photo3d.Config(size=64))


@pytest.mark.parametrize("shape", [(0, 0), (0, 48), (32, 0)])
def test_make_refuses_an_empty_depth_map(shape):
    # (0, 48): a ZeroDivisionError comparing its aspect ratio with the image's
    import photo3d

    with pytest.raises(InputError, match=r"depth has shape \(.*\); it holds no values"):
        photo3d.make(np.zeros((32, 48, 3)), depth=np.zeros(shape, np.float32),
                     config=photo3d.Config(size=None))


@pytest.mark.parametrize("argument, error, message", [
    ({"inpainter": "diffusion"}, ConfigError,
     r"inpainter must be an inpainting backend .*got a str; .*Config\(inpainter='diffusion'\)"),
    ({"intrinsics": (48.0, 48.0, 24.0, 16.0)}, InputError,
     "intrinsics must be a photo3d.camera.Intrinsics, got a tuple"),
    ({"progress": 3}, ConfigError, "progress must be a callable"),
])
def test_make_refuses_arguments_of_the_wrong_kind(monkeypatch, argument, error, message):
    # an AttributeError ('str' object has no attribute 'margin', 'tuple' object has no
    # attribute 'width') or a TypeError ('int' object is not callable) after the work
    import photo3d
    from photo3d import pipeline

    monkeypatch.setattr(pipeline, "preprocess", _no_work)
    with pytest.raises(error, match=message):
        photo3d.make(np.zeros((32, 48, 3)), depth=np.ones((32, 48)),
                     config=photo3d.Config(size=None), **argument)


def _no_work(*args, **kwargs):
    raise AssertionError("the pipeline started")


@pytest.mark.parametrize("changes, message", [
    ({"glb": "no"}, "glb must be True or False, got 'no'"),
    ({"full_glb": "false"}, "full_glb must be True or False"),
    ({"viewer": 0}, "viewer must be True or False, got 0"),
    ({"light_error": "0.5"}, "light_error must be a number of pixels >= 0 or None"),
    ({"light_error": float("inf")}, "light_error must be a number of pixels >= 0 or None"),
    ({"videos": "circle"}, "videos must be a list of photo3d.render.animate.VideoSpec s"),
    ({"videos": ["circle"]}, "videos must be photo3d.render.animate.VideoSpec s, got 'circle'"),
    ({"render_settings": {"ssaa": 1}}, "render_settings must be a photo3d.render.renderer"),
])
def test_save_options_of_the_wrong_kind_are_refused(tmp_path, changes, message):
    # glb="no" wrote mesh.glb, full_glb="false" the full mesh, a dict of render
    # settings was ignored; videos="circle" was a TypeError (asdict) before writing
    import photo3d
    from photo3d.save_options import SaveOptions

    with pytest.raises(ConfigError, match=message):
        SaveOptions(**changes)
    photo = photo3d.make(np.zeros((16, 16, 3)), depth=np.ones((16, 16)),
                         config=photo3d.Config(size=None))
    with pytest.raises(ConfigError, match=message):
        photo.save(tmp_path / "out", **changes)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("changes, message", [
    ({"ssaa": "2"}, "ssaa must be a whole number between 1 and 8, got '2'"),
    ({"ssaa": 2.5}, "ssaa must be a whole number between 1 and 8, got 2.5"),
    ({"crop": None}, "crop must be 4 fractions in"),
    ({"crop": (0.1, "0", 0, 0)}, "crop must be 4 fractions in"),
    ({"background": (1, 2)}, "background must be an RGB triple in"),
    ({"background": None}, "background must be an RGB triple in"),
    ({"background": (255, 0, 0)}, r"background must be an RGB triple in \[0, 1\]"),
    ({"near": "0.1"}, "near must be a finite number > 0, got '0.1'"),
    ({"near": float("nan")}, "near must be a finite number > 0"),
    ({"fill_holes": "no"}, "fill_holes must be True or False"),
])
def test_render_settings_of_the_wrong_kind_are_refused(changes, message):
    # a TypeError comparing a string (ssaa, near) or taking len(None) (crop), numpy's
    # broadcast error (background (1, 2)), or a view of NaN (background None)
    with pytest.raises(ConfigError, match=message):
        RenderSettings(**changes)


def test_render_settings_take_lists():
    settings = RenderSettings(crop=[0.1, 0.1, 0.1, 0.1], background=np.zeros(3), ssaa=np.int64(2))
    assert settings.crop == (0.1, 0.1, 0.1, 0.1) and settings.background == (0, 0, 0)


def test_renderer_refuses_what_is_no_mesh_or_settings():
    # an AttributeError ('NoneType' / 'LDI' object has no attribute 'split_fringe',
    # 'dict' object has no attribute 'backend')
    ldi = from_image(np.full((8, 8, 3), 0.5, np.float32), np.ones((8, 8), np.float32))
    for mesh in (None, ldi):
        with pytest.raises(InputError, match="mesh must be a photo3d Mesh or TexturedMesh"):
            Renderer(mesh)
    with pytest.raises(ConfigError, match="settings must be a RenderSettings or None, got a dict"):
        Renderer(build_mesh(ldi), {"ssaa": 1})


_A = np.random.default_rng(0).random((32, 32, 3)).astype(np.float32)


@pytest.mark.parametrize("a, b, message", [
    ((_A * 255).astype(np.uint8), _A, "a has dtype uint8; expected floats in"),
    (_A, (_A * 255).astype(np.uint8), "b has dtype uint8; expected floats in"),
    (_A * 255, _A * 255, r"a has values outside \[0, 1\]"),
    (np.full_like(_A, np.nan), _A, r"a has values outside \[0, 1\] \(or NaN"),
    (_A[..., 0], _A[..., 0], r"a has shape \(32, 32\); expected \(H, W, 3\)"),
])
@pytest.mark.parametrize("metric", ["psnr", "ssim"])
def test_metrics_refuse_images_they_are_not_defined_on(metric, a, b, message):
    # psnr of a uint8 image against its float copy was -43.6 dB, of two uint8 images
    # 1/255 apart 0 dB; ssim of 0..255 floats used the constants of [0, 1]; NaN gave
    # NaN; (H, W) said "images differ in shape: (32, 32) vs (32, 32)"
    from photo3d.eval import metrics

    with pytest.raises(InputError, match=message):
        getattr(metrics, metric)(a, b)


def test_metrics_take_lists():
    # an AttributeError ('list' object has no attribute 'shape')
    from photo3d.eval.metrics import psnr, ssim

    mask = np.zeros((32, 32), bool)
    mask[:8] = True
    assert psnr(_A.tolist(), (_A * 0.5).tolist(), mask=mask.tolist()) == psnr(
        _A, _A * 0.5, mask=mask)
    assert ssim(_A.tolist(), _A.tolist()) == 1.0


@pytest.mark.parametrize("position, target, up, message", [
    ((0, 0, 0), (0, 0, 0), (0, -1, 0), "target is at the camera's position"),
    ((0, 0, 0), (0, 5, 0), (0, -1, 0), "up is parallel to the viewing direction"),
    ((0, 0), (0, 0, 5), (0, -1, 0), "position must be 3 finite numbers"),
    ((0, 0, 0), (0, 0, np.nan), (0, -1, 0), "target must be 3 finite numbers"),
    ((0, 0, 0), (0, 0, 5), "up", "up must be 3 finite numbers"),
])
def test_look_at_refuses_what_gives_no_camera(position, target, up, message):
    # target at the position gave a NaN pose; up parallel a bare ValueError; a 2-vector
    # numpy's broadcast error
    with pytest.raises(InputError, match=message):
        Camera.look_at(Intrinsics.default(8, 8), position, target, up)


@pytest.mark.parametrize("mesh", [None, "mesh.glb"])
def test_write_viewer_refuses_what_is_no_mesh(tmp_path, mesh):
    # an AttributeError from the payload's encoder
    from photo3d.viewer import write_viewer

    with pytest.raises(InputError, match="mesh must be a photo3d Mesh or TexturedMesh"):
        write_viewer(mesh, tmp_path / "viewer.html")
    assert not (tmp_path / "viewer.html").exists()


def test_save_and_load_refuse_what_is_no_path_or_no_option(tmp_path):
    # photo.save(None) / save(5) / load(None): Python's TypeError; save(out, {"glb":
    # False}): an AttributeError; save(out, bogus=1): dataclasses' TypeError
    import photo3d

    photo = photo3d.make(np.full((16, 16, 3), 0.5), depth=np.ones((16, 16)),
                         config=photo3d.Config(size=None))
    for out in (None, 5, ""):
        with pytest.raises(InputError, match="out must be a folder path"):
            photo.save(out)
    with pytest.raises(InputError, match="path must be a folder path"):
        photo3d.load(None)
    with pytest.raises(ConfigError, match="options must be a SaveOptions"):
        photo.save(tmp_path / "a", {"glb": False})
    with pytest.raises(ConfigError, match="unknown save option 'bogus'; the options are"):
        photo.save(tmp_path / "b", bogus=1)
    assert list(tmp_path.iterdir()) == []


def test_export_and_light_mesh_take_what_a_user_means_or_refuse_it(tmp_path):
    # export_folder(out, "splats.ply") said "unknown export format 's'"; splat_fit="no"
    # was taken as true; light_mesh(max_error="1") was a TypeError inside the simplifier
    import photo3d
    from photo3d.export import export_folder

    photo = photo3d.make(np.full((16, 16, 3), 0.5), depth=np.ones((16, 16)),
                         config=photo3d.Config(size=None))
    out = photo.save(tmp_path / "out", viewer=False, ply=None)
    assert [p.name for p in export_folder(out, "splats.ply")] == ["splats.ply"]
    with pytest.raises(ConfigError, match="splat_fit must be True or False, got 'no'"):
        export_folder(out, ["splats.spz"], splat_fit="no")
    assert not (out / "splats.spz").exists()
    for bad in ("1", np.nan, -1.0, np.inf):
        with pytest.raises(InputError, match="need max_error >= 0"):
            photo.light_mesh(max_error=bad)
