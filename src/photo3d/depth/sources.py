"""One entry point for every depth source: file, stereo pair, network, embedded map.

:func:`resolve_depth` turns what the user gave (``--depth FILE``, ``--right IMAGE``,
``--depth-model NAME``, or nothing: the photo's own embedded depth map) into a
:class:`DepthEstimate` that :func:`photo3d.make` accepts as ``depth=estimate.depth``
with ``depth_kind=estimate.kind``, plus a one-line description of the source and
plausibility warnings (:func:`photo3d.depth.checks.check_depth`).
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

from photo3d.depth.checks import check_depth
from photo3d.depth.normalize import DepthInput, match_shape, prepare_depth
from photo3d.errors import InputError
from photo3d.io.depth import read_depth
from photo3d.io.images import decoded_shape, read_image, to_float_image

PathLike = str | os.PathLike[str]


@dataclass(frozen=True, eq=False)
class DepthEstimate:
    """A depth map ready for the pipeline, with where it came from.

    Attributes:
        depth: ``(H, W) float32`` at the image size (a map of another size with the
            same aspect ratio is resampled here, nearest neighbour, with one
            warning; a map of the photo file's size, silently, when the photo was
            decoded reduced for a working size). Unknown values
            (NaN, inf, negative) may remain; the pipeline fills them.
        kind: ``"disparity"`` (larger = nearer) or ``"depth"`` (camera z).
        source: one line for humans, e.g. ``"embedded GDepth depth map (range
            inverse, near 0.3, far 4.2)"``.
        warnings: one-line warnings (doubtful pairs, inverted or flat maps, ...).
        image: ``(H, W, 3) float32`` a better photo than the file's primary image
            when the source carries one (the unblurred original of a Google
            lens-blur JPEG), else None.
        photo: ``(H, W, 3) float32`` the photo as :func:`resolve_depth` decoded it
            (None when built by hand), so that ``make`` decodes it once.
        prepared: ``depth`` as the pipeline takes it (:func:`prepare_depth`, for
            ``photo``'s size and ``kind``), so that ``make`` prepares it once.
    """

    depth: np.ndarray
    kind: str
    source: str
    warnings: tuple[str, ...] = ()
    image: np.ndarray | None = None
    photo: np.ndarray | None = None
    prepared: DepthInput | None = None


UNKNOWN_WARNING = 0.5
"""Warn when more than this fraction of the depth map is unknown."""


def read_photo(image: np.ndarray | PathLike, *, working_size: int | None = None
               ) -> np.ndarray:
    """A photo path (JPEG/PNG/TIFF/WebP, or HEIF/HEIC with pillow-heif, told apart by
    content, not extension: :func:`~photo3d.depth.heif.is_heif`) or array ->
    ``(H, W, 3) float32`` in [0, 1].

    The one photo reader of :func:`photo3d.make`, ``photo3d make`` and ``photo3d
    batch`` (:func:`photo3d.load` reloads a saved 3D photo, not a photo).

    Args:
        image: the photo file or an array (:func:`~photo3d.io.images.to_float_image`).
        working_size: the longer side the photo will be resized to (``Config.size``):
            a file more than ``KEEP`` (2) times larger is decoded at about ``KEEP``
            times that size (:func:`~photo3d.io.images.read_image`); None, an array
            or a HEIF file: whole.

    Example:
        >>> read_photo(np.zeros((8, 8), np.uint8)).shape
        (8, 8, 3)
    """
    if isinstance(image, str | os.PathLike):
        from photo3d.depth.heif import is_heif, read_heif_image

        if is_heif(image):  # by content: a JPEG named .heic is a JPEG
            return read_heif_image(image)
        return read_image(image, working_size=working_size)
    return to_float_image(image)


def describe_depth(depth: np.ndarray | PathLike, kind: str) -> str:
    """One line naming a depth map given as a file or an array (a
    :attr:`DepthEstimate.source`).

    Example:
        >>> describe_depth("d.png", "disparity"), describe_depth(np.ones((2, 2)), "depth")
        ('depth file d.png (disparity)', 'depth array (depth)')
    """
    if isinstance(depth, str | os.PathLike):
        return f"depth file {depth} ({kind})"
    return f"depth array ({kind})"


def resolve_depth(
    image: np.ndarray | PathLike,
    *,
    depth: np.ndarray | PathLike | None = None,
    right: np.ndarray | PathLike | None = None,
    depth_model: str | PathLike | None = None,
    kind: str | None = None,
    fallback_model: str | PathLike | None = "default",
    download_bar=None,
    working_size: int | None = None,
) -> DepthEstimate:
    """Get the depth for a photo from whichever source was given.

    Exactly one of ``depth``, ``right`` and ``depth_model`` may be given; with none,
    the depth map embedded in the image file (Google GDepth / Dynamic Depth JPEG,
    HEIF depth image) is used, and a photo without one gets its depth from
    ``fallback_model``.

    Args:
        image: the photo, a path or an ``(H, W, 3)`` array (embedded depth needs a path).
        depth: a depth file (:func:`photo3d.io.depth.read_depth`) or ``(H, W)`` array.
        right: the right view of a rectified stereo pair whose left view is ``image``
            (:func:`photo3d.depth.stereo.stereo_disparity`).
        depth_model: a monocular network (:func:`photo3d.depth.models.estimate_depth`).
        kind: ``"disparity"`` or ``"depth"``. Default: ``"disparity"`` for ``depth``,
            the model's own kind for ``depth_model`` (given, it overrides it);
            ignored for stereo (always disparity) and embedded maps (decoded exactly).
        fallback_model: the monocular model for a photo with no source and no
            embedded map: ``"default"`` (:func:`photo3d.depth.fetch.default_depth_model`,
            Depth Anything V2 Small), another model, or None (refuse such photos).
        download_bar: a ``tqdm`` class showing the download of a hub model that is
            not cached yet (default: nothing shown).
        working_size: the longer side the photo will be resized to: a much larger
            photo (and a depth file of its size) is decoded reduced
            (:func:`read_photo`, :func:`~photo3d.io.depth.read_depth`).

    Returns:
        :class:`DepthEstimate`.

    Raises:
        InputError: several sources given, none given, ``depth_model`` neither an
            existing local model nor a valid hub name, none embedded and the fallback
            model not usable (missing extra, offline, an invalid name), or any error
            of the chosen source.

    Example:
        >>> est = resolve_depth(np.zeros((8, 8, 3)), depth=np.ones((8, 8)))
        >>> est.kind, est.source
        ('disparity', 'depth array (disparity)')
        >>> est.warnings
        ('depth has almost no range: the 3D photo will look flat',)
    """
    given = [n for n, v in (("depth", depth), ("right", right), ("depth_model", depth_model))
             if v is not None]
    if len(given) > 1:
        raise InputError(f"give only one depth source, got {' and '.join(given)} "
                         "(--depth, --right and --depth-model exclude each other)")
    if kind not in (None, "disparity", "depth"):
        raise InputError(f"depth kind must be 'disparity' or 'depth', got {kind!r}")
    if depth_model is not None:
        from photo3d.depth.fetch import check_model_name

        check_model_name(depth_model)  # a missing folder or a bad hub name: at once
    photo = read_photo(image, working_size=working_size)
    notes: list[str] = []
    better_image = None
    if depth is not None:
        kind = kind or "disparity"
        raw = (read_depth(depth, working_size=working_size)
               if isinstance(depth, str | os.PathLike) else np.asarray(depth, np.float32))
        source = describe_depth(depth, kind)
    elif right is not None:
        from photo3d.depth.stereo import stereo_disparity

        result = stereo_disparity(photo, read_photo(right, working_size=working_size))
        raw, kind = result.disparity, "disparity"
        notes += result.warnings
        source = (f"stereo pair (SGBM, {result.valid.mean():.0%} of pixels matched, "
                  f"disparities up to {result.max_disparity} px)")
    elif depth_model is not None:
        raw, kind, source, found = _model(photo, depth_model, kind, download_bar)
        notes += found
    else:
        embedded = _embedded(image, kind, photo.shape[:2])
        if embedded is not None:
            raw, kind, source, found, better_image = embedded
        else:
            raw, kind, source, found = _fallback(image, photo, fallback_model, kind,
                                                 download_bar)
        notes += found
    if raw.ndim == 2:  # resample once here, so that the pipeline does not warn again
        matched, note = match_shape(raw, photo.shape[:2])
        if decoded_shape(raw.shape, working_size) == photo.shape[:2]:
            note = ""  # a map of the file's size, for a photo decoded reduced
        raw = matched
        notes += [note] if note else []
    prepared, found = _checks(raw, photo, kind)
    return DepthEstimate(depth=raw.astype(np.float32), kind=kind, source=source,
                         warnings=tuple(notes + found), image=better_image, photo=photo,
                         prepared=prepared)


def _model(photo, model, kind, download_bar):
    """Depth from a monocular network, downloaded first if it is a hub model not cached."""
    from photo3d.depth.fetch import fetch_model
    from photo3d.depth.models import run_model

    fetch_model(model, bar=download_bar)
    out = run_model(photo, model, kind=kind)
    source = f"monocular depth model {model} ({out.kind}: {out.reason})"
    notes = []
    if out.reason.startswith("assumed"):
        notes.append(f"the model's output kind is unknown; {out.kind} assumed "
                     "(pass --depth-kind to change it)")
    return out.depth, out.kind, source, notes


def _fallback(image, photo, model, kind, download_bar):
    """Depth from the fallback model for a photo that came with none."""
    what = Path(image).name if isinstance(image, str | os.PathLike) else "an image array"
    ways = "pass --depth FILE, --right IMAGE or --depth-model NAME"
    if model is None:
        raise InputError(f"no depth given: {ways}; {what} has no embedded depth map")
    if model == "default":
        from photo3d.depth.fetch import default_depth_model

        model = default_depth_model()
    try:
        return _model(photo, model, kind, download_bar)
    except InputError as err:
        raise InputError(f"no depth for {what} (no embedded depth map) and no depth "
                         f"model to estimate it: {err}; {ways}") from err


def _embedded(image, kind, shape):
    """The embedded depth map of an image file, resized to the image size, or None."""
    if not isinstance(image, str | os.PathLike):
        return None
    from photo3d.depth.portrait import read_embedded_depth

    found = read_embedded_depth(image)
    if found is None:
        return None
    notes = list(found.warnings)
    if kind is not None and kind != found.kind:
        notes.append(f"--depth-kind {kind} ignored: the embedded map is decoded as {found.kind}")
    h, w = shape
    depth = found.depth
    if depth.shape != (h, w) and abs(depth.shape[1] / depth.shape[0] / (w / h) - 1) <= 0.01:
        depth = np.asarray(Image.fromarray(depth.astype(np.float32), "F").resize(
            (w, h), Image.Resampling.BILINEAR))
    return depth, found.kind, found.source, notes, found.image


def _checks(raw: np.ndarray, photo: np.ndarray, kind: str) -> tuple[DepthInput, list[str]]:
    """The prepared depth, and plausibility warnings plus any warning the conversion
    itself raised."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        prepared = prepare_depth(raw, photo.shape[:2], kind=kind)
    notes = [str(w.message) for w in caught]
    unknown = float(prepared.unknown.mean())
    if unknown > UNKNOWN_WARNING:
        notes.append(f"depth is unknown at {unknown:.0%} of the pixels (NaN, inf or out of "
                     "range): they are guessed from their row neighbours")
    return prepared, notes + check_depth(prepared.disparity, photo, kind=kind)
