"""LDI -> triangle mesh (paper, Sec. 3.4).

One vertex per LDI pixel, placed at its pixel centre and depth; two triangles per
fully linked 2x2 quad of LDI pixels, one triangle where exactly three of the quad's
four links exist (stitches the ends of depth edges so nothing tears). Triangles are
emitted once each, wound counter-clockwise as seen from the input camera (normals
point towards it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photo3d._meshfaces import mesh_faces
from photo3d.camera import unproject
from photo3d.errors import InputError
from photo3d.ldi import LDI


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
    """

    vertices: np.ndarray
    colors: np.ndarray
    labels: np.ndarray
    faces: np.ndarray
    width: int
    height: int
    hfov: float
    vfov: float

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


def build_mesh(ldi: LDI) -> Mesh:
    """Triangulate an LDI.

    For a quad with corners a (top-left), b (top-right), c (bottom-left) and
    d (bottom-right), the corner triangles are T_a = (a, c, b) if a links right and
    down, T_d = (b, c, d) if d links up and left, and only when neither exists
    T_b = (a, d, b) (b links left and down) or else T_c = (a, c, d) (c links up
    and right). Every triangle is produced by exactly one corner pixel, so none is
    duplicated, and all are wound the same way.

    Args:
        ldi: the layered depth image.

    Returns:
        :class:`Mesh` with one vertex per LDI pixel (same order).

    Example:
        >>> from photo3d.ldi import from_image
        >>> ldi = from_image(np.zeros((3, 3, 3), np.float32), np.ones((3, 3), np.float32))
        >>> m = build_mesh(ldi)
        >>> m.vertices.shape, m.faces.shape
        ((9, 3), (8, 3))
    """
    # Faces in order of their last vertex: the input layer's faces come first (its
    # pixels are the first H * W), and neighbouring faces are close in memory.
    faces = mesh_faces(np.ascontiguousarray(ldi.links, np.int32))
    hfov, vfov = ldi.intrinsics.fov
    return Mesh(
        vertices=unproject(ldi.x, ldi.y, ldi.depth(), ldi.intrinsics),
        colors=np.clip(np.round(ldi.color * 255.0), 0, 255).astype(np.uint8),
        labels=ldi.label.copy(),
        faces=faces,
        width=ldi.width,
        height=ldi.height,
        hfov=hfov,
        vfov=vfov,
    )
