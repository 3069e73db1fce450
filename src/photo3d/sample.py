"""The bundled real sample: the Middlebury 2014 motorcycle stereo pair.

The pair ships inside scikit-image (extra ``photo3d[sample]``), so it works offline.
It is a quarter-resolution rectified pair with ground-truth disparity and the
calibration scikit-image documents for it.

Example:
    >>> sample = motorcycle()
    >>> sample.left.shape, sample.disparity.shape
    ((500, 741, 3), (500, 741))
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from photo3d.errors import require
from photo3d.io.images import to_float_image


@dataclass(frozen=True, eq=False)
class StereoSample:
    """A rectified stereo pair with ground-truth disparity and calibration.

    Middlebury convention: a left pixel ``(y, x)`` with disparity ``d`` appears at
    ``(y, x - d)`` in the right view, and its depth is
    ``z = baseline * focal / (d + doffs)`` (in mm, like ``baseline``).

    Example:
        >>> import numpy as np
        >>> image = np.zeros((8, 8, 3), np.float32)
        >>> sample = StereoSample(image, image, np.full((8, 8), 10.0, np.float32))
        >>> sample.focal, sample.baseline
        (994.978, 193.001)
    """

    left: np.ndarray
    """``(H, W, 3) float32`` in [0, 1], the left (reference) view."""
    right: np.ndarray
    """``(H, W, 3) float32`` in [0, 1], the right view."""
    disparity: np.ndarray
    """``(H, W) float32`` in pixels of the left view, ``+inf`` where unknown."""
    focal: float = 994.978
    """Focal length in pixels (both views)."""
    cx: float = 311.193
    """Principal point x of the left view, in pixels."""
    cy: float = 254.877
    """Principal point y, in pixels (both views)."""
    doffs: float = 31.086
    """Principal point x of the right view minus that of the left, in pixels."""
    baseline: float = 193.001
    """Distance between the camera centres, in mm."""


def motorcycle() -> StereoSample:
    """Load the Middlebury 2014 motorcycle pair bundled with scikit-image.

    Images are down-sampled by 4 from the benchmark; the calibration fields are the
    values documented in ``skimage.data.stereo_motorcycle`` for that size.

    Returns:
        A :class:`StereoSample` with ``left``/``right`` ``(500, 741, 3) float32`` in
        [0, 1] and ``disparity`` ``(500, 741) float32`` exactly as scikit-image gives
        it (values about 7..60 px, ``+inf`` where the ground truth is unknown; the
        scikit-image docstring says NaN, but the data holds ``+inf``).

    Raises:
        MissingExtra: scikit-image is not installed (extra ``sample``).

    Example:
        >>> import numpy as np
        >>> sample = motorcycle()
        >>> sample.left.dtype, bool(np.isposinf(sample.disparity).any())
        (dtype('float32'), True)
    """
    skimage = require("skimage", "sample", purpose="the bundled sample",
                      package="scikit-image")
    files = _bundled_files(skimage)
    if files is not None:
        left, right, disparity = files
    else:  # not shipped as files in this version: scikit-image's own loader
        data = require("skimage.data", "sample", purpose="the bundled sample",
                       package="scikit-image")
        left, right, disparity = data.stereo_motorcycle()
    return StereoSample(
        left=to_float_image(left),
        right=to_float_image(right),
        disparity=np.asarray(disparity, dtype=np.float32),
    )


def _bundled_files(skimage) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The pair read straight from the files scikit-image ships in ``skimage/data``
    (what ``skimage.data.stereo_motorcycle`` reads): the same arrays, without
    importing ``skimage.io`` and what it pulls in (about 0.2 s). None if the files
    are not there."""
    from PIL import Image

    folder = Path(skimage.__file__).parent / "data"
    paths = [folder / name for name in ("motorcycle_left.png", "motorcycle_right.png",
                                        "motorcycle_disp.npz")]
    if not all(path.is_file() for path in paths):
        return None
    images = []
    for path in paths[:2]:
        with Image.open(path) as image:
            images.append(np.array(image))
    with np.load(paths[2]) as data:
        disparity = data["arr_0"]
    return images[0], images[1], disparity
