"""The depth map a photo file carries (:mod:`photo3d.depth.portrait` reads JPEG
portraits, :mod:`photo3d.depth.heif` HEIF/HEIC ones)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class EmbeddedDepth:
    """A depth map found inside a photo file.

    Attributes:
        depth: ``(h, w) float32`` at the stored resolution (often smaller than the
            photo), upright: depth in the file's units for ``kind="depth"``, else
            normalised disparity in [0, 1].
        kind: ``"depth"`` (camera z, near = small) or ``"disparity"``.
        source: one line saying where the map came from and how it was decoded.
        warnings: notes about doubtful decoding.
        image: ``(H, W, 3) float32`` the unblurred original photo carried by a
            Google lens-blur JPEG (``GImage:Data``), else None.
    """

    depth: np.ndarray
    kind: str
    source: str
    warnings: tuple[str, ...] = ()
    image: np.ndarray | None = None
