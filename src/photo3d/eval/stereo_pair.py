"""Rectified stereo pairs with ground truth: Middlebury ``calib.txt`` and the sample.

Geometry (Middlebury): ``Z = baseline * f / (d + doffs)`` where ``d`` is the left
view's disparity in pixels and ``doffs = cx1 - cx0``. The right camera sits at
``+baseline`` along the left camera's x axis: camera-from-world translation
``(-baseline, 0, 0)``, with its own intrinsics ``cam1``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from photo3d.camera import Camera, Intrinsics
from photo3d.errors import InputError
from photo3d.io.bounded import read_bytes

MAX_CALIB_BYTES = 1 << 20
"""The largest ``calib.txt`` :func:`read_calib` reads (Middlebury's are under 1 kB)."""


@dataclass(frozen=True)
class StereoPair:
    """A rectified pair with ground-truth left disparity.

    Attributes:
        left, right: ``(H, W, 3) float32`` in [0, 1].
        disparity: ``(H, W) float32`` left disparity in pixels, NaN where unknown.
        left_camera, right_camera: intrinsics (and pose) of the two views.
        baseline: in the calibration's units (Middlebury: mm).
        doffs: ``cx1 - cx0`` in pixels.
    """

    left: np.ndarray
    right: np.ndarray
    disparity: np.ndarray
    left_camera: Intrinsics
    right_camera: Camera
    baseline: float
    doffs: float

    def depth(self) -> np.ndarray:
        """``(H, W) float32`` metric depth of the left view (NaN where unknown)."""
        return (self.baseline * self.left_camera.fx / (self.disparity + self.doffs)).astype(
            np.float32)


def read_calib(path: str | Path) -> dict:
    """Parse a Middlebury ``calib.txt`` (``cam0=[f 0 cx; 0 f cy; 0 0 1]``, ``doffs=``, ...).

    Raises:
        InputError: one line; the file is missing, unreadable, not UTF-8 or larger
            than :data:`MAX_CALIB_BYTES`, a camera matrix is not 3x3 numbers, a
            required key is missing, or a value is out of range (focal lengths and
            baseline > 0, all finite, width and height 1 to 65536).

    Example:
        >>> import tempfile, pathlib
        >>> p = pathlib.Path(tempfile.mkdtemp()) / "calib.txt"
        >>> _ = p.write_text("cam0=[100 0 50; 0 100 40; 0 0 1]\\n"
        ...                  "cam1=[100 0 60; 0 100 40; 0 0 1]\\ndoffs=10\\nbaseline=200\\n"
        ...                  "width=100\\nheight=80\\nndisp=64\\n")
        >>> c = read_calib(p)
        >>> float(c["cam1"][0, 2]), c["baseline"], c["width"]
        (60.0, 200.0, 100)
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"calibration file not found: {path}")
    data = read_bytes(path, max_bytes=MAX_CALIB_BYTES, what=f"calibration {path}")
    try:
        text = data.decode()
    except UnicodeDecodeError as err:
        raise InputError(f"cannot read calibration {path}: {err}") from None
    out: dict = {}
    for line in text.splitlines():
        if "=" not in line:
            continue
        key, value = (v.strip() for v in line.split("=", 1))
        if key in ("cam0", "cam1"):
            try:
                nums = [float(v) for v in re.split(r"[\s;,\[\]]+", value) if v]
            except ValueError:
                nums = []
            if len(nums) != 9:
                raise InputError(f"{path}: {key} must hold a 3x3 matrix of numbers "
                                 f"([f 0 cx; 0 f cy; 0 0 1]), got {value[:60]!r}")
            out[key] = np.array(nums).reshape(3, 3)
        else:
            try:
                out[key] = int(value) if key in ("width", "height", "ndisp") else float(value)
            except ValueError:
                continue
    missing = {"cam0", "cam1", "baseline", "width", "height"} - out.keys()
    if missing:
        raise InputError(f"{path}: missing {', '.join(sorted(missing))}")
    out.setdefault("doffs", float(out["cam1"][0, 2] - out["cam0"][0, 2]))
    _check_calib(out, path)
    return out


def _check_calib(calib: dict, path: Path) -> None:
    """Refuse values that give no usable geometry: a focal length or baseline that is
    not a positive finite number, a non-finite matrix or doffs, a size out of range."""
    for key in ("cam0", "cam1"):
        k = calib[key]
        if not (np.isfinite(k).all() and k[0, 0] > 0 and k[1, 1] > 0):
            raise InputError(f"{path}: {key} needs finite numbers and positive focal "
                             f"lengths, got f = {k[0, 0]:g}, {k[1, 1]:g}")
    if not (np.isfinite(calib["baseline"]) and calib["baseline"] > 0):
        raise InputError(f"{path}: baseline must be a positive number, "
                         f"got {calib['baseline']:g}")
    if not np.isfinite(calib["doffs"]):
        raise InputError(f"{path}: doffs must be a finite number, got {calib['doffs']:g}")
    for key in ("width", "height"):
        if not 1 <= calib[key] <= 65536:
            raise InputError(f"{path}: {key} must be between 1 and 65536, got {calib[key]}")


def _cameras(k0: np.ndarray, k1: np.ndarray, width: int, height: int, baseline: float):
    left = Intrinsics(k0[0, 0], k0[1, 1], k0[0, 2], k0[1, 2], width, height)
    right_k = Intrinsics(k1[0, 0], k1[1, 1], k1[0, 2], k1[1, 2], width, height)
    return left, Camera.translated(right_k, (baseline, 0.0, 0.0))


def load_pair(left: str | Path, right: str | Path, disparity: str | Path,
              calib: str | Path) -> StereoPair:
    """Load a Middlebury-style pair: images, left disparity (PFM with inf = unknown,
    or 8/16-bit PNG with 0 = unknown) and ``calib.txt``."""
    from photo3d.io.depth import read_depth
    from photo3d.io.images import read_image

    c = read_calib(calib)
    left_img, right_img = read_image(left), read_image(right)
    disp = read_depth(disparity).astype(np.float32)
    if Path(disparity).suffix.lower() == ".png":
        disp[disp == 0] = np.nan
    disp[~np.isfinite(disp)] = np.nan
    shape = (c["height"], c["width"])
    for name, a in (("left image", left_img), ("right image", right_img), ("disparity", disp)):
        if a.shape[:2] != shape:
            raise InputError(f"{name} is {a.shape[1]}x{a.shape[0]} but calib says "
                             f"{shape[1]}x{shape[0]}")
    lk, rc = _cameras(c["cam0"], c["cam1"], c["width"], c["height"], c["baseline"])
    return StereoPair(left_img, right_img, disp, lk, rc, float(c["baseline"]), float(c["doffs"]))


def motorcycle_pair() -> StereoPair:
    """The Middlebury 2014 *Motorcycle* pair shipped in scikit-image, calibrated."""
    from photo3d.sample import motorcycle

    s = motorcycle()
    h, w = s.disparity.shape
    k0 = np.array([[s.focal, 0, s.cx], [0, s.focal, s.cy], [0, 0, 1]])
    k1 = k0.copy()
    k1[0, 2] += s.doffs
    disp = np.where(np.isfinite(s.disparity), s.disparity, np.nan).astype(np.float32)
    lk, rc = _cameras(k0, k1, w, h, s.baseline)
    return StereoPair(s.left, s.right, disp, lk, rc, float(s.baseline), float(s.doffs))
