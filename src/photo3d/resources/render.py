"""``render``'s peak (videos and stills; ``make``'s videos are within ``make``'s):
a loaded 3D photo and its mesh per LDI pixel, plus per output pixel and view the
frame, its supersamples and, for a video, the encoder.

Measured (``benchmarks/bench_memory.py``, RESULTS.md "Peak memory of every command"):
``render --still`` of a small 3D photo (82k LDI pixels) at 2000-6000 px took about
45 bytes per output pixel at ``--ssaa 1`` and 16 more per supersample; at 9000x9000
it took 8.2 GB, 98 bytes per pixel, since a view magnified that much leaves holes
wider than the near fill reaches and the pyramid fill (:func:`photo3d.holes.fill_holes`,
63 bytes per pixel) runs at full size. The estimate counts that fill for every frame.
"""

from __future__ import annotations

import math

from photo3d.io import limits
from photo3d.resources.model import BASE_BYTES, Estimate, check

RENDER_BASE_BYTES = 100e6
"""What the renderer's kernels add to :data:`BASE_BYTES` (measured about 50 MB)."""
RENDER_BYTES_PER_LDI_PIXEL = 400
"""Bytes per LDI pixel of a loaded 3D photo and the mesh the renderer draws (measured
315 with ``render --still``: 628 MB for a 1.47M pixel LDI, 273 MB for 335k)."""
FRAME_BYTES_PER_PIXEL = 120
"""Bytes per output pixel and view of a frame besides its supersamples: colour,
coverage and depth, the pyramid hole fill (63) and the ``uint8`` image (measured 98
for a still at 9000x9000, PNG encoding included)."""
RENDER_BYTES_PER_SAMPLE = 20
"""Bytes per supersample (``ssaa * ssaa`` per output pixel and view; measured 16:
``render --still`` at 4096x2768 took 810 MB, 1.34 GB and 2.23 GB at ssaa 1, 2, 3)."""
VIDEO_BYTES_PER_PIXEL = 64
"""Bytes per pixel of a video frame the encoder holds (measured 53 for mp4)."""


def render_terms(ldi_pixels: int, size: tuple[int, int], *, ssaa: int, views: int = 1,
                 video: bool = False) -> Estimate:
    """The :class:`~photo3d.resources.model.Estimate` of :func:`render_memory_estimate`."""
    width, height = size
    per_view = FRAME_BYTES_PER_PIXEL + RENDER_BYTES_PER_SAMPLE * ssaa * ssaa
    frames = 2 if video else 1  # frames rendered at once
    per_pixel = frames * views * per_view + (VIDEO_BYTES_PER_PIXEL if video else 0)
    return Estimate("render" if video else "render --still",
                    (("base", int(BASE_BYTES + RENDER_BASE_BYTES)),
                     ("the 3D photo", int(RENDER_BYTES_PER_LDI_PIXEL * ldi_pixels)),
                     ("frames", int(per_pixel * width * height))))


def render_memory_estimate(ldi_pixels: int, size: tuple[int, int], *, ssaa: int,
                           views: int = 1, video: bool = False) -> int:
    """Peak bytes ``render`` needs for a 3D photo of ``ldi_pixels`` LDI pixels at
    output ``size`` ``(width, height)`` with supersampling ``ssaa`` per axis, ``views``
    views per frame (2 for stereo) and, for ``video``, the encoder and a second frame
    rendered at once (:meth:`~photo3d.render.renderer.Renderer.frame_workers`); else a
    still.

    Example:
        >>> round(render_memory_estimate(1_500_000, (1024, 768), ssaa=2, video=True) / 1e9, 2)
        1.26
    """
    return render_terms(ldi_pixels, size, ssaa=ssaa, views=views, video=video).bytes


def check_render_memory(ldi_pixels: int, size: tuple[int, int], *, ssaa: int,
                        views: int = 1, video: bool = False) -> None:
    """Raise :class:`ConfigError` if rendering would need more memory than is available
    (:func:`render_memory_estimate`); the message names the largest size that fits.

    Example:
        >>> check_render_memory(300_000, (640, 480), ssaa=2)  # within any machine
    """
    from photo3d.resources.model import available_memory

    estimate = render_terms(ldi_pixels, size, ssaa=ssaa, views=views, video=video)
    need, have = estimate.bytes, available_memory()
    if have is None or need <= have:
        return
    width, height = size
    fixed = render_memory_estimate(ldi_pixels, (0, 0), ssaa=ssaa, views=views, video=video)
    what = f"rendering {width}x{height} with --ssaa {ssaa}"
    scale = math.sqrt(max(have - fixed, 0) / (need - fixed))
    if min(width, height) * scale < 16:
        advice = f"the 3D photo's {ldi_pixels:,} LDI pixels alone need {limits.format_bytes(fixed)}"
    else:
        fits = f"{int(width * scale) // 2 * 2}x{int(height * scale) // 2 * 2}"
        advice = (f"use a smaller --size (about {fits} fits)"
                  + (" or --ssaa 1" if ssaa > 1 else ""))
    check(estimate, what=what, advice=advice)
