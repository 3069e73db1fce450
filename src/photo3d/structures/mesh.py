"""The mesh types every writer and renderer takes: :class:`Mesh` (one vertex per LDI
pixel, vertex colours; built by :mod:`photo3d.mesh.full`) and :class:`TexturedMesh`
(fewer vertices, colours in a texture; built by :mod:`photo3d.mesh.light`).

Both are in the input camera's frame (OpenCV axes, see :mod:`photo3d.camera`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from photo3d.errors import InputError


@dataclass(frozen=True)
class Mesh:
    """A vertex-coloured triangle mesh in the input camera's frame.

    Attributes:
        vertices: ``(N, 3) float32`` OpenCV camera coordinates of the input view
            (x right, y down, z forward; units of the depth mapping).
        colors: ``(N, 3) uint8`` sRGB vertex colours.
        labels: ``(N,) uint8`` the authors' vertex label (PLY "alpha"): 1 original,
            ``pass + 1`` for inpainted pixels, 5 extrapolated border.
        faces: ``(M, 3) int32`` vertex indices, counter-clockwise seen from the camera.
        width, height: size in pixels of the input view.
        hfov, vfov: field of view of the input view, radians.
        alpha: ``(N,) float32`` vertex coverage in [0, 1] (the LDI's soft
            silhouettes, :attr:`~photo3d.structures.ldi.LDI.alpha`), or None: all 1.
            A face with a vertex below 1 is drawn blended over what lies behind it
            (:meth:`split_fringe`).
    """

    vertices: np.ndarray
    colors: np.ndarray
    labels: np.ndarray
    faces: np.ndarray
    width: int
    height: int
    hfov: float
    vfov: float
    alpha: np.ndarray | None = None

    def split_fringe(self) -> tuple[Mesh, Mesh | None]:
        """``(opaque, fringe)``: this mesh without the faces that touch a vertex of
        ``alpha < 1`` (same vertices, ``alpha`` None), and those faces as a mesh of
        their own vertices only (with their ``alpha``), or None if there are none.

        Example:
            >>> v = np.zeros((4, 3), np.float32)
            >>> m = Mesh(v, np.zeros((4, 3), np.uint8), np.ones(4, np.uint8),
            ...          np.array([[0, 1, 2], [1, 3, 2]], np.int32), 2, 2, 1.0, 1.0,
            ...          alpha=np.array([1, 1, 1, 0.5], np.float32))
            >>> opaque, fringe = m.split_fringe()
            >>> opaque.faces.tolist(), fringe.faces.tolist(), fringe.alpha.tolist()
            ([[0, 1, 2]], [[0, 2, 1]], [1.0, 1.0, 0.5])
        """
        if self.alpha is None:
            return self, None
        faces = np.asarray(self.faces, np.int32)
        soft = np.asarray(self.alpha, np.float32) < 1.0
        touch = soft[faces].any(axis=1)
        opaque = dataclasses.replace(self, faces=faces[~touch], alpha=None)
        if not touch.any():
            return opaque, None
        used, inverse = np.unique(faces[touch], return_inverse=True)
        return opaque, dataclasses.replace(
            self, vertices=np.asarray(self.vertices)[used], colors=np.asarray(self.colors)[used],
            labels=np.asarray(self.labels)[used],
            faces=inverse.reshape(-1, 3).astype(np.int32),
            alpha=np.asarray(self.alpha, np.float32)[used])

    def checked(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(vertices, colors, labels, faces)`` in the documented dtypes, validated.

        Raises :class:`~photo3d.errors.InputError` on inconsistent shapes or face
        indices out of range (what writers need before they touch a file).

        Example:
            >>> m = Mesh(np.zeros((3, 3)), np.zeros((3, 3)), np.ones(3), np.array([[0, 1, 2]]),
            ...          4, 4, 1.0, 1.0)
            >>> [a.dtype.name for a in m.checked()]
            ['float32', 'uint8', 'uint8', 'int32']
        """
        vertices = np.asarray(self.vertices, np.float32)
        count = len(vertices)
        arrays = (
            vertices,
            np.asarray(self.colors, np.uint8),
            np.asarray(self.labels, np.uint8),
            np.asarray(self.faces, np.int32),
        )
        shapes = ((count, 3), (count, 3), (count,), (len(arrays[3]), 3))
        for name, array, shape in zip(
            ("vertices", "colors", "labels", "faces"), arrays, shapes, strict=True
        ):
            if array.shape != shape:
                raise InputError(f"mesh.{name} has shape {array.shape}, expected {shape}")
        if arrays[3].size and (arrays[3].min() < 0 or arrays[3].max() >= count):
            raise InputError(f"mesh.faces has indices outside [0, {count})")
        return arrays


@dataclass(frozen=True)
class TexturedMesh:
    """A textured triangle mesh in the input camera's frame.

    Attributes:
        vertices: ``(N, 3) float32`` OpenCV camera coordinates of the input view.
        uv: ``(N, 2) float32`` texture coordinates in [0, 1], origin at the
            texture's top-left corner (glTF's convention), ``(u, v) = ((col + 0.5) /
            width, (row + 0.5) / height)`` of the texel holding the vertex colour.
        texture: ``(T, U, 3) uint8`` sRGB.
        labels: ``(N,) uint8`` the authors' vertex labels (see :class:`Mesh`).
        faces: ``(M, 3) int32`` counter-clockwise seen from the camera; the first
            ``n_input`` belong to the input layer.
        n_input: number of input-layer faces at the start of ``faces``.
        width, height: size in pixels of the input view.
        hfov, vfov: field of view of the input view, radians.
        overlay: the soft silhouettes' fringe (:meth:`Mesh.split_fringe`), drawn
            blended over this mesh, or None.
    """

    vertices: np.ndarray
    uv: np.ndarray
    texture: np.ndarray
    labels: np.ndarray
    faces: np.ndarray
    n_input: int
    width: int
    height: int
    hfov: float
    vfov: float
    overlay: Mesh | None = None

    def checked(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(vertices, uv, labels, faces)`` in the documented dtypes, validated.

        Example:
            >>> m = TexturedMesh(np.zeros((3, 3)), np.zeros((3, 2)), np.zeros((1, 1, 3), np.uint8),
            ...                  np.ones(3), np.array([[0, 1, 2]]), 1, 4, 4, 1.0, 1.0)
            >>> [a.dtype.name for a in m.checked()]
            ['float32', 'float32', 'uint8', 'int32']
        """
        vertices = np.asarray(self.vertices, np.float32)
        arrays = (vertices, np.asarray(self.uv, np.float32),
                  np.asarray(self.labels, np.uint8), np.asarray(self.faces, np.int32))
        n = len(vertices)
        shapes = ((n, 3), (n, 2), (n,), (len(arrays[3]), 3))
        for name, array, shape in zip(("vertices", "uv", "labels", "faces"), arrays, shapes,
                                      strict=True):
            if array.shape != shape:
                raise InputError(f"mesh.{name} has shape {array.shape}, expected {shape}")
        if arrays[3].size and (arrays[3].min() < 0 or arrays[3].max() >= n):
            raise InputError(f"mesh.faces has indices outside [0, {n})")
        texture = np.asarray(self.texture)
        if texture.ndim != 3 or texture.shape[2] != 3 or texture.dtype != np.uint8:
            raise InputError(f"mesh.texture must be (T, U, 3) uint8, got {texture.shape} "
                             f"{texture.dtype}")
        return arrays

    def sample(self) -> np.ndarray:
        """``(N, 3) uint8`` the texture at each vertex (its colour as a vertex mesh).

        Example:
            >>> m = TexturedMesh(np.zeros((1, 3)), np.array([[0.75, 0.25]]),
            ...                  np.arange(12, dtype=np.uint8).reshape(2, 2, 3), np.ones(1),
            ...                  np.zeros((0, 3), int), 0, 4, 4, 1.0, 1.0)
            >>> m.sample().tolist()
            [[3, 4, 5]]
        """
        t = np.asarray(self.texture)
        col = np.clip((self.uv[:, 0] * t.shape[1]).astype(np.int64), 0, t.shape[1] - 1)
        row = np.clip((self.uv[:, 1] * t.shape[0]).astype(np.int64), 0, t.shape[0] - 1)
        return t[row, col]
