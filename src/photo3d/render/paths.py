"""Camera paths: the authors' four presets and custom keyframed paths.

A path is a list of :class:`~photo3d.camera.Camera`, one per frame, in the world
frame of the input view (OpenCV axes; depth units of the 3D photo, so the authors'
shifts give the authors' parallax, see :mod:`photo3d.camera`).

Presets (the authors' ``video_postfix`` list, docs/outputs.md), with the
translation ``t = (x, y, z)`` of the camera-from-world pose:

* ``dolly-zoom-in``, ``zoom-in``: *double straight line*: a quadratic spline
  through ``-s``, ``0`` and ``s`` with ``s = (0, 0, -0.05)``, i.e. the camera moves
  forward along the optical axis. The dolly zoom also changes the focal length every
  frame so that the plane at the depth of the centre pixel keeps its size.
* ``circle``: ``t = (cos(pi u) * -0.015, sin(pi u) * -0.015, cos(pi u / 2) * -0.05)``
  for ``u`` in ``[-2, 2)``.
* ``swing``: the circle with ``y = 0``.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from photo3d.camera import Camera, Intrinsics
from photo3d.errors import InputError, require
from photo3d.io.bounded import MalformedJSON, loads_json, read_bytes

STANDARD_PATHS = ("dolly-zoom-in", "zoom-in", "circle", "swing")
_SHIFTS = {  # x, y, z of the authors' presets
    "dolly-zoom-in": (0.0, 0.0, -0.05),
    "zoom-in": (0.0, 0.0, -0.05),
    "circle": (-0.015, -0.015, -0.05),
    "swing": (-0.015, 0.0, -0.05),
}


def preset_path(name: str, intrinsics: Intrinsics, *, frames: int = 240,
                centre_depth: float | None = None) -> list[Camera]:
    """One of the authors' four camera paths.

    Args:
        name: ``dolly-zoom-in``, ``zoom-in``, ``circle`` or ``swing``.
        intrinsics: intrinsics of every frame (the dolly zoom rescales its focal length).
        frames: number of frames.
        centre_depth: depth of the centre pixel; required by ``dolly-zoom-in``.

    Returns:
        ``frames`` cameras.

    Example:
        >>> k = Intrinsics.default(64, 48)
        >>> path = preset_path("circle", k, frames=4)
        >>> [round(float(c.pose[0, 3]), 4) for c in path]
        [-0.015, 0.015, -0.015, 0.015]
    """
    if name not in _SHIFTS:
        raise InputError(f"unknown camera path {name!r}; presets: {', '.join(STANDARD_PATHS)}")
    if frames < 1:
        raise InputError(f"frames must be at least 1, got {frames}")
    sx, sy, sz = _SHIFTS[name]
    if name in ("dolly-zoom-in", "zoom-in"):
        u = np.linspace(0.0, 1.0, frames)
        # Quadratic interpolation through -s, 0, s at u = 0, 0.5, 1 (collinear
        # points, so it is the straight line -s + 2 s u).
        shift = np.array([sx, sy, sz])
        ts = -shift[None] + 2.0 * shift[None] * u[:, None]
    else:
        u = np.arange(-2.0, 2.0, 4.0 / frames)[:frames]
        ys = np.sin(np.pi * u) * sy
        ts = np.stack([np.cos(np.pi * u) * sx, ys, np.cos(np.pi * u / 2) * sz], axis=1)
    cameras = []
    for t in ts:
        pose = np.eye(4)
        pose[:3, 3] = t
        k = intrinsics
        if name == "dolly-zoom-in":
            if centre_depth is None or not centre_depth > 0:
                raise InputError("dolly-zoom-in needs the depth of the centre pixel")
            # the plane at centre_depth is now at centre_depth + t_z from the camera
            scale = (centre_depth + t[2]) / centre_depth
            k = replace(k, fx=k.fx * scale, fy=k.fy * scale)
        cameras.append(Camera(k, pose))
    return cameras


def _catmull_rom(times: np.ndarray, values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Centripetal-free uniform Catmull-Rom through ``values`` at ``times``."""
    n = len(times)
    if n == 1:
        return np.repeat(values[:1], len(t), axis=0)
    idx = np.clip(np.searchsorted(times, t, side="right") - 1, 0, n - 2)
    t0, t1 = times[idx], times[idx + 1]
    s = ((t - t0) / np.where(t1 > t0, t1 - t0, 1.0))[:, None]
    p0 = values[np.maximum(idx - 1, 0)]
    p1, p2 = values[idx], values[idx + 1]
    p3 = values[np.minimum(idx + 2, n - 1)]
    return 0.5 * ((2 * p1) + (-p0 + p2) * s + (2 * p0 - 5 * p1 + 4 * p2 - p3) * s**2
                  + (-p0 + 3 * p1 - 3 * p2 + p3) * s**3)


def _euler_to_matrix(degrees) -> np.ndarray:
    """Camera-to-world rotation from Euler angles (x, y, z) in degrees, applied x, y, z."""
    rx, ry, rz = np.radians(np.asarray(degrees, float))
    cx, sx, cy, sy, cz, sz = math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry), \
        math.cos(rz), math.sin(rz)
    mx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    my = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    mz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return mz @ my @ mx


def _to_quat(m: np.ndarray) -> np.ndarray:
    w = math.sqrt(max(0.0, 1 + m[0, 0] + m[1, 1] + m[2, 2])) / 2
    x = math.copysign(math.sqrt(max(0.0, 1 + m[0, 0] - m[1, 1] - m[2, 2])) / 2, m[2, 1] - m[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1 - m[0, 0] + m[1, 1] - m[2, 2])) / 2, m[0, 2] - m[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1 - m[0, 0] - m[1, 1] + m[2, 2])) / 2, m[1, 0] - m[0, 1])
    return np.array([w, x, y, z])


def _from_quat(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def _slerp(q0: np.ndarray, q1: np.ndarray, s: float) -> np.ndarray:
    dot = float(np.dot(q0, q1))
    if dot < 0:
        q1, dot = -q1, -dot
    if dot > 0.9995:
        q = q0 + s * (q1 - q0)
        return q / np.linalg.norm(q)
    theta = math.acos(dot)
    return (math.sin((1 - s) * theta) * q0 + math.sin(s * theta) * q1) / math.sin(theta)


MAX_COORDINATE = 1e9
"""Largest coordinate of a keyframe's position or look_at point (depth units): far
beyond any scene, small enough that the spline and the view direction cannot overflow."""


def keyframe_path(keyframes: list[dict], intrinsics: Intrinsics, *, frames: int) -> list[Camera]:
    """Smoothly interpolated path through keyframes.

    Each keyframe is a dictionary with ``position`` ``[x, y, z]`` (camera centre,
    world = input camera frame, OpenCV axes), optional ``time`` (any increasing
    numbers; default: evenly spaced), optional ``fov`` (vertical field of view in
    degrees; default: the input's), and either ``look_at`` ``[x, y, z]`` (a point
    the camera looks at, with world up = -y) or ``rotation`` (Euler angles x, y, z in
    degrees of the camera-to-world rotation; default no rotation). Positions and
    look-at points follow a Catmull-Rom spline, rotations a spherical linear
    interpolation, fields of view a linear one; frames are evenly spaced in time.
    Coordinates beyond :data:`MAX_COORDINATE`, non-finite numbers and rotations that are
    not three angles raise :class:`~photo3d.errors.InputError` (one line).

    Example:
        >>> k = Intrinsics.default(64, 48)
        >>> keys = [{"position": [0, 0, 0]}, {"position": [0.1, 0, 0], "fov": 40}]
        >>> path = keyframe_path(keys, k, frames=3)
        >>> [round(float(c.position[0]), 3) for c in path]
        [0.0, 0.05, 0.1]
    """
    if not keyframes:
        raise InputError("a camera path needs at least one keyframe")
    for i, k in enumerate(keyframes):
        if not isinstance(k, dict):
            raise InputError(f"keyframe {i} is {str(k)[:40]!r}; expected an object with a "
                             "position, e.g. {\"position\": [0, 0, 0]}")
    try:
        times = np.array([float(k.get("time", i)) for i, k in enumerate(keyframes)])
        positions = np.array([k["position"] for k in keyframes], float)
        base_fov = math.degrees(intrinsics.fov[1])
        fovs = np.array([float(k.get("fov", base_fov)) for k in keyframes])
        use_look = all("look_at" in k for k in keyframes)
        if any("look_at" in k for k in keyframes) and not use_look:
            raise InputError("give look_at in every keyframe or in none")
        targets = np.array([k["look_at"] for k in keyframes], float) if use_look else None
        rotations = np.array([k.get("rotation", (0, 0, 0)) for k in keyframes], float)
    except (KeyError, TypeError, ValueError, IndexError) as err:
        raise InputError(f"bad keyframe: {err}") from None
    points = [positions] + ([] if targets is None else [targets])
    with np.errstate(over="ignore", invalid="ignore"):  # -1e308 to 1e308: refused below
        steps = np.diff(times)
    finite = all(np.isfinite(a).all() for a in (times, steps, fovs)) and all(
        (np.abs(a) <= MAX_COORDINATE).all() for a in points)  # also False for NaN
    if positions.ndim != 2 or positions.shape[1:] != (3,) or not finite or \
            np.any(steps <= 0) or np.any(fovs <= 0) or np.any(fovs >= 180):
        raise InputError(f"keyframes need 3-D positions and look_at points within "
                         f"{MAX_COORDINATE:g} of the origin, increasing times and "
                         "0 < fov < 180")
    if rotations.shape != (len(keyframes), 3) or not np.isfinite(rotations).all():
        raise InputError("keyframe rotations need three finite Euler angles in degrees")
    quats = [_to_quat(_euler_to_matrix(r)) for r in rotations]
    if use_look:
        for i, (p, q) in enumerate(zip(positions, targets, strict=True)):
            _check_view_direction(q - p, f"keyframe {i}")
    t = np.linspace(times[0], times[-1], frames)
    pos = _catmull_rom(times, positions, t)
    look = _catmull_rom(times, targets, t) if use_look else None
    fov = np.interp(t, times, fovs)
    cameras = []
    for i in range(frames):
        k = _with_fov(intrinsics, math.radians(fov[i]))
        if use_look:
            _check_view_direction(look[i] - pos[i], f"frame {i} (between keyframes)")
            cameras.append(Camera.look_at(k, pos[i], look[i], up=_UP))
            continue
        j = int(np.clip(np.searchsorted(times, t[i], side="right") - 1, 0, len(times) - 1))
        if j == len(times) - 1:
            rot = _from_quat(quats[j])
        else:
            s = (t[i] - times[j]) / (times[j + 1] - times[j])
            rot = _from_quat(_slerp(quats[j], quats[j + 1], s))
        pose = np.eye(4)
        pose[:3, :3] = rot.T
        pose[:3, 3] = -rot.T @ pos[i]
        cameras.append(Camera(k, pose))
    return cameras


_UP = (0.0, -1.0, 0.0)  # world up of look_at keyframes (OpenCV: -y)


def _check_view_direction(direction: np.ndarray, where: str) -> None:
    """Refuse a ``look_at`` view ``direction`` (target - position, ``(3,)`` float) that
    is zero or (within ~0.06 degrees) parallel to world up, where no roll is defined.

    Example:
        >>> _check_view_direction(np.array([0.0, -2.0, 0.0]), "keyframe 1")
        ... # doctest: +ELLIPSIS
        Traceback (most recent call last):
        photo3d.errors.InputError: keyframe 1 looks straight up or down (look_at - ...
    """
    length = float(np.linalg.norm(direction))
    if not length > 1e-9:
        raise InputError(f"{where} looks at its own position (look_at == position)")
    if np.linalg.norm(np.cross(_UP, direction / length)) < 1e-3:
        shown = ", ".join(f"{v:g}" for v in direction)
        raise InputError(f"{where} looks straight up or down (look_at - position = [{shown}] "
                         "is parallel to world up -y); tilt it a little")


def _with_fov(k: Intrinsics, vfov: float) -> Intrinsics:
    f = k.height / (2.0 * math.tan(vfov / 2.0))
    scale = f / k.fy
    return replace(k, fx=k.fx * scale, fy=k.fy * scale)


def load_path(path: str | Path, intrinsics: Intrinsics, *, frames: int) -> list[Camera]:
    """Read keyframes from a JSON (or, with PyYAML installed, YAML) file.

    The file holds a list of keyframes or ``{"keyframes": [...]}`` (see
    :func:`keyframe_path`).

    Raises:
        InputError: one line; the file is missing, unreadable, not JSON/YAML (also
            nested too deeply), or its keyframes are invalid (including a ``look_at``
            equal to the position or straight up/down: checked here, before any work).
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"camera path file not found: {path}")
    try:
        text = read_bytes(path, max_bytes=16 << 20, what=f"camera path {path}").decode()
    except UnicodeDecodeError as err:
        raise InputError(f"cannot read camera path {path}: {err}") from None
    is_yaml = path.suffix.lower() in (".yaml", ".yml")
    if is_yaml:
        yaml = require("yaml", "yaml", purpose="reading YAML camera paths", package="PyYAML")
    try:
        if is_yaml:
            try:
                data = yaml.safe_load(text)
            except yaml.YAMLError as err:
                raise InputError(f"cannot parse camera path {path}: "
                                 f"{' '.join(str(err).split())}") from None
        else:
            try:
                data = loads_json(text, what=f"camera path {path}")
            except MalformedJSON as err:
                raise InputError(f"cannot parse camera path {path}: {err.reason}") from None
    except InputError:  # the YAML message above, already one line naming the file
        raise
    except (ValueError, AttributeError) as err:
        raise InputError(f"cannot parse camera path {path}: {err}") from None
    except RecursionError:
        raise InputError(f"cannot parse camera path {path}: nested too deeply") from None
    if isinstance(data, dict):
        data = data.get("keyframes")
    if not isinstance(data, list):
        raise InputError(f"camera path {path} must hold a list of keyframes")
    return keyframe_path(data, intrinsics, frames=frames)
