"""Camera paths rendered to videos (mono or stereo)."""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterator, Sequence
from contextlib import closing
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from photo3d.camera import Camera, Intrinsics
from photo3d.errors import ConfigError
from photo3d.parallel import overlap, thread_pool
from photo3d.progress import CountProgress
from photo3d.render._resolve import to_rgb8
from photo3d.render.paths import STANDARD_PATHS, load_path, preset_path
from photo3d.render.renderer import Renderer, output_intrinsics
from photo3d.render.stereo import compose, eye_cameras, file_tag
from photo3d.structures.ldi import LDI

MAX_SIDE = 65536
"""Longest width or height of a video or still (WebM's encoder's limit, the largest of
:data:`photo3d.io.video.MAX_VIDEO_SIDE`; MP4's is 16384, checked against the format by
:func:`photo3d.io.video.check_video_size`)."""


def _check_size(size: tuple[int, int]) -> None:
    """Refuse a ``(width, height)`` that is not positive, longer than :data:`MAX_SIDE`
    or odd, in that order (a size that is too large is told so, even when odd).

    Example:
        >>> _check_size((64, 48))
        >>> _check_size((99999999, 48))
        Traceback (most recent call last):
        photo3d.errors.ConfigError: video size 99999999x48 is too large: at most 65536 pixels a side
    """
    width, height = size
    if min(width, height) < 1:
        raise ConfigError(f"video size must be positive, got {width}x{height}")
    if max(width, height) > MAX_SIDE:
        raise ConfigError(f"video size {width}x{height} is too large: at most {MAX_SIDE} "
                          "pixels a side")
    if width % 2 or height % 2:
        raise ConfigError(f"video size must be even numbers, got {width}x{height}")


@dataclass(frozen=True)
class VideoSpec:
    """What to render for one video.

    Attributes:
        path: a preset name (``dolly-zoom-in``, ``zoom-in``, ``circle``, ``swing``)
            or a JSON/YAML keyframe file.
        size: ``(width, height)`` in pixels (positive even numbers, at most
            :data:`MAX_SIDE`; None: the photo's size rounded down to even numbers).
        fps: frames per second (the authors': 40).
        frames: number of frames (the authors': 240).
        format: ``mp4``, ``webm`` or ``gif``.
        stereo: None (mono) or a mode of :data:`photo3d.render.stereo.MODES`.
        eye_separation: distance between the eyes in depth units.
        eye_order: ``lr`` or ``rl`` for side-by-side.
    """

    path: str = "circle"
    size: tuple[int, int] | None = None
    fps: float = 40.0
    frames: int = 240
    format: str = "mp4"
    stereo: str | None = None
    eye_separation: float = 0.01
    eye_order: str = "lr"

    def __post_init__(self) -> None:
        if self.size is not None:
            _check_size(self.size)
        if not 1 <= self.frames <= 100_000 or not 0 < self.fps <= 1000:
            raise ConfigError(f"frames must be 1..100000 and fps in (0, 1000], got "
                              f"{self.frames} frames at {self.fps} fps")
        if not (math.isfinite(self.eye_separation) and self.eye_separation >= 0):
            raise ConfigError(f"eye separation must be >= 0, got {self.eye_separation}")
        if self.path not in STANDARD_PATHS and not Path(self.path).is_file():
            raise ConfigError(f"unknown camera path {self.path!r}: not a preset "
                              f"({', '.join(STANDARD_PATHS)}) nor a keyframe file")
        if self.path not in STANDARD_PATHS:  # a keyframe file: check it now, not after the work
            load_path(self.path, Intrinsics.default(64, 48), frames=2)

    @property
    def name(self) -> str:
        """File stem of the video: the preset name or keyframe file stem, plus for
        stereo the tag players recognise (:func:`~photo3d.render.stereo.file_tag`:
        ``circle_LRF_Full_SBS``) or the mode (``circle_anaglyph``).

        Example:
            >>> VideoSpec(stereo="sbs").name, VideoSpec(path="swing", stereo="sbs-half").name
            ('circle_LRF_Full_SBS', 'swing_sbs-half')
        """
        stem = self.path if self.path in STANDARD_PATHS else Path(self.path).stem
        return f"{stem}_{file_tag(self.stereo, self.eye_order)}" if self.stereo else stem


def centre_depth(ldi: LDI) -> float:
    """Depth of the input pixel at the image centre (the dolly zoom keeps its plane)."""
    return float(ldi.depth()[(ldi.height // 2) * ldi.width + ldi.width // 2])


def path_cameras(ldi: LDI, spec: VideoSpec) -> list[Camera]:
    """The cameras of ``spec`` for a photo, at the output size.

    Example:
        >>> from photo3d.stages.ldi import from_image
        >>> ldi = from_image(np.zeros((10, 16, 3), np.float32), np.ones((10, 16), np.float32))
        >>> cams = path_cameras(ldi, VideoSpec(path="zoom-in", frames=3, size=(32, 20)))
        >>> len(cams), cams[0].intrinsics.width
        (3, 32)
    """
    width, height = spec.size or (ldi.width // 2 * 2, ldi.height // 2 * 2)
    k = output_intrinsics(ldi.intrinsics, width, height)
    if spec.path in STANDARD_PATHS:
        return preset_path(spec.path, k, frames=spec.frames, centre_depth=centre_depth(ldi))
    return load_path(spec.path, k, frames=spec.frames)


def render_frames(renderer: Renderer, cameras: Sequence[Camera], *, stereo: str | None = None,
                  eye_separation: float = 0.01, eye_order: str = "lr",
                  progress: CountProgress | None = None) -> Iterator[np.ndarray]:
    """Yield ``(H, W, 3) uint8`` frames, one per camera (stereo frames composed).

    With the CPU rasterizer, two frames are rendered at once on two threads, each with
    half of the caller's budget (:meth:`~photo3d.render.renderer.Renderer.frame_workers`,
    :func:`~photo3d.parallel.thread_pool`): the same frames, yielded in order.

    Example:
        >>> from photo3d.stages.ldi import from_image
        >>> from photo3d.mesh.full import build_mesh
        >>> from photo3d.render.renderer import RenderSettings
        >>> mesh = build_mesh(from_image(np.ones((8, 8, 3), np.float32),
        ...                              np.ones((8, 8), np.float32)))
        >>> r = Renderer(mesh, RenderSettings(backend="numba"))
        >>> cams = [Camera(Intrinsics.default(8, 8), np.eye(4))] * 2
        >>> [f.shape for f in render_frames(r, cams, stereo="sbs")]
        [(8, 16, 3), (8, 16, 3)]
    """
    def frame(cam: Camera) -> np.ndarray:
        if stereo:
            left, right = (renderer.render(c).color for c in eye_cameras(cam, eye_separation))
            return to_rgb8(compose(left, right, stereo, order=eye_order))
        return renderer.render_rgb8(cam)

    workers = renderer.frame_workers() if len(cameras) > 1 else 1
    if workers == 1:
        for i, cam in enumerate(cameras):
            yield frame(cam)
            if progress is not None:
                progress(i + 1, len(cameras))
        return
    # frames rendered at once on worker threads, yielded in order, `workers` in flight,
    # each worker's parallel kernels on its share of this thread's budget
    pool = thread_pool(workers, name="frame")
    try:
        pending = deque(pool.submit(frame, cam) for cam in cameras[:workers])
        for i in range(len(cameras)):
            image = pending.popleft().result()  # raises the worker's error here
            if i + workers < len(cameras):
                pending.append(pool.submit(frame, cameras[i + workers]))
            yield image
            if progress is not None:
                progress(i + 1, len(cameras))
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def render_still(renderer: Renderer, ldi: LDI, spec: VideoSpec) -> np.ndarray:
    """The input view (or the stereo pair around it) at ``spec``'s size, ``uint8``.

    Example:
        >>> from photo3d.stages.ldi import from_image
        >>> from photo3d.mesh.full import build_mesh
        >>> from photo3d.render.renderer import RenderSettings
        >>> ldi = from_image(np.ones((8, 8, 3), np.float32), np.ones((8, 8), np.float32))
        >>> r = Renderer(build_mesh(ldi), RenderSettings(backend="numba"))
        >>> render_still(r, ldi, VideoSpec(stereo="sbs-half")).shape
        (8, 8, 3)
    """
    width, height = spec.size or (ldi.width // 2 * 2, ldi.height // 2 * 2)
    cam = Camera(output_intrinsics(ldi.intrinsics, width, height), np.eye(4))
    return next(render_frames(renderer, [cam], stereo=spec.stereo,
                              eye_separation=spec.eye_separation, eye_order=spec.eye_order))


def render_video(renderer: Renderer, ldi: LDI, spec: VideoSpec, out: str | Path, *,
                 progress: CountProgress | None = None) -> Path:
    """Render ``spec`` to the video file ``out`` (format from ``spec.format``).

    The file is written to a temporary name and renamed when complete. Frames are
    converted to YUV and encoded on a worker thread while the next ones render
    (:func:`render_frames`: the rasterizer, hole filling and the encoder release the
    GIL; the encoder's thread runs no parallel kernel), one frame in the encoder.
    """
    from photo3d.io.video import VideoWriter

    cameras = path_cameras(ldi, spec)
    k: Intrinsics = cameras[0].intrinsics
    width = k.width * (2 if spec.stereo == "sbs" else 1)
    frames = render_frames(renderer, cameras, stereo=spec.stereo,
                           eye_separation=spec.eye_separation, eye_order=spec.eye_order,
                           progress=progress)
    # closing: on an error the frames' worker threads stop now, not when collected
    with closing(frames), VideoWriter(out, fps=spec.fps, size=(width, k.height)) as writer, \
            overlap(name="encode") as pool:
        pending = None
        for frame in frames:  # each a new array: the worker may keep it
            if pending is not None:
                pending.result()  # raises the worker's error here
            pending = pool.submit(writer.write, frame)
        if pending is not None:
            pending.result()
    return Path(out)
