"""Depth steps where the photo's coverage crosses one half (issue 44), after the
alignment.

A depth map sampled at pixel centres puts a pixel on the near side of a silhouette
when the foreground covers more than half of it. Depth that is fat at silhouettes
(networks, stereo, phones) does not: after :func:`~photo3d.stages.align.align_edges`
the outermost near-side pixel is often a mixed pixel that shows mostly background, a
line of intermediate colour along the outline that the colour-guided median keeps as
it keeps a thin wire (its own colour lies along it). Cut there, and grown by
``grow_foreground``, the foreground carries a line of background colour into every
novel view.

:func:`snap_to_coverage` estimates the coverage of every near-side pixel next to a
step with the soft silhouettes' matting (:func:`~photo3d.stages.silhouettes.
soft_silhouettes`: the pixel as ``a F + (1 - a) B``, ``F`` from the near side's pixels
at least a step further in, ``B`` from the far side) and hands the pixels covered less
than half to the far side, pass by pass. A structure with no inner pixels (a 1 or 2
px wire) has no ``F`` to compare with and keeps its value; so does a pixel whose two
sides look alike.
"""

from __future__ import annotations

import numpy as np

from photo3d.stages.silhouettes import soft_silhouettes

_DIRECTIONS = ((0, -1), (0, 1), (-1, 0), (1, 0))  # the cut bits: left, right, up, down


def snap_to_coverage(image: np.ndarray, disparity: np.ndarray, *, threshold: float,
                     radius: int = 2, passes: int = 4) -> np.ndarray:
    """Hand the near-side pixels along depth steps that the foreground covers less than
    half to the far side (module docstring).

    Each pass finds the steps (4-neighbours more than ``threshold`` apart), estimates
    the coverage of the near-side pixels next to them (matting in a ``2 radius + 1``
    window) and gives each pixel covered less than half the value of its nearest
    farther 4-neighbour; the passes stop early when none moves.

    Args:
        image: ``(H, W, 3) float32`` photo in [0, 1].
        disparity: ``(H, W) float32`` normalised disparity (larger is nearer).
        threshold: the discontinuity threshold (normalised disparity).
        radius: half side of the matting window, working pixels.
        passes: peeling passes (each moves an outline by at most one pixel).

    Returns:
        ``(H, W) float32`` disparity.

    Example:
        >>> img = np.zeros((8, 12, 3), np.float32); img[:, 6:] = 1.0  # white foreground
        >>> img[:, 5] = 0.25                                          # a 25 % mixed column
        >>> d = np.zeros((8, 12), np.float32); d[:, 4:] = 1.0          # depth 2 px fat
        >>> snap_to_coverage(img, d, threshold=0.04)[4].tolist()
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0]
    """
    out = np.array(disparity, np.float32, copy=True)
    guide = np.ascontiguousarray(image, np.float32)
    for _ in range(max(passes, 0)):
        cuts, far = _steps(out, threshold)
        if not cuts.any():
            break
        alpha = soft_silhouettes(guide, out, cuts, band=1, radius=radius,
                                 threshold=threshold).alpha
        move = (alpha < 0.5) & np.isfinite(far)
        if not move.any():
            break
        out[move] = far[move]
    return out


def _steps(disparity: np.ndarray, threshold: float) -> tuple[np.ndarray, np.ndarray]:
    """``(cuts (H, W) uint8, far (H, W) float32)``: the 4-neighbour links across a step
    (bit ``d`` for direction ``d`` of :data:`_DIRECTIONS`, as
    :attr:`~photo3d.stages.edges.DepthEdges.cuts`) and, on each step's near side, the
    value of the nearest of its farther 4-neighbours (``-inf`` elsewhere)."""
    h, w = disparity.shape
    cuts = np.zeros((h, w), np.uint8)
    far = np.full((h, w), -np.inf, np.float32)
    padded = np.pad(disparity, 1, mode="constant", constant_values=np.nan)
    for bit, (dy, dx) in enumerate(_DIRECTIONS):
        other = padded[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]
        with np.errstate(invalid="ignore"):
            cuts[np.abs(other - disparity) > threshold] |= np.uint8(1 << bit)
            lower = disparity - other > threshold
        far = np.where(lower & (other > far), other, far)
    return cuts, far
