"""Disparity from a rectified stereo pair: semi-global matching with OpenCV.

The left image is the reference view (the photo that becomes the 3D photo); a left
pixel ``(y, x)`` with disparity ``d`` appears at ``(y, x - d)`` in the right view
(Middlebury convention, see :class:`photo3d.sample.StereoSample`). Disparity is in
pixels of the left view: larger = nearer, which is what ``kind="disparity"`` means
everywhere in photo3d.

Steps of :func:`stereo_disparity`:

1. :func:`check_pair`: ORB feature matches must lie on the same rows (rectified)
   and mostly have ``x_left > x_right`` (not swapped); they also give the search
   range (both ends, with margins) when ``max_disparity`` is not given: a range
   that starts at 0 when the scene's nearest far point is at 15 px lets a few
   mismatches reach 0, which stretches the min-max normalised disparity.
2. OpenCV ``StereoSGBM`` (3-way) on both views: the right view's disparity is
   computed by flipping both images horizontally and swapping them.
3. Left-right consistency: a left disparity is valid only if the right view's
   disparity at ``x - d`` agrees within 1 px (removes occlusions and mismatches)
   and it is not at an end of the search range. A pair of which fewer than
   :data:`MIN_MATCHED` of the pixels pass is refused: it is not a stereo pair of one
   scene (a depth map given as the right view, another photo).
4. Invalid pixels are filled with the farther of their row neighbours
   (:func:`photo3d.depth.normalize.fill_unknown`), then a joint weighted median
   filter guided by the left image (``cv2.ximgproc.weightedMedianFilter``) aligns
   depth edges with image edges.

Needs ``opencv-contrib-python-headless`` (extra ``photo3d[stereo]``).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from photo3d.depth.normalize import fill_unknown
from photo3d.errors import InputError, MissingExtra, install_hint, require
from photo3d.io.images import to_float_image

WORK_SIZE = 1600
"""Longer side, in pixels, at which pairs are matched (larger pairs are reduced)."""

ROW_TOLERANCE = 1.5
"""Largest vertical offset, in pixels at <= 1024 px, of a match in a rectified pair."""

MIN_SIDE = 32
"""Shortest side, in pixels, of a pair that can be matched, also once reduced for
feature matching (long side 1024 px) and for SGBM (long side :data:`WORK_SIZE`):
SGBM needs more columns than its 16 disparities plus its block."""

MIN_MATCHED = 0.1
"""Smallest fraction of the left view's pixels that must pass the left-right check
(the Middlebury motorcycle: 74 %; the photo with its own depth map as the right view:
2 %)."""

_REFERENCE_SIDE = 741  # parameters below were tuned on the 741 px Middlebury pair


@dataclass(frozen=True)
class PairCheck:
    """What feature matches say about a stereo pair (see :func:`check_pair`).

    Attributes:
        matches: number of ORB matches that passed the ratio test.
        row_offset: median ``y_left - y_right`` of the matches, in pixels of the input.
        same_row: fraction of matches within :data:`ROW_TOLERANCE` of that offset.
        swapped: fraction of same-row matches (with ``|dx| > 1``) having ``x_left < x_right``.
        max_disparity: 99th percentile of ``x_left - x_right`` over same-row matches,
            in pixels of the input (``nan`` without matches).
        min_disparity: 1st percentile of the same (``nan`` without matches).
    """

    matches: int
    row_offset: float
    same_row: float
    swapped: float
    max_disparity: float
    min_disparity: float = math.nan

    @property
    def reliable(self) -> bool:
        """Enough matches (>= 20) to judge the pair."""
        return self.matches >= 20


@dataclass(frozen=True, eq=False)
class StereoResult:
    """Disparity of the left view of a stereo pair.

    Attributes:
        disparity: ``(H, W) float32`` in pixels of the left view, >= 0, every pixel
            filled (invalid ones from the background side) and edge-aware filtered.
        valid: ``(H, W) bool``, pixels whose matched disparity passed the left-right check.
        max_disparity: upper end of the search range, in pixels of the input.
        min_disparity: lower end of the search range, in pixels of the input.
        check: what the feature matches said (:class:`PairCheck`).
        warnings: human-readable notes (e.g. the pair could not be verified).
    """

    disparity: np.ndarray
    valid: np.ndarray
    max_disparity: int
    min_disparity: int
    check: PairCheck
    warnings: tuple[str, ...] = ()


def _cv2(feature: str = "stereo matching"):
    """Import OpenCV with the contrib modules or explain how to install them."""
    cv2 = require("cv2", "stereo", purpose=feature, package="OpenCV")
    if not hasattr(cv2, "ximgproc"):
        raise MissingExtra(feature, "OpenCV's contrib modules", "stereo", module="cv2.ximgproc",
                           hint="pip uninstall opencv-python-headless and "
                                f"{install_hint('stereo')} (opencv-contrib-python-headless)")
    return cv2


def _to_uint8(image: np.ndarray) -> np.ndarray:
    return np.round(to_float_image(image) * 255.0).astype(np.uint8)


def check_pair(left: np.ndarray, right: np.ndarray) -> PairCheck:
    """Match ORB features between the views and summarise their geometry.

    Args:
        left, right: ``(H, W, 3)`` images of the same shape (any dtype
            :func:`photo3d.io.images.to_float_image` accepts).

    Returns:
        :class:`PairCheck`; offsets and disparities in pixels of the input.

    Example:
        >>> rng = np.random.default_rng(0)
        >>> scene = rng.random((120, 200)).repeat(2, 0).repeat(2, 1)
        >>> left, right = scene[:, 10:210], scene[:, 20:220]   # disparity 10 px
        >>> c = check_pair(left, right)
        >>> c.reliable, round(c.row_offset), c.swapped, 9 <= c.max_disparity <= 12
        (True, 0, 0.0, True)
    """
    cv2 = _cv2()
    a, b = _to_uint8(left), _to_uint8(right)
    scale = min(1.0, 1024.0 / max(a.shape[:2]))
    grey = []
    for im in (a, b):
        g = cv2.cvtColor(im, cv2.COLOR_RGB2GRAY)
        if scale < 1.0:
            g = cv2.resize(g, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
        grey.append(g)
    orb = cv2.ORB_create(nfeatures=3000)
    kl, dl = orb.detectAndCompute(grey[0], None)
    kr, dr = orb.detectAndCompute(grey[1], None)
    good = []
    if dl is not None and dr is not None and len(kl) >= 2 and len(kr) >= 2:
        pairs = cv2.BFMatcher(cv2.NORM_HAMMING).knnMatch(dl, dr, k=2)
        good = [p[0] for p in pairs if len(p) == 2 and p[0].distance < 0.75 * p[1].distance]
    if not good:
        return PairCheck(0, 0.0, 0.0, 0.0, math.nan, math.nan)
    pl = np.array([kl[m.queryIdx].pt for m in good])
    pr = np.array([kr[m.trainIdx].pt for m in good])
    dx, dy = pl[:, 0] - pr[:, 0], pl[:, 1] - pr[:, 1]
    offset = float(np.median(dy))
    row = np.abs(dy - offset) <= ROW_TOLERANCE
    moving = row & (np.abs(dx) > 1.0)
    swapped = float((dx[moving] < 0).mean()) if moving.any() else 0.0
    lo, hi = np.percentile(dx[row], [1, 99]) / scale if row.any() else (math.nan, math.nan)
    return PairCheck(len(good), offset / scale, float(row.mean()), swapped, float(hi), float(lo))


def _check_size(height: int, width: int) -> None:
    """Refuse a pair whose short side is below :data:`MIN_SIDE` pixels, as given or
    once its long side is reduced to 1024 px (features) or :data:`WORK_SIZE` (SGBM).

    Example:
        >>> _check_size(10, 20000)  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        photo3d.errors.InputError: the stereo pair is 20000x10 pixels: too small or too ...
    """
    reduced = min(1.0, min(WORK_SIZE, 1024) / max(height, width))
    if min(height, width) * reduced < MIN_SIDE:
        ratio = min(WORK_SIZE, 1024) // MIN_SIDE
        raise InputError(f"the stereo pair is {width}x{height} pixels: too small or too "
                         f"elongated to match (the short side must be at least {MIN_SIDE} "
                         f"px, and at least 1/{ratio} of the long side)")


def _refuse_unusable(check: PairCheck, side: int) -> None:
    """Raise :class:`InputError` for pairs that are not rectified or are swapped."""
    tolerance = ROW_TOLERANCE * max(1.0, side / 1024.0)  # offsets are in input pixels
    if not check.reliable:
        return
    if check.same_row < 0.6:
        raise InputError(
            f"the stereo pair is not rectified (or not a pair): only {check.same_row:.0%} of "
            f"{check.matches} feature matches lie on the same row; rectify it first "
            "(e.g. OpenCV stereoRectify) or pass a depth map"
        )
    if abs(check.row_offset) > tolerance:
        raise InputError(
            f"the stereo pair is not rectified: the right image is shifted vertically by "
            f"{-check.row_offset:.1f} px; rectify it first or pass a depth map"
        )
    if check.swapped > 0.7:
        raise InputError(
            f"left and right seem swapped: try swapping them ({check.swapped:.0%} of feature "
            "matches have x_left < x_right)"
        )


def _search_range(check: PairCheck, width: int, given: float | None) -> tuple[int, int]:
    """``(lowest disparity, number of disparities)`` to search, in working pixels.

    The number is a multiple of 16 (OpenCV's rule). Without ``given``, the feature
    matches set both ends with a margin (0.9 x 1st percentile - 8 px, 1.1 x 99th
    percentile + 8 px); without reliable matches the range is ``0 .. width / 8``.
    """
    low = 0
    if given is not None:
        high = float(given)
    elif check.reliable and np.isfinite(check.max_disparity):
        low = max(0, math.floor(0.9 * check.min_disparity - 8.0))
        high = 1.1 * max(check.max_disparity, 0.0) + 8.0
    else:
        high = width / 8.0
    count = max(16, math.ceil((high - low) / 16.0) * 16)
    return low, int(min(count, max(16, (width // 2) // 16 * 16)))


def _sgbm(cv2, left: np.ndarray, right: np.ndarray, low: int, ndisp: int) -> np.ndarray:
    """Left-view disparity in pixels (float32), below ``low`` where SGBM found none."""
    side = max(left.shape[:2])
    block = 3 if side <= 1000 else 5
    matcher = cv2.StereoSGBM_create(
        minDisparity=low, numDisparities=ndisp, blockSize=block,
        P1=8 * 3 * block**2, P2=32 * 3 * block**2, disp12MaxDiff=-1, uniquenessRatio=10,
        speckleWindowSize=max(50, round(100 * (side / _REFERENCE_SIDE) ** 2)), speckleRange=2,
        preFilterCap=63, mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY,
    )
    return matcher.compute(left, right).astype(np.float32) / 16.0


def stereo_disparity(
    left: np.ndarray, right: np.ndarray, *, max_disparity: int | None = None, check: bool = True
) -> StereoResult:
    """Disparity of the left view of a rectified stereo pair.

    Args:
        left: ``(H, W, 3)`` reference view (uint8, uint16 or float in [0, 1]).
        right: ``(H, W, 3)`` the other view, same shape, to the right of ``left``.
        max_disparity: largest disparity to search, in pixels of the input (the
            search then starts at 0); default from the feature matches (0.9 x their
            1st percentile - 8 px to 1.1 x their 99th percentile + 8 px), or
            ``0 .. W / 8`` when there are too few. Rounded up to a multiple of 16 at the
            working size (pairs larger than :data:`WORK_SIZE` are matched reduced).
        check: refuse pairs that feature matches show to be unrectified or swapped,
            and pairs that match almost nowhere (:data:`MIN_MATCHED`).

    Returns:
        :class:`StereoResult` at the input size.

    Raises:
        InputError: shapes differ, the pair is too small or too elongated
            (:data:`MIN_SIDE`), unrectified or swapped, (almost) nothing could be
            matched, or OpenCV (contrib) is not installed.

    Example:
        >>> rng = np.random.default_rng(0)
        >>> scene = rng.random((60, 100)).repeat(2, 0).repeat(2, 1)
        >>> res = stereo_disparity(scene[:, :160], scene[:, 12:172])
        >>> float(np.median(res.disparity)), res.disparity.shape
        (12.0, (120, 160))
    """
    a, b = _to_uint8(left), _to_uint8(right)
    if a.shape != b.shape:
        raise InputError(f"right image has shape {b.shape} but left image is {a.shape}")
    h, w = a.shape[:2]
    _check_size(h, w)
    cv2 = _cv2()
    pair = check_pair(a, b)
    notes = []
    if check:
        _refuse_unusable(pair, max(h, w))
        if not pair.reliable:
            notes.append(f"only {pair.matches} feature matches: could not verify that the "
                         "pair is rectified and in left-right order")
    scale = min(1.0, WORK_SIZE / max(h, w))
    if scale < 1.0:
        size = (round(w * scale), round(h * scale))
        a = cv2.resize(a, size, interpolation=cv2.INTER_AREA)
        b = cv2.resize(b, size, interpolation=cv2.INTER_AREA)
    given = None if max_disparity is None else max_disparity * scale
    scaled = dataclasses.replace(pair, max_disparity=pair.max_disparity * scale,
                                 min_disparity=pair.min_disparity * scale)
    low, ndisp = _search_range(scaled, a.shape[1], given)

    disp_l = _sgbm(cv2, a, b, low, ndisp)
    disp_r = _sgbm(cv2, b[:, ::-1].copy(), a[:, ::-1].copy(), low, ndisp)[:, ::-1]
    # A disparity at an end of the search range may really lie beyond it: not trusted
    # (except 0, the disparity of far-away points, when the range starts there).
    bottom = low + 0.5 if low > 0 else -0.5
    valid = _left_right_consistent(disp_l, disp_r, bottom, low + ndisp - 1.5)
    if not valid.any():
        raise InputError("stereo matching found no reliable disparity: are the images a "
                         "rectified stereo pair of the same scene?")
    if check and valid.mean() < MIN_MATCHED:
        raise InputError(f"the right view matches only {valid.mean():.1%} of the photo's "
                         f"pixels (at least {MIN_MATCHED:.0%} are needed): it is not the "
                         "right view of a rectified stereo pair of the same scene (a depth "
                         "map goes with --depth, not --right)")
    filled = fill_unknown(np.where(valid, disp_l, 0.0).astype(np.float32), ~valid)
    radius = max(2, round(7 * max(a.shape[:2]) / _REFERENCE_SIDE))
    smooth = cv2.ximgproc.weightedMedianFilter(a, filled, radius, sigma=25.5)
    if scale < 1.0:
        smooth = cv2.resize(smooth, (w, h), interpolation=cv2.INTER_NEAREST) / scale
        valid = cv2.resize(valid.astype(np.uint8), (w, h), interpolation=cv2.INTER_NEAREST) > 0
    return StereoResult(
        disparity=np.maximum(smooth, 0.0).astype(np.float32), valid=valid,
        max_disparity=round((low + ndisp) / scale), min_disparity=round(low / scale),
        check=pair, warnings=tuple(notes),
    )


def _left_right_consistent(disp_l: np.ndarray, disp_r: np.ndarray, low: float, high: float,
                           tol: float = 1.0) -> np.ndarray:
    """``(H, W) bool``: left disparity d at x lies strictly inside (low, high) and
    agrees within ``tol`` with the right view's disparity at x - d."""
    h, w = disp_l.shape
    x_r = np.round(np.arange(w)[None, :] - disp_l).astype(np.int64)
    inside = (disp_l > low) & (disp_l < high) & (x_r >= 0) & (x_r < w)
    back = disp_r[np.arange(h)[:, None], np.clip(x_r, 0, w - 1)]
    return inside & (back > low) & (np.abs(disp_l - back) <= tol)
