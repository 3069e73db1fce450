"""Write rendered camera paths as video: MP4 (H.264), WebM (VP9) or animated GIF.

The encoders come from PyAV (``pip install av``), whose wheels bundle FFmpeg with
libx264 and libvpx, so no system ffmpeg is needed. The format follows the extension:

* ``.mp4``: H.264 (``libx264``), ``yuv420p`` so every player opens it, ``+faststart``
  so browsers stream it, CRF 18 by default, preset ``veryfast`` with the diamond
  motion search and the fastest subpixel refinement (``me=dia:subme=1``: on 80
  rendered frames of the demo's ``circle`` at 1280x720, 9.5 instead of 13.7 ms of
  CPU a frame for 9 % larger files and 0.1 dB less PSNR; ``superfast`` saves a
  little more but its files are 1.4-3.3 times larger, ``benchmarks/bench_encode.py``).
* ``.webm``: VP9 (``libvpx-vp9``), ``yuv420p``, constant quality CRF 32 by default,
  real-time speed settings.
* ``.gif``: 256 colours from one global palette (median cut over the first
  ``PALETTE_FRAMES`` frames), Floyd-Steinberg dithering, loops forever.

MP4 and WebM store limited-range BT.709 YUV (converted by
:func:`photo3d.io._yuv.rgb_to_yuv420`) and tag it so. ``yuv420p`` halves the
colour resolution, so they need an even width and height (the renderer produces even
sizes); GIF takes any size. The video goes to a hidden temporary file beside the
target (``.NAME.XXXXXXXX.tmp.part``, a :class:`~photo3d.files.atomic.PendingFile`),
renamed over it only when :meth:`VideoWriter.close` succeeds: an error, Ctrl-C or
termination signal never leaves a partial video behind.

Example:
    >>> sorted(video_formats())
    ['.gif', '.mp4', '.webm']
"""

from __future__ import annotations

import contextlib
import math
import os
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from photo3d.errors import ConfigError, InputError, OutputError, require
from photo3d.files.atomic import PendingFile
from photo3d.io._yuv import rgb_to_yuv420

PathLike = str | os.PathLike[str]

PALETTE_FRAMES = 8
"""Number of leading frames a GIF's global palette is computed from."""

_GIF_MAX_FPS = 50  # GIF delays are whole 1/100 s; browsers slow delays < 2 cs to 10 cs

# extension -> (muxer, encoder, default CRF, muxer options, description)
_FORMATS: dict[str, tuple[str, str, int | None, dict[str, str], str]] = {
    ".mp4": ("mp4", "libx264", 18, {"movflags": "+faststart"},
             "H.264 video (libx264, yuv420p, even sizes); plays everywhere"),
    ".webm": ("webm", "libvpx-vp9", 32, {},
              "VP9 video (libvpx-vp9, yuv420p, even sizes); smaller, for the web"),
    ".gif": ("gif", "gif", None, {"loop": "0"},
             "animated GIF, 256-colour global palette, loops forever; large files"),
}  # fmt: skip
# encoder -> (highest CRF, options besides the CRF)
_CRF_ENCODERS = {
    "libx264": (51, {"preset": "veryfast", "x264-params": "me=dia:subme=1"}),
    "libvpx-vp9": (63, {"b": "0", "deadline": "realtime", "cpu-used": "8", "row-mt": "1"}),
}


MAX_VIDEO_SIDE = {"mp4": 16384, "webm": 65536, "gif": 65535}
"""Longest width or height each format's encoder opens (libx264: 16384; libvpx-vp9:
65536; GIF: 65535, its 16-bit fields), measured with PyAV's FFmpeg."""
MAX_FRAME_AREA = 2**31 // 8
"""FFmpeg opens no encoder for a frame with ``(width + 128) * (height + 128)`` at or
above this (``av_image_check_size``): 16254 x 16254 opens, 16256 x 16256 does not."""


def check_video_size(size: tuple[int, int], fmt: str) -> None:
    """Refuse a frame ``size`` ``(width, height)`` that the encoder of ``fmt`` (``mp4``,
    ``webm`` or ``gif``) would not open, before any rendering.

    Raises:
        ConfigError: one line naming the limit.

    Example:
        >>> check_video_size((16384, 2), "mp4")
        >>> check_video_size((16386, 2), "mp4")
        Traceback (most recent call last):
        photo3d.errors.ConfigError: a 16386x2 mp4 video is too large: its encoder takes at most 16384 pixels a side
        >>> check_video_size((16386, 2), "webm")
    """  # noqa: E501
    width, height = size
    side = MAX_VIDEO_SIDE.get(fmt.lower().lstrip("."))
    if side is not None and max(width, height) > side:
        raise ConfigError(f"a {width}x{height} {fmt} video is too large: its encoder takes "
                          f"at most {side} pixels a side")
    if (width + 128) * (height + 128) >= MAX_FRAME_AREA:
        raise ConfigError(f"a {width}x{height} video is too large: FFmpeg's encoders take at "
                          f"most about {int(MAX_FRAME_AREA**0.5) - 128} x "
                          f"{int(MAX_FRAME_AREA**0.5) - 128} pixels")


def video_formats() -> dict[str, str]:
    """Return the video extensions :class:`VideoWriter` writes, mapped to a description."""
    return {suffix: spec[-1] for suffix, spec in _FORMATS.items()}


def _require_av() -> Any:
    return require("av", None, purpose="writing video", package="PyAV")


class VideoWriter:
    """Encode frames one at a time into a video file; use it as a context manager.

    ``with VideoWriter(path, fps=40, size=(w, h)) as vw: vw.write(frame)``. Leaving
    the ``with`` block normally finishes the file; leaving it by an exception
    deletes the partial file and leaves any earlier file at ``path`` untouched.

    Args:
        path: target file; the extension picks the format (see :func:`video_formats`)
            and its folder must exist. An existing file is replaced.
        fps: frames per second, > 0 (at most 50 for GIF: browsers slow faster GIFs).
        size: ``(width, height)`` in pixels; both even for ``.mp4`` and ``.webm``.
        quality: constant-rate factor for libx264 (0..51, default 18) and libvpx-vp9
            (0..63, default 32); lower is better and larger. Ignored for ``.gif`` and
            other encoders.
        codec: FFmpeg encoder overriding the extension's default (e.g. ``"libvpx-vp9"``
            in an ``.mp4``); for ``.mp4``/``.webm`` it must take ``yuv420p``.

    Raises:
        OutputError: unknown extension, odd size for yuv420p, missing folder, unknown
            codec, or the file cannot be created.
        ConfigError: ``fps``, ``size`` or ``quality`` out of range.
        ImportError: PyAV is not installed.
    """

    def __init__(
        self,
        path: PathLike,
        *,
        fps: float = 30,
        size: tuple[int, int],
        quality: int | None = None,
        codec: str | None = None,
    ) -> None:
        self.path = Path(path)
        suffix = self.path.suffix.lower()
        if suffix not in _FORMATS:
            raise OutputError(
                f"cannot write video {self.path}: unknown extension {suffix or '(none)'!r}; "
                f"supported: {', '.join(_FORMATS)}"
            )
        muxer, default_codec, default_crf, mux_options, _ = _FORMATS[suffix]
        self._gif = suffix == ".gif"
        codec = codec or default_codec
        self.size = _check_settings(size, fps, quality, codec, gif=self._gif)
        if not self.path.parent.is_dir():
            raise OutputError(
                f"cannot write video {self.path}: folder {self.path.parent} does not exist"
            )
        if self.path.is_dir():
            raise OutputError(f"cannot write video {self.path}: it is a folder")
        av = _require_av()
        if codec not in av.codecs_available:
            raise OutputError(
                f"cannot write video {self.path}: FFmpeg encoder {codec!r} "
                "is not available in this PyAV build"
            )
        self.count = 0
        """Number of frames written so far."""
        self._closed = False
        self._pending: list[np.ndarray] = []  # GIF frames not yet encoded
        self._palette: tuple[Image.Image, np.ndarray] | None = None
        # the muxer is named, so any suffix; never written through a symbolic link
        self._file = PendingFile(self.path, suffix=".part", follow_symlinks=False)
        try:
            self._container = av.open(str(self._file.path), "w", format=muxer,
                                      options=mux_options)
        except OSError as err:
            self._file.discard()
            raise OutputError(f"cannot write video {self.path}: {err}") from err
        try:
            self._stream = self._add_stream(codec, fps, default_crf if quality is None else quality)
        except BaseException:
            self._abort()
            raise

    def _add_stream(self, codec: str, fps: float, crf: int | None) -> Any:
        stream = self._container.add_stream(
            codec, rate=Fraction(float(fps)).limit_denominator(1001)
        )
        stream.width, stream.height = self.size
        if self._gif:
            stream.pix_fmt = "pal8"
            return stream
        stream.pix_fmt = "yuv420p"
        context = stream.codec_context
        context.colorspace = context.color_primaries = context.color_trc = 1  # BT.709
        context.color_range = 1  # limited ("tv") range
        if codec in _CRF_ENCODERS:
            stream.options = {"crf": str(crf), **_CRF_ENCODERS[codec][1]}
        return stream

    def write(self, frame: np.ndarray) -> None:
        """Append one frame.

        Args:
            frame: ``(height, width, 3)`` RGB, ``uint8`` or float in [0, 1] (floats
                are clipped to [0, 1] and rounded to 8 bits), matching ``size``.

        Raises:
            InputError: wrong shape or dtype, or non-finite float values.
            OutputError: the writer is closed.
        """
        if self._closed:
            raise OutputError(f"cannot write to video {self.path}: the writer is closed")
        pixels = _to_uint8(frame, self.size, self.count)
        self.count += 1
        if self._gif:  # copy: the caller may reuse its buffer while we wait for the palette
            self._pending.append(pixels if self._palette is not None else pixels.copy())
            if self._palette is not None or len(self._pending) == PALETTE_FRAMES:
                self._flush_pending()
            return
        planes = rgb_to_yuv420(pixels)
        self._encode(_require_av().VideoFrame.from_ndarray(planes, format="yuv420p"),
                     self.count - 1)

    def close(self) -> None:
        """Finish the file and move it to ``path``; on failure remove it. Idempotent.

        Raises:
            InputError: no frame was written (no file is made).
            OutputError: the file cannot be finished or moved into place.
        """
        if self._closed:
            return
        try:
            if self.count == 0:
                raise InputError(f"no frames were written to video {self.path}")
            self._flush_pending()
            self._encode(None)
            self._container.close()
        except (OSError, _require_av().FFmpegError) as err:
            self._abort()
            raise OutputError(f"cannot write video {self.path}: {err}") from err
        except BaseException:
            self._abort()
            raise
        self._closed = True
        self._file.commit()  # on failure it removes the file and raises OutputError

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(self, exc_type: object, exc: object, traceback: object) -> None:
        if exc_type is None:
            self.close()
        else:
            self._abort()

    def _abort(self) -> None:
        """Drop the partial file; errors while tearing down must not hide the cause."""
        if self._closed:
            return
        self._closed = True
        av = _require_av()
        with contextlib.suppress(OSError, av.FFmpegError):
            self._container.close()
        self._file.discard()

    def _encode(self, frame: Any, pts: int | None = None) -> None:
        """Encode one ``av.VideoFrame`` at ``pts`` (frame index), or flush on ``None``."""
        if frame is not None:
            frame.pts = pts
        for packet in self._stream.encode(frame):
            self._container.mux(packet)

    def _flush_pending(self) -> None:
        """Quantize and encode the buffered GIF frames (palette from the first ones)."""
        if not self._pending:
            return
        if self._palette is None:
            self._palette = _global_palette(self._pending)
        palette_image, argb = self._palette
        first = self.count - len(self._pending)
        for index, pixels in enumerate(self._pending, start=first):
            indices = Image.fromarray(pixels).quantize(
                palette=palette_image, dither=Image.Dither.FLOYDSTEINBERG
            )
            pal8 = _require_av().VideoFrame.from_ndarray((np.asarray(indices), argb), "pal8")
            self._encode(pal8, index)
        self._pending = []


def _check_settings(
    size: tuple[int, int], fps: float, quality: int | None, codec: str, gif: bool
) -> tuple[int, int]:
    if len(size) != 2 or any(int(s) != s or s < 1 for s in size):
        raise ConfigError(f"size is {size}; expected (width, height), positive integers")
    if not gif and (size[0] % 2 or size[1] % 2):
        raise OutputError(
            f"size is {tuple(size)}; MP4 and WebM (yuv420p) need an even width and height"
        )
    if not (math.isfinite(fps) and fps > 0):
        raise ConfigError(f"fps is {fps}; expected a positive number")
    if gif and fps > _GIF_MAX_FPS:
        raise ConfigError(f"fps is {fps}; a GIF plays at most {_GIF_MAX_FPS} fps")
    max_crf = _CRF_ENCODERS.get(codec, (None,))[0]
    if quality is not None and max_crf is not None and not 0 <= quality <= max_crf:
        raise ConfigError(f"quality is {quality}; expected a CRF in 0..{max_crf} for {codec}")
    return int(size[0]), int(size[1])


def _to_uint8(frame: np.ndarray, size: tuple[int, int], index: int) -> np.ndarray:
    """Check one frame against ``size`` and return it as C-contiguous ``uint8``."""
    frame = np.asarray(frame)
    expected = (size[1], size[0], 3)
    if frame.shape != expected or not (frame.dtype == np.uint8 or frame.dtype.kind == "f"):
        raise InputError(
            f"frame {index} has shape {frame.shape} and dtype {frame.dtype}; expected "
            f"{expected} uint8 or float in [0, 1] for size {size}"
        )
    if frame.dtype == np.uint8:
        return np.ascontiguousarray(frame)
    if not np.isfinite(frame).all():
        raise InputError(f"frame {index} holds NaN or infinite values")
    scaled = np.clip(frame, 0.0, 1.0) * np.float32(255)
    scaled += np.float32(0.5)
    return scaled.astype(np.uint8)


def _global_palette(frames: list[np.ndarray]) -> tuple[Image.Image, np.ndarray]:
    """Median-cut 256-colour palette of ``frames``, as a Pillow ``P`` image and ``(256, 4)``
    ARGB ``uint8`` (opaque; unused entries black), the form PyAV's ``pal8`` takes."""
    height, width = frames[0].shape[:2]
    step = max(1, int(math.sqrt(height * width / 60_000)))  # ~60k samples per frame
    sample = np.concatenate([f[::step, ::step] for f in frames], axis=0)
    palette_image = Image.fromarray(sample).quantize(256, method=Image.Quantize.MEDIANCUT)
    rgb = np.zeros((256, 3), np.uint8)
    colours = np.asarray(palette_image.getpalette("RGB"), np.uint8).reshape(-1, 3)[:256]
    rgb[: len(colours)] = colours
    argb = np.concatenate([np.full((256, 1), 255, np.uint8), rgb], axis=1)
    return palette_image, argb
