"""``make``'s peak (also ``batch``'s workers and the UI's requests): linear in the
working pixels, border included.

``benchmarks/bench_memory.py`` measured the peak resident memory of ``photo3d demo
--no-video`` at ``--size`` 256, 512 and 1024 (246, 392 and 1123 MB: about 200 MB of
interpreter and libraries plus 850-1050 bytes per working pixel).

It must hold whatever the depth map holds, and a depth map with an edge every few
pixels costs more: ``make`` bounds each inpainting pass and the LDI by the working
pixels (:mod:`photo3d.stages.passes`: at most :data:`~photo3d.stages.passes.LDI_LIMIT`
LDI pixels per lattice position), but the light mesh of such a fragmented LDI takes
up to about 550 bytes per LDI pixel while it is built. The worst measured, 3x3 blocks
of uniform noise for a 741x500 photo (``benchmarks/bench_hard_depth.py --hostile``),
peaked at 609 MB at 512 px and 1.60 GB at 1024 px (the LDI at its limit): about 280 MB
plus 1430 bytes per working pixel. With the edges aligned to the photo's colour
edges (the default since), the same 1024 px run peaked at 1.80 GB (1.86M LDI pixels,
the limit): about 1620 bytes per working pixel. :data:`BYTES_PER_PIXEL` rounds that up.

``--export`` adds what the export writers hold beside the saved folder
(:func:`photo3d.resources.export.export_terms` of the largest LDI the working size
allows, :func:`ldi_bound`).

Example:
    >>> from photo3d.config import Config
    >>> round(memory_estimate((768, 1024), Config()) / 1e9, 1)  # with its 60 px border
    2.1
"""

from __future__ import annotations

from collections.abc import Sequence

from photo3d.config import Config, working_shape
from photo3d.resources.model import BASE_BYTES, Estimate, check

MAKE_BASE_BYTES = 100e6
"""What ``make``'s kernels and libraries add to :data:`BASE_BYTES` before any pixel."""
BYTES_PER_PIXEL = 1800
"""Peak bytes of ``make`` per working pixel (measured 850-1050 for photos, 1620 for the
worst depth maps; rounded up)."""


def lattice_pixels(shape: tuple[int, int], config: Config) -> int:
    """Lattice positions of the LDI ``make`` builds for an input of ``shape``
    ``(H, W)``: the working shape and its border.

    Example:
        >>> lattice_pixels((768, 1024), Config())  # 60 px of border on each side
        1015872
    """
    h, w = working_shape(shape, config.size)
    border = 2 * config.spatial(config.regions.border, max(h, w))
    return (h + border) * (w + border)


def ldi_bound(shape: tuple[int, int], config: Config) -> int:
    """The most LDI pixels ``make`` can give an input of ``shape``, whatever its
    depth holds: :data:`~photo3d.stages.passes.LDI_LIMIT` per lattice position.

    Example:
        >>> ldi_bound((768, 1024), Config())
        2031744
    """
    from photo3d.stages.passes import LDI_LIMIT

    return int(LDI_LIMIT * lattice_pixels(shape, config))


def make_estimate(shape: tuple[int, int], config: Config,
                  exports: Sequence[str] = (), *, splat_fit: bool = True) -> Estimate:
    """``make``'s peak for an input of ``shape`` ``(H, W)`` with ``config``, writing
    ``exports`` too (names of :data:`photo3d.save_options.EXPORT_FORMATS`; ``splat_fit``:
    the splats' colours fitted)."""
    from photo3d.resources.export import export_terms

    terms = [("base", int(BASE_BYTES + MAKE_BASE_BYTES)),
             ("working pixels", int(BYTES_PER_PIXEL * lattice_pixels(shape, config)))]
    if exports:
        terms.append(("exports", sum(b for _, b in export_terms(
            ldi_bound(shape, config), exports, splat_fit=splat_fit))))
    return Estimate("make", tuple(terms))


def memory_estimate(shape: tuple[int, int], config: Config,
                    exports: Sequence[str] = (), *, splat_fit: bool = True) -> int:
    """Peak bytes ``make`` needs for an input of ``shape`` ``(H, W)`` with ``config``,
    whatever its depth map holds (:func:`make_estimate`)."""
    return make_estimate(shape, config, exports, splat_fit=splat_fit).bytes


def check_memory(shape: tuple[int, int], config: Config, *, at_least: bool = False,
                 exports: Sequence[str] = (), splat_fit: bool = True) -> None:
    """Raise :class:`~photo3d.errors.ConfigError` if ``make`` would need more memory
    than is available (:func:`make_estimate`).

    ``at_least``: ``shape`` is only an aspect ratio giving a lower bound (the message
    says so).

    Example:
        >>> check_memory((480, 640), Config(size=512))  # well within any machine
    """
    h, w = working_shape(shape, config.size)
    size = (f"a {w}x{h} working size" if not at_least
            else f"--size {config.size}" if config.size else "--size 0 (the photo's size)")
    smaller = memory_estimate(shape, config.with_(size=1024), exports, splat_fit=splat_fit)
    check(make_estimate(shape, config, exports, splat_fit=splat_fit), what=size, at_least=at_least,
          advice=f"use a smaller --size (1024 needs about {smaller / 1e9:.1f} GB)")


def batch_estimate(config: Config, *, workers: int, exports: Sequence[str] = (),
                   splat_fit: bool = True) -> Estimate:
    """``photo3d batch``'s peak with ``workers`` local processes each making a 16:9
    photo at once (at least: a squarer photo has more working pixels).

    Example:
        >>> [name for name, _ in batch_estimate(Config(size=256), workers=2).terms]
        ['base', '2 workers']
    """
    one = make_estimate((9, 16), config, exports, splat_fit=splat_fit)
    return Estimate("batch", (("base", int(BASE_BYTES)), (f"{workers} workers",
                                                          workers * one.bytes)))


def check_batch_memory(config: Config, *, workers: int, exports: Sequence[str] = (),
                       splat_fit: bool = True) -> None:
    """Raise :class:`~photo3d.errors.ConfigError` if ``photo3d batch``'s ``workers``
    would need more memory than is available (:func:`batch_estimate`).

    Example:
        >>> check_batch_memory(Config(size=256), workers=2)  # within any machine
    """
    one = make_estimate((9, 16), config, exports, splat_fit=splat_fit).bytes
    check(batch_estimate(config, workers=workers, exports=exports, splat_fit=splat_fit),
          what=f"{workers} workers at --size {config.size or 0}", at_least=True,
          advice=f"use fewer --workers or a smaller --size (each worker needs at least "
                 f"{one / 1e9:.1f} GB)")
