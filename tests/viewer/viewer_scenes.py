"""Small 3D photos and helpers shared by the viewer tests."""

from __future__ import annotations

import functools

import numpy as np
from conftest import exact_config, texture

import photo3d
from photo3d.structures.mesh import Mesh

WIDTH, HEIGHT = 96, 64


@functools.cache
def box_photo() -> photo3d.Photo3D:
    """96x64 textured background (disparity 1) with a box in front (disparity 2.5).

    Inpainted layers behind the box and a 12 px extrapolated border, so moved
    cameras see hidden surfaces.
    """
    disp = np.ones((HEIGHT, WIDTH), np.float32)
    disp[18:46, 30:64] = 2.5
    return photo3d.make(texture(HEIGHT, WIDTH, seed=3), depth=disp, config=exact_config(border=12))


def canonical_faces(faces: np.ndarray) -> np.ndarray:
    """Faces rotated so the smallest index is first (same winding), rows sorted."""
    f = np.asarray(faces)
    k = np.argmin(f, axis=1)
    rows = np.arange(len(f))[:, None]
    rotated = f[rows, (k[:, None] + np.arange(3)) % 3]
    return rotated[np.lexsort(rotated.T[::-1])]


def shuffled(mesh: Mesh, seed: int = 0) -> Mesh:
    """The same surface with faces in random order and random rotations."""
    rng = np.random.default_rng(seed)
    faces = mesh.faces[rng.permutation(len(mesh.faces))]
    shift = rng.integers(0, 3, len(faces))
    faces = faces[np.arange(len(faces))[:, None], (shift[:, None] + np.arange(3)) % 3]
    return Mesh(mesh.vertices, mesh.colors, mesh.labels, faces.astype(np.int32), mesh.width,
                mesh.height, mesh.hfov, mesh.vfov)
