"""Memory a run needs, estimated before the work so that a too-large size is refused.

The estimate is linear in the working pixels (longer side ``Config.size``, border
included): ``benchmarks/bench_memory.py`` measured the peak resident memory of
``photo3d demo --no-video`` at ``--size`` 256, 512 and 1024 (246, 392 and 1123 MB:
about 200 MB of interpreter and libraries plus 850-1050 bytes per working pixel).
The per-pixel figure used here rounds that up (1024 px: 1.5 GB estimated).

Example:
    >>> from photo3d.config import Config
    >>> round(memory_estimate((768, 1024), Config()) / 1e9, 1)  # with its 60 px border
    1.6
"""

from __future__ import annotations

import os

from photo3d.config import Config
from photo3d.errors import ConfigError
from photo3d.stages.preprocess import working_shape

BASE_BYTES = 200e6
"""Interpreter, numpy, numba and the nets' code, resident before any pixel."""
BYTES_PER_PIXEL = 1400
"""Peak bytes per working pixel (measured 850-1050, rounded up)."""


def memory_estimate(shape: tuple[int, int], config: Config) -> int:
    """Peak bytes ``make`` needs for an input of ``shape`` ``(H, W)`` with ``config``."""
    h, w = working_shape(shape, config.size)
    border = 2 * config.spatial(config.regions.border, max(h, w))
    return int(BASE_BYTES + BYTES_PER_PIXEL * (h + border) * (w + border))


def available_memory() -> int | None:
    """Bytes the system can give this process now (Linux ``MemAvailable``), or None."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


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
    size = f"--size {config.size}" if at_least else f"a {w}x{h} working size"
    raise ConfigError(f"{size} needs {'at least' if at_least else 'about'} "
                      f"{need / 1e9:.1f} GB of memory but "
                      f"{have / 1e9:.1f} GB are available: use a smaller --size (1024 needs "
                      f"about {memory_estimate(shape, config.with_(size=1024)) / 1e9:.1f} GB)")
