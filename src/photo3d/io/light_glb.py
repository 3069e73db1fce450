"""photo3d's own light mesh file read back: the ``mesh.glb`` of a 3D photo folder.

A folder saved with the default ``mesh.glb`` holds the light textured mesh
(:func:`photo3d.mesh.light.build_light_mesh`, written by
:func:`photo3d.io.gltf_textured.write_textured_glb`). Reading it takes about 0.05 s
where building it again from ``photo3d.npz`` takes 1.5-2 s, so ``photo3d render``
and the UI's videos draw it (:func:`photo3d.output.write_videos`). The geometry reads
back exactly; the texture is the file's JPEG (quality 90: 38.8 dB from the built
texture on the demo, frames 39 dB from those of the built mesh).

:func:`read_light_glb` reads only a file photo3d wrote for an LDI of the given
size (its generator, its textured light mesh, its view): anything else raises
:class:`~photo3d.errors.InputError`, and the caller builds the mesh instead.
"""

from __future__ import annotations

import math
import os
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from photo3d.errors import InputError
from photo3d.io.glb import read_chunks
from photo3d.io.gltf_textured import read_textured_glb

if TYPE_CHECKING:
    from photo3d.camera import Intrinsics
    from photo3d.structures.mesh import TexturedMesh

PathLike = str | os.PathLike[str]

TEXTURE_RATIO = 16
"""A light mesh's texture holds at most this many pixels per lattice pixel (plus a
megapixel), checked before it is decoded: the atlas of the input layer and the
hidden layers' charts measures 1-5 lattices; a larger one is not photo3d's (its
texture could take gigabytes), so the mesh is built again instead."""


def read_light_glb(path: PathLike, *, intrinsics: Intrinsics,
                   lattice: tuple[int, int]) -> TexturedMesh:
    """The light textured mesh photo3d saved in ``path``, for the LDI it was made of.

    Args:
        path: a ``mesh.glb`` written by photo3d's light mesh writer.
        intrinsics: the LDI's input view (the file must be of the same size and
            field of view).
        lattice: ``(rows, cols)`` of the LDI's lattice (image plus border): the
            input layer's texels are the texture's top-left ``rows x cols`` block,
            which gives ``n_input`` (the file does not store it).

    Returns:
        :class:`~photo3d.structures.mesh.TexturedMesh` with its ``n_input`` faces of
        the input layer first, as :func:`~photo3d.mesh.light.build_light_mesh` made it.

    Raises:
        InputError: the file is missing, not photo3d's, not a textured light mesh,
            of another view, or damaged in any way (every field is checked before
            it is used; a texture larger than :data:`TEXTURE_RATIO` lattices is
            refused before it is decoded).

    Example:
        >>> import tempfile, pathlib
        >>> from photo3d.io.gltf_textured import write_textured_glb
        >>> from photo3d.mesh.light import build_light_mesh
        >>> from photo3d.stages.ldi import from_image
        >>> ldi = from_image(np.full((8, 8, 3), 0.5, np.float32), np.ones((8, 8), np.float32))
        >>> built = build_light_mesh(ldi)
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "mesh.glb"
        >>> write_textured_glb(path, built)
        >>> back = read_light_glb(path, intrinsics=ldi.intrinsics, lattice=ldi.lattice_shape)
        >>> back.n_input == built.n_input, np.array_equal(back.faces, built.faces)
        (True, True)
    """
    rows, cols = lattice
    document, _ = read_chunks(path)
    asset = document.get("asset")
    if not isinstance(asset, dict) or asset.get("generator") != "photo3d":
        raise InputError(f"{path} was not written by photo3d")
    mesh = read_textured_glb(path, max_pixels=TEXTURE_RATIO * rows * cols + (1 << 20))
    k = intrinsics
    hfov, vfov = k.fov
    if (mesh.width, mesh.height) != (k.width, k.height) or not (
            math.isclose(mesh.hfov, hfov, rel_tol=1e-9) and math.isclose(mesh.vfov, vfov,
                                                                         rel_tol=1e-9)):
        raise InputError(f"{path} is the mesh of a {mesh.width}x{mesh.height} view, "
                         f"not of this {k.width}x{k.height} photo")
    if mesh.texture.shape[0] < rows or mesh.texture.shape[1] < cols:
        raise InputError(f"{path} has a {mesh.texture.shape[1]}x{mesh.texture.shape[0]} "
                         f"texture, smaller than the photo's {cols}x{rows} lattice")
    # a writeable copy: the rasterizer's kernels are compiled for the built mesh's
    # writeable texture; the decoded JPEG's read-only one would compile them again
    return replace(_with_n_input(mesh, rows, cols), texture=np.array(mesh.texture))


def _with_n_input(mesh: TexturedMesh, rows: int, cols: int) -> TexturedMesh:
    """``mesh`` with ``n_input``: the leading faces whose corners all lie in the
    texture's top-left ``rows x cols`` texels (the input layer's chart; the hidden
    layers' charts lie beside and below it, a gutter texel away).

    Example:
        >>> from photo3d.structures.mesh import TexturedMesh
        >>> uv = np.array([[0.1, 0.1], [0.2, 0.1], [0.1, 0.2], [0.9, 0.9]], np.float32)
        >>> m = TexturedMesh(np.zeros((4, 3)), uv, np.zeros((10, 10, 3), np.uint8),
        ...                  np.ones(4), np.array([[0, 1, 2], [1, 2, 3]]), 0, 4, 4, 1.0, 1.0)
        >>> _with_n_input(m, 5, 5).n_input
        1
    """
    t_h, t_w = mesh.texture.shape[:2]
    inside = ((mesh.uv[:, 0] * t_w - 0.5 < cols - 0.5)
              & (mesh.uv[:, 1] * t_h - 0.5 < rows - 0.5))
    face_inside = inside[mesh.faces].all(axis=1)
    n_input = len(face_inside) if face_inside.all() else int(np.argmin(face_inside))
    return replace(mesh, n_input=n_input)
