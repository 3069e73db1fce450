"""photo3d's own light mesh read back from its ``mesh.glb`` (io/light_glb)."""

from __future__ import annotations

import numpy as np
import pytest

import photo3d
from photo3d.errors import InputError
from photo3d.io.gltf import write_glb
from photo3d.io.gltf_textured import write_textured_glb
from photo3d.io.light_glb import read_light_glb
from photo3d.mesh.full import build_mesh
from photo3d.mesh.light import build_light_mesh


def _ldi(shape=(32, 48)):
    """A textured photo with a depth step: its light mesh has hidden-layer faces."""
    h, w = shape
    yy, xx = np.mgrid[0:h, 0:w] / w
    image = np.stack([0.5 + 0.3 * np.sin(9 * xx + c) * np.cos(7 * yy) for c in range(3)], -1)
    disparity = np.ones(shape, np.float32)
    disparity[:, w // 2:] = 2.0
    return photo3d.make(image, depth=disparity, config=photo3d.Config(size=None)).ldi


@pytest.fixture(scope="module")
def ldi():
    return _ldi()


def test_reads_back_the_geometry_exactly_and_finds_the_input_faces(tmp_path, ldi):
    built = build_light_mesh(ldi)
    assert 0 < built.n_input < len(built.faces)  # there are hidden layers
    path = tmp_path / "mesh.glb"
    write_textured_glb(path, built)
    back = read_light_glb(path, intrinsics=ldi.intrinsics, lattice=ldi.lattice_shape)
    assert back.n_input == built.n_input
    for name in ("vertices", "uv", "faces", "labels"):
        assert np.array_equal(getattr(back, name), getattr(built, name)), name
    assert back.texture.shape == built.texture.shape  # JPEG: close, not equal
    assert np.abs(back.texture.astype(int) - built.texture).mean() < 3


def test_refuses_a_file_photo3d_did_not_write(tmp_path, ldi):
    path = tmp_path / "mesh.glb"
    write_textured_glb(path, build_light_mesh(ldi))
    data = path.read_bytes()
    assert data.count(b'"photo3d"') >= 1
    path.write_bytes(data.replace(b'"generator": "photo3d"', b'"generator": "other3d"')
                     .replace(b'"generator":"photo3d"', b'"generator":"other3d"'))
    with pytest.raises(InputError, match="not written by photo3d"):
        read_light_glb(path, intrinsics=ldi.intrinsics, lattice=ldi.lattice_shape)


def test_refuses_the_full_mesh_another_photos_mesh_and_no_file(tmp_path, ldi):
    full = tmp_path / "full.glb"
    write_glb(full, build_mesh(ldi))
    with pytest.raises(InputError):
        read_light_glb(full, intrinsics=ldi.intrinsics, lattice=ldi.lattice_shape)
    other = tmp_path / "other.glb"
    write_textured_glb(other, build_light_mesh(_ldi((30, 48))))
    with pytest.raises(InputError, match="not of this"):
        read_light_glb(other, intrinsics=ldi.intrinsics, lattice=ldi.lattice_shape)
    with pytest.raises(InputError):
        read_light_glb(tmp_path / "missing.glb", intrinsics=ldi.intrinsics,
                       lattice=ldi.lattice_shape)
