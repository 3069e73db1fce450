"""Stereo images from two true novel views: side by side and red-cyan anaglyph."""

from __future__ import annotations

import numpy as np

from photo3d.camera import Camera
from photo3d.errors import ConfigError

MODES = ("sbs", "sbs-half", "anaglyph")
"""``sbs``: left and right views side by side at full width each; ``sbs-half``:
squeezed to half width each (the frame keeps the mono size, as 3D TVs expect);
``anaglyph``: red from the left eye, green and blue from the right eye."""

PLAYER_TAGS = {("sbs", "lr"): "LRF_Full_SBS", ("sbs", "rl"): "RLF_cross"}
"""File-name tags by which headset video players (Pigasus needs ``LRF``, SKYBOX
``Full_SBS``; DeoVR reads ``SBS``) recognise full-width side by side, as iw3 names
it; cross-eyed files get iw3's ``RLF_cross`` so no player shows them swapped."""


def file_tag(mode: str, order: str = "lr") -> str:
    """The tag a stereo video's file name ends with: :data:`PLAYER_TAGS`, else the mode.

    Example:
        >>> file_tag("sbs"), file_tag("sbs", "rl"), file_tag("anaglyph")
        ('LRF_Full_SBS', 'RLF_cross', 'anaglyph')
    """
    return PLAYER_TAGS.get((mode, order), mode)


def eye_cameras(camera: Camera, eye_separation: float) -> tuple[Camera, Camera]:
    """Left and right eye cameras, ``eye_separation`` apart along the camera's x axis.

    Example:
        >>> from photo3d.camera import Intrinsics
        >>> left, right = eye_cameras(Camera(Intrinsics.default(8, 8), np.eye(4)), 0.02)
        >>> round(float(left.position[0]), 3), round(float(right.position[0]), 3)
        (-0.01, 0.01)
    """
    if not eye_separation > 0:
        raise ConfigError(f"eye separation must be positive, got {eye_separation}")
    out = []
    for sign in (-0.5, 0.5):
        pose = camera.pose.copy()
        pose[0, 3] -= sign * eye_separation  # camera x axis: move the centre by sign * b
        out.append(Camera(camera.intrinsics, pose))
    return out[0], out[1]


def compose(left: np.ndarray, right: np.ndarray, mode: str, *, order: str = "lr") -> np.ndarray:
    """Combine two ``(H, W, 3)`` views into one stereo image.

    Args:
        left, right: the eyes' views, same shape and dtype.
        mode: one of :data:`MODES`.
        order: ``lr`` (left eye on the left, parallel viewing) or ``rl`` (cross-eyed).

    Example:
        >>> l, r = np.zeros((2, 4, 3)), np.ones((2, 4, 3))
        >>> compose(l, r, "sbs").shape, compose(l, r, "sbs-half").shape
        ((2, 8, 3), (2, 4, 3))
        >>> compose(l, r, "anaglyph")[0, 0].tolist()
        [0.0, 1.0, 1.0]
    """
    if left.shape != right.shape:
        raise ConfigError(f"stereo views differ in shape: {left.shape} vs {right.shape}")
    if mode == "anaglyph":
        out = right.copy()
        out[..., 0] = left[..., 0]
        return out
    if mode not in MODES:
        raise ConfigError(f"unknown stereo mode {mode!r}; modes: {', '.join(MODES)}")
    if order not in ("lr", "rl"):
        raise ConfigError(f"eye order must be 'lr' or 'rl', got {order!r}")
    a, b = (left, right) if order == "lr" else (right, left)
    if mode == "sbs-half":
        even = a.shape[1] // 2 * 2
        a, b = a[:, :even], b[:, :even]
        a = (a[:, 0::2].astype(np.float32) + a[:, 1::2]) / 2
        b = (b[:, 0::2].astype(np.float32) + b[:, 1::2]) / 2
        return np.concatenate([a, b], axis=1).astype(left.dtype)
    return np.concatenate([a, b], axis=1)
