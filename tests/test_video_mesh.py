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
