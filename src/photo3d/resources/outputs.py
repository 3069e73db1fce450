"""Limits of the outputs, checked before the work: SPZ's splat count and free disk space.

SPZ's reference reader takes at most :data:`SPZ_LIMIT` splats. The adaptive splats'
count is known only once they are built, but it is at most the LDI's pixel count
(dense: exactly that), which ``export`` reads from ``photo3d.npz``'s header and
``make`` bounds by its working size (:func:`photo3d.resources.make.ldi_bound`). So
``splats.spz`` is refused at once when the bound can pass the limit: ``make``,
``batch`` and the UI before the photo is made, ``export`` (whose LDI is known) before
any file is written; one file, never several (docs/outputs.md, "SPZ's limit").
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from photo3d.errors import ConfigError, OutputError

SPZ_LIMIT = 10_000_000
"""Most splats an SPZ file may hold (the reference reader's limit,
:data:`photo3d.io.spz._MAX_POINTS`)."""


def check_spz_limit(splats: int, *, what: str, advice: str) -> None:
    """Raise :class:`ConfigError` if ``splats`` (a count, or a bound of it) is more
    than SPZ takes: ``{what} can have up to N splats, more than the 10,000,000 an SPZ
    file holds: {advice}``.

    Example:
        >>> check_spz_limit(9_000_000, what="splats.spz", advice="")
    """
    if splats > SPZ_LIMIT:
        raise ConfigError(f"{what} can have up to {splats:,} splats, more than the "
                          f"{SPZ_LIMIT:,} an SPZ file holds: {advice}")


def free_space(folder: str | os.PathLike[str]) -> tuple[Path, int] | None:
    """``(the nearest existing folder of folder, its file system's free bytes)``, or
    None when they cannot be read.

    Example:
        >>> import tempfile
        >>> free_space(tempfile.mkdtemp() + "/new/deeper")[1] > 0
        True
    """
    found = Path(folder)
    while not found.exists() and found != found.parent:
        found = found.parent
    try:
        return found, shutil.disk_usage(found).free
    except OSError:
        return None


def check_free_space(path: str | os.PathLike[str], need: int, *, what: str) -> None:
    """Raise :class:`OutputError` if the file system that will hold ``path`` (its
    nearest existing folder) has less than ``need`` bytes free (``what``: what is
    written, for the message). Nothing when the free space cannot be read.

    Example:
        >>> import tempfile
        >>> check_free_space(tempfile.mkdtemp() + "/a.png", 1000, what="a.png")
    """
    known = free_space(Path(path).parent)
    if known is None:
        return
    folder, free = known
    if need > free:
        raise OutputError(f"only {_size(free)} free in {folder}; {what} needs about "
                          f"{_size(need)}")


def _size(count: int) -> str:
    """``count`` bytes in MB with one decimal (GB from 1 GB on)."""
    return f"{count / 1e6:.1f} MB" if count < 1e9 else f"{count / 1e9:.1f} GB"


EXPORT_DISK_BYTES = {"splats.ply": 15, "splats.spz": 1, "splats.glb": 15, "mesh.usdz": 1,
                     "quilt": 0}
"""Bytes per LDI pixel each export format writes at least, roughly (adaptive splats:
the bundled sample at 1024 px, 1.45M LDI pixels, 56, 6.6 and 60 bytes, 1.9 for
``mesh.usdz``; 31 for the splat files of 3x3 blocks of noise, whose hidden layers
join; a flat photo joins far more, so these round well down)."""
QUILT_DISK_BYTES = 5_000_000
"""A quilt's PNG at least (its size is fixed: 19 MB for the sample)."""


def export_bytes(ldi_pixels: int, formats) -> int:
    """A low estimate of the bytes ``export`` writes for ``formats`` of a 3D photo of
    ``ldi_pixels`` LDI pixels (a full disk is refused before the work).

    Example:
        >>> export_bytes(1_000_000, ["splats.ply", "quilt"]) / 1e6
        20.0
    """
    formats = list(dict.fromkeys(formats))
    return int(sum(EXPORT_DISK_BYTES.get(f, 0) for f in formats) * ldi_pixels
               + (QUILT_DISK_BYTES if "quilt" in formats else 0))


VIDEO_DISK_BYTES_PER_PIXEL = 0.002
"""Bytes a video takes per pixel of each frame, at least (the sample's four videos at
1024 x 690, 240 frames: 1.1 to 2.3 MB, 0.0065 to 0.0136; a flat photo's far less)."""
IMAGE_DISK_BYTES_PER_PIXEL = 0.1
"""Bytes a PNG (a still, a depth map and its preview) takes per pixel, at least (a
photo's about 1.5 to 3; a flat image's far less)."""


def render_bytes(frame_pixels: int, frames: int, *, still: bool = False) -> int:
    """Bytes ``render`` writes at least: videos of ``frames`` frames of
    ``frame_pixels`` pixels, or (``still``) one image of that many pixels.

    Example:
        >>> render_bytes(1024 * 690, 240) / 1e6, render_bytes(4000 * 4000, 1, still=True) / 1e6
        (0.339148, 1.6)
    """
    if still:
        return int(IMAGE_DISK_BYTES_PER_PIXEL * frame_pixels)
    return int(VIDEO_DISK_BYTES_PER_PIXEL * frame_pixels * frames)
