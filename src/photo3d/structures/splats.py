"""The Gaussian splat type every splat writer takes (built by
:mod:`photo3d.export.splats`, written by :mod:`photo3d.io.splat_ply`,
:mod:`photo3d.io.spz` and :mod:`photo3d.io.splat_glb`).

The values are stored as a renderer uses them (colour, opacity in [0, 1], scale as a
standard deviation); each file format converts them to its own encoding (the 3DGS
PLY's spherical-harmonics DC term, logit opacity and log scale, SPZ's quantized
bytes, glTF's linear attributes).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from photo3d.errors import InputError

SH_C0 = 0.28209479177387814
"""The degree-0 spherical harmonic, ``1 / (2 sqrt(pi))``: a splat's colour is
``0.5 + SH_C0 * f_dc`` (the 3DGS convention)."""


@dataclass(frozen=True)
class Splats:
    """3D Gaussians in the input camera's frame (OpenCV axes: x right, y down,
    z forward; units of the depth mapping, see :mod:`photo3d.camera`).

    Attributes:
        positions: ``(N, 3) float32`` centres.
        colors: ``(N, 3) float32`` sRGB colour (the DC term), nominally in [0, 1].
        opacity: ``(N,) float32`` peak opacity in (0, 1).
        scales: ``(N, 3) float32`` standard deviations along the Gaussian's own
            axes, > 0.
        rotations: ``(N, 4) float32`` unit quaternions ``(w, x, y, z)`` turning
            the Gaussian's axes into camera axes.

    Example:
        >>> s = Splats(np.zeros((2, 3)), np.full((2, 3), 0.5), np.full(2, 0.9),
        ...            np.full((2, 3), 0.01), np.tile([1.0, 0, 0, 0], (2, 1)))
        >>> len(s), s.checked()[0].dtype.name
        (2, 'float32')
    """

    positions: np.ndarray
    colors: np.ndarray
    opacity: np.ndarray
    scales: np.ndarray
    rotations: np.ndarray

    def __len__(self) -> int:
        return int(len(self.positions))

    def checked(self) -> tuple[np.ndarray, ...]:
        """``(positions, colors, opacity, scales, rotations)`` as float32, validated.

        Raises:
            InputError: inconsistent shapes, no splat, non-finite values, opacity
                outside [0, 1] or scales that are not positive.

        Example:
            >>> Splats(np.zeros((1, 3)), np.zeros((1, 3)), np.ones(1), -np.ones((1, 3)),
            ...        np.array([[1.0, 0, 0, 0]])).checked()
            Traceback (most recent call last):
            photo3d.errors.InputError: splats.scales must be > 0
        """
        arrays = tuple(np.asarray(a, np.float32) for a in (
            self.positions, self.colors, self.opacity, self.scales, self.rotations))
        count = len(arrays[0])
        shapes = ((count, 3), (count, 3), (count,), (count, 3), (count, 4))
        for name, array, shape in zip(("positions", "colors", "opacity", "scales",
                                       "rotations"), arrays, shapes, strict=True):
            if array.shape != shape:
                raise InputError(f"splats.{name} has shape {array.shape}, expected {shape}")
            if not np.isfinite(array).all():
                raise InputError(f"splats.{name} has NaN or infinite values")
        if count == 0:
            raise InputError("there are no splats to write")
        if arrays[2].min() < 0 or arrays[2].max() > 1:
            raise InputError("splats.opacity must be in [0, 1]")
        if arrays[3].min() <= 0:
            raise InputError("splats.scales must be > 0")
        return arrays
