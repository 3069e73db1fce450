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
        alpha: ``(N,) float32`` coverage in [0, 1]: 1 for every pixel except the
            mixed pixels along a foreground's silhouette (the soft fringe of
            :mod:`photo3d.stages.silhouettes`), which are drawn blended over what lies
            behind them; their ``color`` is the foreground's estimated colour, not the
            photo's mixed one. None (the default) means all 1.

    Example:
        >>> from photo3d.stages.ldi import from_image
        >>> ldi = from_image(np.zeros((1, 2, 3), np.float32), np.ones((1, 2), np.float32))
        >>> ldi.alpha.tolist(), ldi.soft
        ([1.0, 1.0], False)
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
    alpha: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = self.y.shape[0]
        if self.alpha is None:
            object.__setattr__(self, "alpha", np.ones(n, np.float32))
        elif self.alpha.shape != (n,):
            raise ValueError(f"alpha has shape {self.alpha.shape}, expected ({n},)")

    @property
    def soft(self) -> bool:
        """Whether any pixel has ``alpha < 1`` (a soft silhouette)."""
        return bool(self.alpha.size) and float(self.alpha.min()) < 1.0

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
        """Raise ``ValueError`` if links are not symmetric 4-neighbour links (an
        explicit check, not ``assert``: it guards files read from disk, also under
        ``python -O``).

        One direction at a time (a tenth of the time of all four at once through
        ``np.nonzero`` of the whole table: 0.06 s instead of 0.65 s for the sample's
        1.45M pixels, which every read of a ``photo3d.npz`` pays).

        Example:
            >>> ldi = LDI(y=np.array([0, 0], np.int32), x=np.array([0, 1], np.int32),
            ...           color=np.zeros((2, 3), np.float32), disparity=np.ones(2, np.float32),
            ...           links=np.array([[-1, 1, -1, -1], [0, -1, -1, -1]], np.int32),
            ...           label=np.zeros(2, np.uint8), intrinsics=Intrinsics.default(2, 1),
            ...           mapping=DepthMapping.from_inverse_depth(0.0, 1.0))
            >>> ldi.check()
            >>> ldi.links[1, 0] = -1  # pixel 0 links to 1, 1 not back to 0
            >>> try:
            ...     ldi.check()
            ... except ValueError as err:
            ...     print(err)
            links are not symmetric
        """
        links, y, x = self.links, self.y, self.x
        for d, (dy, dx) in enumerate(((0, -1), (0, 1), (-1, 0), (1, 0))):
            column = links[:, d]
            src = np.flatnonzero(column >= 0)
            dst = column[src]
            if not np.array_equal(links[dst, d ^ 1], src):
                raise ValueError("links are not symmetric")
            if not np.array_equal(y[dst], y[src] + dy):
                raise ValueError("link joins wrong rows")
            if not np.array_equal(x[dst], x[src] + dx):
                raise ValueError("link joins wrong columns")
