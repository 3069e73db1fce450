"""Which mesh the videos of ``save`` are drawn from (light with OpenGL, full with numba)."""

from __future__ import annotations

import numpy as np
import pytest

import photo3d
from photo3d.output import _video_mesh
from photo3d.render.renderer import RenderSettings
from photo3d.structures.mesh import Mesh, TexturedMesh


def _photo():
    return photo3d.make(np.full((24, 24, 3), 0.5), depth=np.ones((24, 24)),
                        config=photo3d.Config(size=None))


def test_numba_videos_use_the_full_mesh():
    photo = _photo()
    mesh = photo.mesh()
    assert _video_mesh(photo, mesh, None, RenderSettings(backend="numba"), 0.5) is mesh


def test_opengl_videos_use_the_light_mesh():
    from photo3d.render.renderer import select_backend

    try:
        select_backend("gl")
    except Exception as err:  # noqa: BLE001 - no EGL or moderngl on this machine
        pytest.skip(f"no OpenGL here: {err}")
    photo = _photo()
    mesh = photo.mesh()
    chosen = _video_mesh(photo, mesh, None, RenderSettings(backend="gl"), 0.5)
    assert isinstance(chosen, TexturedMesh) and not isinstance(chosen, Mesh)
    light = photo.light_mesh()
    assert _video_mesh(photo, mesh, light, RenderSettings(backend="gl"), 0.5) is light
