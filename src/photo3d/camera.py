"""Camera and depth conventions, written once.

Conventions used everywhere in photo3d:

* Images are ``(H, W, 3) float32`` in [0, 1]; pixel ``(row, col) = (y, x)``; the
  centre of pixel ``(y, x)`` is at image coordinates ``(x + 0.5, y + 0.5)``.
* Camera axes follow OpenCV: x right, y down, z forward. Intrinsics ``K`` are in
  pixels. The default camera of a ``W x H`` photo has ``fx = fy = max(H, W)`` and its
  principal point at the image centre ``(W / 2, H / 2)`` (as the authors' code).
* Poses are 4x4 camera-from-world matrices; the input view is the identity.
* Internally the algorithm works on *normalised disparity* in [0, 1] (paper, Sec. 3.1).
  Geometry depth follows the authors' code: ``z = 1 / max(scale * d + offset, floor)``
  with ``scale = 3, offset = 0, floor = 0.05`` by default, i.e. z in [1/3, 20].
  A metric input keeps metric units by choosing ``scale``/``offset`` so that the
  mapping reproduces the input's own 1/z (see :func:`DepthMapping.from_inverse_depth`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from photo3d.errors import InputError


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics in pixels for an image of ``width x height``.

    Example:
        >>> k = Intrinsics.default(640, 480)
        >>> k.fx, k.cx, k.cy
        (640.0, 320.0, 240.0)
    """

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int

    @classmethod
    def default(cls, width: int, height: int) -> Intrinsics:
        """The authors' camera: focal ``max(H, W)``, principal point at the centre."""
        f = float(max(width, height))
        return cls(f, f, width / 2.0, height / 2.0, int(width), int(height))

    @property
    def matrix(self) -> np.ndarray:
        """``(3, 3) float64`` calibration matrix K."""
        return np.array([[self.fx, 0, self.cx], [0, self.fy, self.cy], [0, 0, 1]], float)

    @property
    def fov(self) -> tuple[float, float]:
        """``(horizontal, vertical)`` field of view in radians."""
        return (
            2.0 * math.atan(self.width / (2.0 * self.fx)),
            2.0 * math.atan(self.height / (2.0 * self.fy)),
        )

    def scaled(self, width: int, height: int) -> Intrinsics:
        """The same camera for the image resized to ``width x height``.

        Example:
            >>> Intrinsics.default(100, 50).scaled(200, 100).fx
            200.0
        """
        sx, sy = width / self.width, height / self.height
        return Intrinsics(self.fx * sx, self.fy * sy, self.cx * sx, self.cy * sy, width, height)


@dataclass(frozen=True)
class DepthMapping:
    """Map normalised disparity ``d`` in [0, 1] to camera depth z.

    ``z = 1 / max(scale * d + offset, floor)``.

    Example:
        >>> m = DepthMapping()
        >>> float(m.depth(np.float32(1.0))), float(m.depth(np.float32(0.0)))
        (0.3333333432674408, 20.0)
    """

    scale: float = 3.0
    offset: float = 0.0
    floor: float = 0.05

    @classmethod
    def from_inverse_depth(cls, inv_min: float, inv_max: float) -> DepthMapping:
        """Mapping that restores a metric ``1/z`` range normalised to [0, 1]."""
        return cls(scale=float(inv_max - inv_min), offset=float(inv_min), floor=1e-12)

    def depth(self, disparity: np.ndarray) -> np.ndarray:
        """``disparity``: normalised, any shape -> depth z, same shape, float32."""
        inv = np.maximum(self.scale * np.asarray(disparity, np.float32) + self.offset, self.floor)
        return (1.0 / inv).astype(np.float32)


def unproject(x: np.ndarray, y: np.ndarray, z: np.ndarray, k: Intrinsics) -> np.ndarray:
    """Lattice positions to 3D points in camera coordinates.

    Args:
        x, y: ``(N,)`` integer lattice columns / rows (may lie outside the image
            for extrapolated border pixels); the point is the pixel centre.
        z: ``(N,)`` depth along the optical axis.
        k: intrinsics of the input view.

    Returns:
        ``(N, 3) float32`` points (OpenCV axes).

    Example:
        >>> k = Intrinsics.default(4, 4)
        >>> unproject(np.array([1]), np.array([1]), np.array([2.0]), k).tolist()
        [[-0.25, -0.25, 2.0]]
    """
    z = np.asarray(z, np.float32)
    px = (np.asarray(x, np.float32) + 0.5 - k.cx) / k.fx
    py = (np.asarray(y, np.float32) + 0.5 - k.cy) / k.fy
    return np.stack([px * z, py * z, z], axis=1).astype(np.float32)


def intrinsics_from_fov(width: int, height: int, vfov: float) -> Intrinsics:
    """Square-pixel intrinsics with vertical field of view ``vfov`` (radians).

    Example:
        >>> k = intrinsics_from_fov(200, 100, 2 * math.atan(0.5))
        >>> round(k.fx, 6), k.cx, k.cy
        (100.0, 100.0, 50.0)
    """
    f = height / (2.0 * math.tan(vfov / 2.0))
    return Intrinsics(f, f, width / 2.0, height / 2.0, int(width), int(height))


@dataclass(frozen=True)
class Camera:
    """A camera: intrinsics (which also fix the output size) and a pose.

    Attributes:
        intrinsics: pinhole intrinsics in pixels.
        pose: ``(4, 4) float64`` camera-from-world matrix (the input view is the
            identity; world = the input camera's OpenCV frame).

    Example:
        >>> cam = Camera.translated(Intrinsics.default(64, 48), (0.1, 0.0, 0.0))
        >>> cam.position.tolist()
        [0.1, 0.0, 0.0]
    """

    intrinsics: Intrinsics
    pose: np.ndarray

    @classmethod
    def translated(cls, intrinsics: Intrinsics, position: tuple[float, float, float]) -> Camera:
        """Camera looking along +z like the input view, centred at ``position`` (world)."""
        pose = np.eye(4)
        pose[:3, 3] = -np.asarray(position, float)
        return cls(intrinsics, pose)

    @classmethod
    def look_at(cls, intrinsics: Intrinsics, position, target, up=(0.0, -1.0, 0.0)) -> Camera:
        """Camera at ``position`` looking at ``target``; ``up`` is world up (OpenCV: -y).

        Raises:
            InputError: a point or ``up`` that is not 3 finite numbers, ``target`` at
                ``position``, or ``up`` parallel to the viewing direction.

        Example:
            >>> cam = Camera.look_at(Intrinsics.default(8, 8), (0, 0, 0), (0, 0, 5))
            >>> np.allclose(cam.pose, np.eye(4))
            True
        """
        position, target, up = (_point(v, name) for v, name in
                                ((position, "position"), (target, "target"), (up, "up")))
        forward = target - position
        if np.linalg.norm(forward) == 0:
            raise InputError("look_at: target is at the camera's position")
        forward /= np.linalg.norm(forward)
        right = np.cross(-up, forward)
        if np.linalg.norm(right) < 1e-9:
            raise InputError("look_at: up is parallel to the viewing direction")
        right /= np.linalg.norm(right)
        down = np.cross(forward, right)
        rot = np.stack([right, down, forward])  # rows: camera axes in world coordinates
        pose = np.eye(4)
        pose[:3, :3] = rot
        pose[:3, 3] = -rot @ position
        return cls(intrinsics, pose)

    @property
    def position(self) -> np.ndarray:
        """``(3,)`` camera centre in world coordinates."""
        return -self.pose[:3, :3].T @ self.pose[:3, 3]


def _point(value, name: str) -> np.ndarray:
    """``value`` as 3 finite numbers ``(3,) float64``, or :class:`InputError` naming it."""
    try:
        point = np.asarray(value, float)
    except (TypeError, ValueError):
        point = None
    if point is None or point.shape != (3,) or not np.isfinite(point).all():
        raise InputError(f"look_at: {name} must be 3 finite numbers, got {value!r}")
    return point


def check_intrinsics(k: Intrinsics, what: str = "intrinsics") -> None:
    """Refuse intrinsics that are no camera: focal lengths that are not finite numbers
    > 0, or a principal point that is not finite (``make``'s input camera, a rendered
    view's); ``what`` names them in the message.

    Raises:
        InputError: one line with the four values.

    Example:
        >>> check_intrinsics(Intrinsics.default(64, 48))
        >>> check_intrinsics(Intrinsics(0.0, 0.0, 32.0, 24.0, 64, 48))  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        photo3d.errors.InputError: intrinsics need finite fx, fy > 0 and a ... fx=0, fy=0, ...
    """
    try:
        fx, fy, cx, cy = (float(v) for v in (k.fx, k.fy, k.cx, k.cy))
    except (TypeError, ValueError):
        raise InputError(f"{what} must be numbers, got fx={k.fx!r}, "
                         f"fy={k.fy!r}, cx={k.cx!r}, cy={k.cy!r}") from None
    if not (fx > 0 and fy > 0 and np.isfinite([fx, fy, cx, cy]).all()):
        raise InputError(f"{what} need finite fx, fy > 0 and a finite principal point, "
                         f"got fx={fx:g}, fy={fy:g}, cx={cx:g}, cy={cy:g}")
