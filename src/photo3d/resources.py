"""Memory a run needs, estimated before the work so that a too-large size is refused.

The estimate is linear in the working pixels (longer side ``Config.size``, border
included): ``benchmarks/bench_memory.py`` measured the peak resident memory of
``photo3d demo --no-video`` at ``--size`` 256, 512 and 1024 (246, 392 and 1123 MB:
about 200 MB of interpreter and libraries plus 850-1050 bytes per working pixel).

It must hold whatever the depth map holds, and a depth map with an edge every few
pixels costs more: ``make`` bounds each inpainting pass and the LDI by the working
pixels (:mod:`photo3d.stages.passes`), but the light mesh of such a fragmented LDI
takes up to about 550 bytes per LDI pixel while it is built. The worst measured, 3x3
blocks of uniform noise for a 741x500 photo (``benchmarks/bench_hard_depth.py
--hostile`` has noise, a checkerboard and a flat map), peaked at 609 MB at 512 px and
1.60 GB at 1024 px (the LDI at its limit): about 280 MB plus 1430 bytes per working
pixel. The figures used here round that up (1024 px: 1.8 GB estimated).

Example:
    >>> from photo3d.config import Config
    >>> round(memory_estimate((768, 1024), Config()) / 1e9, 1)  # with its 60 px border
    1.9
"""

from __future__ import annotations

import math

from photo3d.config import Config, working_shape
from photo3d.errors import ConfigError
from photo3d.io import limits

BASE_BYTES = 200e6
"""Interpreter, numpy, numba and the nets' code, resident before any pixel."""
MAKE_BASE_BYTES = 100e6
"""What ``make``'s kernels and libraries add to :data:`BASE_BYTES` before any pixel."""
BYTES_PER_PIXEL = 1600
"""Peak bytes of ``make`` per working pixel (measured 850-1050 for photos, 1430 for the
worst depth maps; rounded up)."""


def memory_estimate(shape: tuple[int, int], config: Config) -> int:
    """Peak bytes ``make`` needs for an input of ``shape`` ``(H, W)`` with ``config``,
    whatever its depth map holds."""
    h, w = working_shape(shape, config.size)
    border = 2 * config.spatial(config.regions.border, max(h, w))
    return int(BASE_BYTES + MAKE_BASE_BYTES + BYTES_PER_PIXEL * (h + border) * (w + border))


def available_memory() -> int | None:
    """Bytes the system can give this process now (Linux ``MemAvailable``), or None
    (:func:`photo3d.io.limits.available_memory`, which the file readers check)."""
    return limits.available_memory()


def check_memory(shape: tuple[int, int], config: Config, *, at_least: bool = False) -> None:
    """Raise :class:`ConfigError` if ``make`` would need more memory than is available.

    ``at_least``: ``shape`` is only an aspect ratio giving a lower bound (the message
    says so).

    Example:
        >>> check_memory((480, 640), Config(size=512))  # well within any machine
    """
    need, have = memory_estimate(shape, config), available_memory()
    if have is None or need <= have:
        return
    h, w = working_shape(shape, config.size)
    size = (f"a {w}x{h} working size" if not at_least
            else f"--size {config.size}" if config.size else "--size 0 (the photo's size)")
    raise ConfigError(f"{size} needs {'at least' if at_least else 'about'} "
                      f"{need / 1e9:.1f} GB of memory but "
                      f"{have / 1e9:.1f} GB are available: use a smaller --size (1024 needs "
                      f"about {memory_estimate(shape, config.with_(size=1024)) / 1e9:.1f} GB)")


RENDER_BYTES_PER_LDI_PIXEL = 400
"""Bytes per LDI pixel of a loaded 3D photo and the mesh the renderer draws (measured
315 with ``render --still``: 628 MB for a 1.47M pixel LDI, 273 MB for 335k)."""
RENDER_BYTES_PER_PIXEL = 48
"""Bytes per output pixel and view besides the supersamples (measured 32)."""
RENDER_BYTES_PER_SAMPLE = 20
"""Bytes per supersample (``ssaa * ssaa`` per output pixel and view; measured 16:
``render --still`` at 4096x2768 took 810 MB, 1.34 GB and 2.23 GB at ssaa 1, 2, 3)."""
VIDEO_BYTES_PER_PIXEL = 64
"""Bytes per pixel of a video frame the encoder holds (measured 53 for mp4)."""


def render_memory_estimate(ldi_pixels: int, size: tuple[int, int], *, ssaa: int,
                           views: int = 1, video: bool = False) -> int:
    """Peak bytes ``render`` needs for a 3D photo of ``ldi_pixels`` LDI pixels at
    output ``size`` ``(width, height)`` with supersampling ``ssaa`` per axis, ``views``
    views per frame (2 for stereo) and, for ``video``, the encoder and a second frame
    rendered at once (:meth:`~photo3d.render.renderer.Renderer.frame_workers`).

    Example:
        >>> round(render_memory_estimate(1_500_000, (1024, 768), ssaa=2) / 1e9, 2)
        0.9
    """
    width, height = size
    per_view = RENDER_BYTES_PER_PIXEL + RENDER_BYTES_PER_SAMPLE * ssaa * ssaa
    frames = 2 if video else 1  # frames rendered at once
    per_pixel = frames * views * per_view + (VIDEO_BYTES_PER_PIXEL if video else 0)
    return int(BASE_BYTES + RENDER_BYTES_PER_LDI_PIXEL * ldi_pixels
               + per_pixel * width * height)


def check_render_memory(ldi_pixels: int, size: tuple[int, int], *, ssaa: int,
                        views: int = 1, video: bool = False) -> None:
    """Raise :class:`ConfigError` if rendering would need more memory than is available
    (:func:`render_memory_estimate`); the message names the largest size that fits.

    Example:
        >>> check_render_memory(300_000, (640, 480), ssaa=2)  # within any machine
    """
    need, have = render_memory_estimate(ldi_pixels, size, ssaa=ssaa, views=views,
                                        video=video), available_memory()
    if have is None or need <= have:
        return
    width, height = size
    fixed = render_memory_estimate(ldi_pixels, (0, 0), ssaa=ssaa, views=views, video=video)
    what = (f"rendering {width}x{height} with --ssaa {ssaa} needs about "
            f"{limits.format_bytes(need)} of memory but {limits.format_bytes(have)} are "
            "available")
    scale = math.sqrt(max(have - fixed, 0) / (need - fixed))
    if min(width, height) * scale < 16:
        raise ConfigError(f"{what}: the 3D photo's {ldi_pixels:,} LDI pixels alone need "
                          f"{limits.format_bytes(fixed)}")
    fits = f"{int(width * scale) // 2 * 2}x{int(height * scale) // 2 * 2}"
    smaller = " or --ssaa 1" if ssaa > 1 else ""
    raise ConfigError(f"{what}: use a smaller --size (about {fits} fits){smaller}")


EXPORT_SPLAT_BYTES_PER_LDI_PIXEL = 250
"""Peak bytes per LDI pixel of ``export`` writing splat files, beyond :data:`BASE_BYTES`
(measured on the bundled sample's 1,453,295 LDI pixels: 511 MB for the three splat
files with ``--splats dense``, 348 MB adaptive)."""
EXPORT_MESH_BYTES_PER_LDI_PIXEL = 500
"""The same for the formats made of the light mesh (``mesh.usdz``, the quilt: the
mesh is built once for both; measured with the three splat files, adaptive: 998 MB
for all five formats)."""
_MESH_EXPORTS = ("mesh.usdz", "quilt")


def export_memory_estimate(ldi_pixels: int, formats) -> int:
    """Peak bytes ``photo3d export`` needs to write ``formats`` (names of
    :data:`photo3d.save_options.EXPORT_FORMATS`) of a 3D photo of ``ldi_pixels``
    LDI pixels.

    Example:
        >>> round(export_memory_estimate(1_453_295, ["splats.spz", "quilt"]) / 1e9, 2)
        1.29
        >>> round(export_memory_estimate(1_453_295, ["splats.spz"]) / 1e9, 2)
        0.56
    """
    per_pixel = (EXPORT_SPLAT_BYTES_PER_LDI_PIXEL if any(f.startswith("splats.")
                                                         for f in formats) else 0)
    per_pixel += (EXPORT_MESH_BYTES_PER_LDI_PIXEL if any(f in _MESH_EXPORTS
                                                         for f in formats) else 0)
    return int(BASE_BYTES + per_pixel * ldi_pixels)


def check_export_memory(ldi_pixels: int, formats) -> None:
    """Raise :class:`ConfigError` if exporting ``formats`` would need more memory than
    is available (:func:`export_memory_estimate`).

    Example:
        >>> check_export_memory(300_000, ["splats.ply"])  # within any machine
    """
    need, have = export_memory_estimate(ldi_pixels, formats), available_memory()
    if have is None or need <= have:
        return
    raise ConfigError(f"exporting {', '.join(formats)} of a 3D photo of {ldi_pixels:,} LDI "
                      f"pixels needs about {limits.format_bytes(need)} of memory but "
                      f"{limits.format_bytes(have)} are available: export fewer formats "
                      "at a time")
