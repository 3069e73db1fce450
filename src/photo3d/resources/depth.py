"""``photo3d depth``'s peak: the photo decoded whole (the map is written at its size),
its depth source and the 16-bit map and colour preview written at that size.

A 13000x13000 PNG of 0.5 MB has 169M pixels: decoding it alone needs about 8.1 GB
(:data:`photo3d.io.images` counts 48 bytes per pixel), and the depth at its size,
its checks, the normalised map, its 16-bit PNG and the preview more (measured 9.7 GB
in all). The whole is checked from the header, before a pixel is decoded
(:func:`check_depth_memory`).
Measured with ``benchmarks/bench_memory.py --depth`` (RESULTS.md, "depth").

Example:
    >>> round(depth_memory_estimate((3000, 3000)) / 1e9, 2)
    0.78
"""

from __future__ import annotations

from photo3d.resources.model import BASE_BYTES, Estimate, check

DECODE_BYTES_PER_PIXEL = 48
"""Decoding the photo to ``float32`` (:data:`photo3d.io.images._FLOAT_BYTES`)."""
DEPTH_BYTES_PER_PIXEL = 16
"""What the depth at the photo's size adds once the photo is decoded: the map read or
the model's output resized, its checks and preparation, the normalised map, the
16-bit PNG and the colour preview (measured 55 bytes per pixel in all, decoding
included, at 2000-4000 px: 311, 583 and 971 MB)."""
MODEL_BYTES = 1.5e9
"""A monocular depth model's weights, torch and its activations at the model's own
input size (Depth Anything V2 Small at 518 px: about 1.1 GB measured)."""


def depth_estimate(shape: tuple[int, int], *, model: bool = False) -> Estimate:
    """``photo3d depth``'s peak for a photo of ``shape`` ``(H, W)``; ``model``: the
    depth comes from a monocular model (else a file, a stereo pair or the photo's
    embedded map, read at the photo's size)."""
    pixels = shape[0] * shape[1]
    terms = [("base", int(BASE_BYTES)),
             ("decoding the photo", DECODE_BYTES_PER_PIXEL * pixels),
             ("the depth map", DEPTH_BYTES_PER_PIXEL * pixels)]
    if model:
        terms.append(("the depth model", int(MODEL_BYTES)))
    return Estimate("depth", tuple(terms))


def depth_memory_estimate(shape: tuple[int, int], *, model: bool = False) -> int:
    """Peak bytes of ``photo3d depth`` for a photo of ``shape`` (:func:`depth_estimate`)."""
    return depth_estimate(shape, model=model).bytes


def check_depth_memory(shape: tuple[int, int], *, model: bool = False) -> None:
    """Raise :class:`~photo3d.errors.ConfigError` if ``photo3d depth`` of a photo of
    ``shape`` would need more memory than is available (:func:`depth_estimate`).

    Example:
        >>> check_depth_memory((480, 640))  # within any machine
    """
    h, w = shape
    check(depth_estimate(shape, model=model), what=f"the depth map of a {w}x{h} photo",
          advice="make the photo smaller first (photo3d make reads it at its working "
                 "size)")
