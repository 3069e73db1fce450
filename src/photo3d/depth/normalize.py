"""Raw depth or disparity -> validated, filled, normalised disparity.

Unknown values (NaN, +-inf, and depth <= 0 / disparity < 0, and values float32 cannot
hold: beyond its largest, or a depth so small that its inverse is) are filled along each
image row with the *farther* of the nearest known values to the left and right.
Unknown pixels in stereo ground truth and depth sensors are almost always
occlusions or shadows next to a foreground object, i.e. background, so the farther
neighbour is the plausible value; rows without any known value take the farthest
known value of the whole map.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from photo3d.depth.checks import is_flat
from photo3d.errors import InputError
from photo3d.io.limits import check_available

_PREPARE_BYTES = 24
"""Peak bytes per image pixel of :func:`prepare_depth` (the float32 map at the image's
size, its masks, inverse and filled disparity), besides 4 per pixel of the map."""


@dataclass(frozen=True)
class DepthInput:
    """Disparity ready for resizing and normalisation.

    Attributes:
        disparity: ``(H, W) float32`` inverse depth (any positive scale), filled.
        unknown: ``(H, W) bool`` pixels that were unknown in the input and got filled.
    """

    disparity: np.ndarray
    unknown: np.ndarray


def prepare_depth(depth: np.ndarray, image_shape: tuple[int, int], *, kind: str) -> DepthInput:
    """Validate a raw depth map against the image and turn it into filled disparity.

    Args:
        depth: ``(h, w)`` raw values as read from a file or given by the caller.
        image_shape: ``(H, W)`` of the image the depth belongs to. A map of another
            size with the same aspect ratio (within 1 %) is resampled (with a
            ``UserWarning``); any other size raises :class:`InputError`.
        kind: ``"disparity"`` (larger = nearer) or ``"depth"`` (camera z).

    Returns:
        :class:`DepthInput` at ``image_shape``.

    Raises:
        InputError: a map that is not ``(h, w)`` real numbers, of another aspect
            ratio, with no valid value, or beyond the available memory
            (:func:`photo3d.io.limits.check_available`, before it is converted).

    Example:
        >>> d = np.array([[1.0, np.inf], [2.0, 4.0]], np.float32)
        >>> prepare_depth(d, (2, 2), kind="disparity").disparity.tolist()
        [[1.0, 1.0], [2.0, 4.0]]
    """
    depth = np.asarray(depth)
    if depth.ndim == 3 and depth.shape[2] == 1:
        depth = depth[..., 0]
    if depth.ndim != 2:
        raise InputError(f"depth has shape {depth.shape}; expected a single-channel (H, W) map")
    if depth.size == 0:
        raise InputError(f"depth has shape {depth.shape}; it holds no values")
    if depth.dtype.kind not in "iuf":  # not complex (its imaginary part), nor times
        raise InputError(f"depth has dtype {depth.dtype}; expected real numbers")
    check_available(4 * depth.size + _PREPARE_BYTES * image_shape[0] * image_shape[1],
                    f"depth's {depth.shape[1]}x{depth.shape[0]} values")
    with np.errstate(over="ignore"):  # beyond float32: inf, unknown as below
        depth = depth.astype(np.float32)
    depth, note = match_shape(depth, image_shape)
    if note:
        warnings.warn(note, UserWarning, stacklevel=2)

    if kind == "depth":
        valid = np.isfinite(depth) & (depth > 0)
        with np.errstate(over="ignore"):  # a depth this tiny: inf, unknown
            inverse = 1.0 / np.where(valid, depth, 1.0)
        valid &= np.isfinite(inverse)
        disparity = np.where(valid, inverse, 0.0)
    elif kind == "disparity":
        valid = np.isfinite(depth) & (depth >= 0)
        disparity = np.where(valid, depth, 0.0)
    else:
        raise InputError(f"depth kind must be 'disparity' or 'depth', got {kind!r}")
    if not valid.any():
        raise InputError("depth has no valid value (all NaN, inf or out of range)")
    filled = fill_unknown(disparity.astype(np.float32), ~valid)
    return DepthInput(disparity=filled, unknown=~valid)


def match_shape(depth: np.ndarray, image_shape: tuple[int, int]) -> tuple[np.ndarray, str]:
    """Resample ``depth`` (nearest) to ``image_shape`` if only the resolution differs.

    Returns:
        ``(depth at image_shape, note)``; the note is ``""`` when nothing changed.

    Raises:
        InputError: the aspect ratios differ by more than 1 %.

    Example:
        >>> d, note = match_shape(np.ones((2, 3), np.float32), (4, 6))
        >>> d.shape, note
        ((4, 6), 'depth has shape (2, 3) but image is (4, 6); resampling the depth')
    """
    h, w = image_shape
    if depth.shape == (h, w):
        return depth, ""
    ratio_d, ratio_i = depth.shape[1] / depth.shape[0], w / h
    if abs(ratio_d / ratio_i - 1.0) > 0.01:
        raise InputError(
            f"depth has shape {depth.shape} but image is {(h, w)}: aspect ratios differ"
        )
    note = f"depth has shape {depth.shape} but image is {(h, w)}; resampling the depth"
    return _resize_nearest(depth, (h, w)), note


def fill_unknown(disparity: np.ndarray, unknown: np.ndarray) -> np.ndarray:
    """Fill ``unknown`` pixels with the farther (smaller) nearest known row neighbour.

    Args:
        disparity: ``(H, W) float32``; values under ``unknown`` are ignored.
        unknown: ``(H, W) bool``.

    Returns:
        ``(H, W) float32`` copy with every unknown pixel filled.

    Example:
        >>> d = np.array([[5.0, 0.0, 0.0, 2.0]], np.float32)
        >>> fill_unknown(d, np.array([[False, True, True, False]])).tolist()
        [[5.0, 2.0, 2.0, 2.0]]
    """
    if not unknown.any():
        return disparity.copy()
    h, w = disparity.shape
    cols = np.broadcast_to(np.arange(w), (h, w))
    known = ~unknown
    # Index of the nearest known pixel to the left / right in each row (-1 / w: none).
    left = np.maximum.accumulate(np.where(known, cols, -1), axis=1)
    right = np.minimum.accumulate(np.where(known, cols, w)[:, ::-1], axis=1)[:, ::-1]
    rows = np.arange(h)[:, None]
    big = np.float32(np.inf)
    lv = np.where(left >= 0, disparity[rows, np.clip(left, 0, w - 1)], big)
    rv = np.where(right < w, disparity[rows, np.clip(right, 0, w - 1)], big)
    fill = np.minimum(lv, rv)
    fill = np.where(np.isfinite(fill), fill, disparity[known].min())
    return np.where(unknown, fill, disparity).astype(np.float32)


def normalize(disparity: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Map disparity to [0, 1] by its min and max (paper, Sec. 3.1).

    Returns ``(normalised, min, max)``. A flat map (:func:`photo3d.depth.checks.is_flat`:
    all values within 5 % of the largest, the map :func:`~photo3d.depth.checks.check_depth`
    warns about) gives all zeros: stretching its last digits to the full range would
    turn rounding noise into relief.

    Example:
        >>> n, lo, hi = normalize(np.array([[2.0, 4.0]], np.float32))
        >>> n.tolist(), lo, hi
        ([[0.0, 1.0]], 2.0, 4.0)
        >>> normalize(np.array([[1.0, 1.0000001]], np.float32))[0].tolist()
        [[0.0, 0.0]]
    """
    lo, hi = float(disparity.min()), float(disparity.max())
    if is_flat(disparity):
        return np.zeros_like(disparity, dtype=np.float32), lo, hi
    return ((disparity - lo) / (hi - lo)).astype(np.float32), lo, hi


def _resize_nearest(array: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    h, w = shape
    ys = ((np.arange(h) + 0.5) * array.shape[0] / h).astype(int)
    xs = ((np.arange(w) + 0.5) * array.shape[1] / w).astype(int)
    return array[np.clip(ys, 0, array.shape[0] - 1)][:, np.clip(xs, 0, array.shape[1] - 1)]
