"""The layered depth image type: flat arrays with explicit 4-neighbour links
(built by :mod:`photo3d.stages.ldi`).

An LDI holds any number of pixels per lattice position. Pixel ``i`` has a lattice
position ``(y[i], x[i])`` (it may lie outside the input image in the extrapolated
border), a colour, a normalised disparity, a label, and at most one neighbour per
direction in ``links[i]`` (order left, right, up, down; -1 = none). Links are always
symmetric: ``links[i, d] == j`` iff ``links[j, d ^ 1] == i``. The first ``H * W``
pixels are the input image in raster order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photo3d.camera import DepthMapping, Intrinsics

LABEL_ORIGINAL = 1
LABEL_BORDER = 5


@dataclass(frozen=True)
class LDI:
    """Layered depth image (structure of arrays).

    Attributes:
        y, x: ``(N,) int32`` lattice row / column (border pixels lie outside
            ``[0, H) x [0, W)`` by at most ``border``).
        color: ``(N, 3) float32`` sRGB in [0, 1].
        disparity: ``(N,) float32`` normalised disparity (larger = nearer).
        links: ``(N, 4) int32`` neighbour index per direction L, R, U, D; -1 = none.
        label: ``(N,) uint8`` 1 original, 2-3 inpainted (pass 1, later passes),
            5 extrapolated border.
        intrinsics: camera of the input view (image size ``W x H``).
        mapping: normalised disparity -> depth z.
        border: width of the extrapolated frame in pixels.
    """

    y: np.ndarray
    x: np.ndarray
    color: np.ndarray
    disparity: np.ndarray
    links: np.ndarray
    label: np.ndarray
    intrinsics: Intrinsics
    mapping: DepthMapping
    border: int = 0

    @property
    def size(self) -> int:
        """Number of LDI pixels."""
        return int(self.y.shape[0])

    @property
    def height(self) -> int:
        return self.intrinsics.height

    @property
    def width(self) -> int:
        return self.intrinsics.width

    @property
    def lattice_shape(self) -> tuple[int, int]:
        """``(rows, cols)`` of the lattice including the border."""
        return self.height + 2 * self.border, self.width + 2 * self.border

    def positions(self) -> np.ndarray:
        """``(N,) int64`` flat lattice index ``(y + b) * cols + (x + b)``."""
        cols = self.width + 2 * self.border
        return (self.y.astype(np.int64) + self.border) * cols + (self.x + self.border)

    def position_index(self) -> tuple[np.ndarray, np.ndarray]:
        """CSR lookup of the pixels at each lattice position.

        Returns:
            ``starts (P + 1,) int64`` and ``order (N,) int64``: the pixels at flat
            position ``p`` are ``order[starts[p]:starts[p + 1]]``.
        """
        pos = self.positions()
        rows, cols = self.lattice_shape
        order = np.argsort(pos, kind="stable")
        starts = np.zeros(rows * cols + 1, np.int64)
        np.cumsum(np.bincount(pos, minlength=rows * cols), out=starts[1:])
        return starts, order

    def layers(self) -> np.ndarray:
        """``(rows, cols) int32`` number of pixels at each lattice position."""
        rows, cols = self.lattice_shape
        return np.bincount(self.positions(), minlength=rows * cols).reshape(rows, cols)

    def depth(self) -> np.ndarray:
        """``(N,) float32`` camera z of every pixel."""
        return self.mapping.depth(self.disparity)

    def check(self) -> None:
        """Raise ``AssertionError`` if links are not symmetric 4-neighbour links."""
        src, d = np.nonzero(self.links >= 0)
        dst = self.links[src, d]
        assert np.all(self.links[dst, d ^ 1] == src), "links are not symmetric"
        dy = np.array([0, 0, -1, 1])[d]
        dx = np.array([-1, 1, 0, 0])[d]
        assert np.all(self.y[dst] == self.y[src] + dy), "link joins wrong rows"
        assert np.all(self.x[dst] == self.x[src] + dx), "link joins wrong columns"
