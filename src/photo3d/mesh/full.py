"""LDI -> triangle mesh (paper, Sec. 3.4).

One vertex per LDI pixel, placed at its pixel centre and depth; two triangles per
fully linked 2x2 quad of LDI pixels, one triangle where exactly three of the quad's
four links exist (stitches the ends of depth edges so nothing tears). Triangles are
emitted once each, wound counter-clockwise as seen from the input camera (normals
point towards it).
"""

from __future__ import annotations

import numpy as np

from photo3d.camera import unproject
from photo3d.mesh._faces import mesh_faces
from photo3d.structures.ldi import LDI
from photo3d.structures.mesh import Mesh


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
        :class:`Mesh` with one vertex per LDI pixel (same order); its ``alpha`` is the
        LDI's when a silhouette is soft (:attr:`LDI.soft`), else None.

    Example:
        >>> from photo3d.stages.ldi import from_image
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
        alpha=ldi.alpha.copy() if ldi.soft else None,
    )
