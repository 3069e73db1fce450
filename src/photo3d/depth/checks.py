"""Plausibility checks of a depth map before it becomes a 3D photo.

Two mistakes are common and silent: a depth map given as disparity (or the other
way round), which turns the scene inside out, and a map with almost no range, which
gives a flat 3D photo. :func:`check_depth` returns human-readable warnings for both;
it never raises and never changes the map.

"Flat" is defined once, here (:func:`is_flat`), and the pipeline agrees: a map whose
values all lie within :data:`FLAT_RANGE` of its largest is made flat
(:func:`photo3d.depth.normalize.normalize` gives zeros) instead of having its last
digits stretched to the full depth range, where they would become relief made of
noise (a map of 1.0 and 1.0000001 turned into 3.5 million LDI pixels).

The inversion heuristic ("the ground is near"): in most photos the bottom of the
picture (ground, table, the subject's body) is nearer than the top (sky, walls,
ceiling far away, background behind a head). Per column, the median disparity of the
top 10 % of rows is compared with that of the bottom 10 %; if the top is nearer by
more than 2 % of the map's range in at least two thirds of the columns, the map
probably holds depth where disparity was expected (or vice versa).

Limits: it is a prior, not a proof. It misfires on photos taken looking down at a
surface tilted towards the top (a table from above, a wall seen from its foot, a
ceiling), on pictures upside down, and says nothing when top and bottom are at the
same distance (a face filling the frame, a flat wall) or when only part of the
columns show the ground. It cannot detect a map that belongs to another image.
"""

from __future__ import annotations

import numpy as np

from photo3d.errors import InputError

INVERTED_COLUMNS = 2.0 / 3.0
"""Fraction of columns whose top must be nearer than their bottom to warn."""

FLAT_RANGE = 0.05
"""A disparity map whose relative range (:func:`depth_range`) is below this is flat."""


def depth_range(disparity: np.ndarray) -> float:
    """Relative range ``(max - min) / max`` of a disparity map (finite values).

    The whole range, not percentiles: a small object in front of a wall is relief,
    however few its pixels.

    Args:
        disparity: ``(H, W)`` disparity (>= 0, larger = nearer), any scale.

    Returns:
        A number in [0, 1]; 0 for a constant (or all-zero) map.

    Example:
        >>> round(depth_range(np.linspace(1.0, 2.0, 101).reshape(1, -1)), 3)
        0.5
    """
    finite = np.asarray(disparity, np.float64)
    finite = finite[np.isfinite(finite)]
    if finite.size == 0:
        return 0.0
    lo, hi = float(finite.min()), float(finite.max())
    return (hi - lo) / hi if hi > 0 else 0.0


def is_flat(disparity: np.ndarray) -> bool:
    """Whether photo3d treats ``disparity`` as flat (:func:`depth_range` below
    :data:`FLAT_RANGE`): :func:`check_depth` warns, and
    :func:`photo3d.depth.normalize.normalize` makes it flat everywhere.

    Args:
        disparity: ``(H, W)`` disparity (>= 0, larger = nearer), any scale.

    Example:
        >>> is_flat(np.array([[1.0, 1.0000001]])), is_flat(np.array([[1.0, 2.0]]))
        (True, False)
    """
    return depth_range(disparity) < FLAT_RANGE


def inverted_columns(disparity: np.ndarray) -> float:
    """Fraction of columns whose top 10 % of rows is nearer than their bottom 10 %.

    "Nearer" means a median disparity larger by more than 2 % of the map's
    1st-99th percentile range.

    Args:
        disparity: ``(H, W)`` disparity (larger = nearer).

    Returns:
        A fraction in [0, 1]; near 0 for a typical photo, near 1 for a typical
        photo whose map is inverted.

    Example:
        >>> ground = np.tile(np.linspace(1.0, 5.0, 50)[:, None], (1, 40))  # bottom near
        >>> inverted_columns(ground), inverted_columns(1.0 / ground)
        (0.0, 1.0)
    """
    d = np.asarray(disparity, np.float64)
    band = max(1, d.shape[0] // 10)
    lo, hi = np.nanpercentile(d, [1, 99])
    margin = 0.02 * (hi - lo)
    top = np.nanmedian(d[:band], axis=0)
    bottom = np.nanmedian(d[-band:], axis=0)
    return float(np.mean(top > bottom + margin))


def check_depth(
    disparity: np.ndarray, image: np.ndarray | None = None, *, kind: str = "disparity"
) -> list[str]:
    """Warnings about a disparity map that looks inverted or flat.

    Args:
        disparity: ``(H, W)`` disparity as the pipeline will use it (larger =
            nearer; i.e. already converted from depth when ``kind="depth"``).
        image: ``(H, W, 3)`` the photo, only used to check the shape (optional).
        kind: what the user said the map holds (``"disparity"`` or ``"depth"``);
            it chooses the advice in the inversion warning.

    Returns:
        A list of one-line warnings, empty when nothing looks wrong.

    Raises:
        InputError: ``disparity`` is not 2-D or does not match ``image``.

    Example:
        >>> ground = np.tile(np.linspace(1.0, 5.0, 50)[:, None], (1, 40))
        >>> check_depth(ground)
        []
        >>> check_depth(1.0 / ground)[0][:46]
        'depth looks inverted (near is dark): pass --de'
        >>> check_depth(np.full((50, 40), 3.0))
        ['depth has almost no range: the 3D photo will look flat']
    """
    d = np.asarray(disparity)
    if d.ndim != 2:
        raise InputError(f"disparity has shape {d.shape}; expected (H, W)")
    if image is not None and np.shape(image)[:2] != d.shape:
        raise InputError(f"disparity has shape {d.shape} but image is {np.shape(image)}")
    notes = []
    if is_flat(d):
        notes.append("depth has almost no range: the 3D photo will look flat")
        return notes  # a flat map has no reliable orientation either
    share = inverted_columns(d)
    if share >= INVERTED_COLUMNS:
        fix, looks = ("depth", "near is dark") if kind == "disparity" else (
            "disparity", "near is bright")
        notes.append(
            f"depth looks inverted ({looks}): pass --depth-kind {fix} "
            f"(the top of the picture is nearer than the bottom in {share:.0%} of columns)"
        )
    return notes
