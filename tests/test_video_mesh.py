"""Which mesh the videos of ``save`` are drawn from (the light one, with either backend)."""

from __future__ import annotations

import numpy as np
import pytest

import photo3d
from photo3d.output import _video_mesh
from photo3d.render.renderer import RenderSettings
from photo3d.save_options import SaveOptions
from photo3d.structures.mesh import Mesh, TexturedMesh

NUMBA = SaveOptions(render_settings=RenderSettings(backend="numba"), light_error=0.5)
GL = SaveOptions(render_settings=RenderSettings(backend="gl"), light_error=0.5)


def _photo():
    return photo3d.make(np.full((24, 24, 3), 0.5), depth=np.ones((24, 24)),
                        config=photo3d.Config(size=None))


def test_numba_videos_use_the_light_mesh():
    photo = _photo()
    mesh = photo.mesh()
    chosen = _video_mesh(photo, mesh, None, NUMBA)
    assert isinstance(chosen, TexturedMesh) and not isinstance(chosen, Mesh)
    light = photo.light_mesh()
    assert _video_mesh(photo, mesh, light, NUMBA) is light


def test_opengl_videos_use_the_light_mesh():
    from photo3d.render.renderer import select_backend

    try:
        select_backend("gl")
    except Exception as err:  # noqa: BLE001 - no EGL or moderngl on this machine
        pytest.skip(f"no OpenGL here: {err}")
    photo = _photo()
    mesh = photo.mesh()
    chosen = _video_mesh(photo, mesh, None, GL)
    assert isinstance(chosen, TexturedMesh) and not isinstance(chosen, Mesh)
    light = photo.light_mesh()
    assert _video_mesh(photo, mesh, light, GL) is light


def _saved(tmp_path, **changes):
    photo = photo3d.make(np.random.default_rng(0).random((24, 32, 3)),
                         depth=np.where(np.arange(32) < 16, 1.0, 2.0) * np.ones((24, 1)),
                         config=photo3d.Config(size=None))
    return photo, photo.save(tmp_path / "out", SaveOptions(ply=None, viewer=False, **changes))


def test_a_saved_folder_videos_read_its_light_glb(tmp_path, monkeypatch):
    photo, out = _saved(tmp_path)
    built = photo.light_mesh()

    def no_build(*args, **kwargs):
        raise AssertionError("the light mesh was built, not read")

    monkeypatch.setattr("photo3d.output.build_light_mesh", no_build)
    chosen = _video_mesh(photo, None, None, NUMBA, folder=out)
    assert np.array_equal(chosen.faces, built.faces) and chosen.n_input == built.n_input


@pytest.mark.parametrize("case", ["full glb", "other error", "foreign file", "no config"])
def test_a_folder_without_its_own_light_glb_builds_it(tmp_path, monkeypatch, case):
    import json

    photo, out = _saved(tmp_path, full_glb=case == "full glb",
                        light_error=0.25 if case == "other error" else None)
    if case == "foreign file":
        (out / "mesh.glb").write_bytes(b"glTF not really")
    if case == "no config":
        (out / "config.json").write_text(json.dumps([1, 2]))
    built = []
    real = photo3d.output.build_light_mesh

    def build(*args, **kwargs):
        built.append(kwargs["max_error"])
        return real(*args, **kwargs)

    monkeypatch.setattr("photo3d.output.build_light_mesh", build)
    chosen = _video_mesh(photo, None, None, NUMBA, folder=out)
    assert isinstance(chosen, TexturedMesh) and built == [0.5]


def test_a_read_back_mesh_draws_with_the_kernels_a_built_one_compiled(tmp_path):
    """The texture read back is writeable like the built one: no second compilation
    of the rasterizer for a read-only texture."""
    from photo3d.render._kernels import raster_frame
    from photo3d.render.renderer import Renderer, video_settings

    photo, out = _saved(tmp_path)
    camera = photo3d.camera.Camera(photo.ldi.intrinsics, np.eye(4))
    Renderer(photo.light_mesh(), video_settings()).render(camera)
    before = list(raster_frame.signatures)
    Renderer(_video_mesh(photo, None, None, NUMBA, folder=out), video_settings()).render(camera)
    assert raster_frame.signatures == before
