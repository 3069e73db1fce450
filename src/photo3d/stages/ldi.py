"""The layered depth image: flat arrays with explicit 4-neighbour links.

An LDI holds any number of pixels per lattice position. Pixel ``i`` has a lattice
position ``(y[i], x[i])`` (it may lie outside the input image in the extrapolated
border), a colour, a normalised disparity, a label, and at most one neighbour per
direction in ``links[i]`` (order left, right, up, down; -1 = none). Links are always
symmetric: ``links[i, d] == j`` iff ``links[j, d ^ 1] == i``. The first ``H * W``
pixels are the input image in raster order.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

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


def from_image(
    image: np.ndarray,
    disparity: np.ndarray,
    *,
    intrinsics: Intrinsics | None = None,
    mapping: DepthMapping | None = None,
) -> LDI:
    """The trivial LDI: one fully 4-connected layer.

    Args:
        image: ``(H, W, 3) float32`` in [0, 1].
        disparity: ``(H, W) float32`` normalised disparity.
        intrinsics: defaults to :meth:`Intrinsics.default`.
        mapping: defaults to the authors' mapping (:class:`DepthMapping`).

    Example:
        >>> ldi = from_image(np.zeros((2, 3, 3), np.float32), np.zeros((2, 3), np.float32))
        >>> ldi.size, ldi.links[0].tolist()
        (6, [-1, 1, -1, 3])
    """
    h, w = disparity.shape
    idx = np.arange(h * w, dtype=np.int32).reshape(h, w)
    links = np.full((h, w, 4), -1, np.int32)
    links[:, 1:, 0] = idx[:, :-1]
    links[:, :-1, 1] = idx[:, 1:]
    links[1:, :, 2] = idx[:-1, :]
    links[:-1, :, 3] = idx[1:, :]
    yy, xx = np.divmod(np.arange(h * w, dtype=np.int32), np.int32(w))
    return LDI(
        y=yy.astype(np.int32),
        x=xx.astype(np.int32),
        color=np.ascontiguousarray(image.reshape(-1, 3), np.float32),
        disparity=np.ascontiguousarray(disparity.reshape(-1), np.float32),
        links=links.reshape(-1, 4),
        label=np.full(h * w, LABEL_ORIGINAL, np.uint8),
        intrinsics=intrinsics or Intrinsics.default(w, h),
        mapping=mapping or DepthMapping(),
    )


def cut(ldi: LDI, cuts: np.ndarray) -> LDI:
    """Remove the links marked in a cut mask (both directions).

    Args:
        ldi: an LDI whose first ``H * W`` pixels are the input image.
        cuts: ``(H, W) uint8`` direction bit set per input pixel.

    Example:
        >>> ldi = from_image(np.zeros((1, 2, 3), np.float32), np.zeros((1, 2), np.float32))
        >>> cut(ldi, np.array([[2, 0]], np.uint8)).links.tolist()
        [[-1, -1, -1, -1], [-1, -1, -1, -1]]
    """
    links = ldi.links.copy()
    flat = cuts.reshape(-1)
    for d in range(4):
        src = np.nonzero(flat & (1 << d))[0]
        dst = links[src, d]
        ok = dst >= 0
        links[dst[ok], d ^ 1] = -1
        links[src, d] = -1
    return replace(ldi, links=links)
