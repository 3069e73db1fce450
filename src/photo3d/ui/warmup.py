"""Warm-up at start: a tiny 3D photo made in a background thread, so that numba
compiles (or loads from its cache) every kernel a request needs before the first
request arrives.

photo3d's kernels are compiled on first use and cached on disk; on a cold cache
that takes minutes, afterwards seconds. The warm-up runs the same path as a
request on a 48x64 synthetic photo, in the order a request needs it: first
:func:`photo3d.kernels.compile_kernels` (``make``'s kernels, shared with a helper
process on a cold cache) and :func:`photo3d.folder.make_folder` (the stages, the
meshes, the GLB and the viewer: phase ``"make"``), then a two-frame video (the
rasterizer and the encoder). A request waits for the phase it needs first
(:meth:`Warmup.wait`) rather than compile the same kernels at the same time; its
videos, later, find the video kernels compiled meanwhile (numba compiles one kernel
at a time, so a kernel the warm-up is still compiling is simply waited for).

Example:
    >>> import tempfile
    >>> warm = Warmup(Path(tempfile.mkdtemp()))
    >>> warm.state
    'not started'
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

from photo3d.parallel import start_thread


class Warmup:
    """Make a tiny photo in a daemon thread.

    Args:
        folder: an empty folder to write the tiny 3D photo in (removed afterwards
            by whoever owns it).

    Attributes:
        seconds: how long the warm-up took, once finished.
        error: one line if it failed (requests still work, they compile what they
            need themselves).
    """

    def __init__(self, folder: Path) -> None:
        self.folder = Path(folder)
        self.seconds: float | None = None
        self.error: str | None = None
        self._started = False
        self._skipped = False
        self._made = threading.Event()
        self._done = threading.Event()

    def start(self) -> None:
        """Start the warm-up thread (once)."""
        if not self._started:
            self._started = True
            start_thread(self._run, name="ui-warmup")

    @property
    def finished(self) -> bool:
        """True once the warm-up has ended (done, failed or skipped)."""
        return self._done.is_set()

    def skip(self) -> None:
        """Mark the warm-up done without running it."""
        self._started = self._skipped = True
        self.seconds = 0.0
        self._made.set()
        self._done.set()

    def wait(self, timeout: float | None = None, *, phase: str = "all") -> bool:
        """Wait until the warm-up has finished ``phase`` (``"make"``: what a 3D photo
        needs before its videos; ``"all"``); False on timeout."""
        return (self._made if phase == "make" else self._done).wait(timeout)

    @property
    def state(self) -> str:
        """``"not started"``, ``"running"``, ``"ready"`` or ``"failed"``."""
        if not self._started:
            return "not started"
        if not self._done.is_set():
            return "running"
        return "failed" if self.error else "ready"

    def message(self) -> str:
        """One line for the page."""
        state = self.state
        if state == "running" or state == "not started":
            return ("Warming up in the background: photo3d compiles its kernels (minutes "
                    "the very first time, seconds afterwards). A photo sent now starts as "
                    "soon as what it needs is compiled.")
        if state == "failed":
            return (f"The warm-up failed ({self.error}); photos still work, the first one "
                    "compiles what it needs.")
        if self._skipped:
            return "Ready (no warm-up: the first photo compiles what it needs)."
        return f"Ready (warm-up took {self.seconds:.1f} s)."

    def _run(self) -> None:
        start = time.perf_counter()
        try:
            from photo3d.kernels import compile_kernels

            compile_kernels()
            out = self.folder / "warmup"
            photo = _tiny_make(out)
            self._made.set()
            _tiny_video(photo, out)
        except Exception as err:  # reported in the page; requests compile on their own
            self.error = f"{type(err).__name__}: {err}".splitlines()[0]
        finally:
            self.seconds = time.perf_counter() - start
            self._made.set()
            self._done.set()


def _tiny_make(out: Path):
    """A 48x64 two-plane photo through ``make`` (GLB, viewer, PLY; no video)."""
    import numpy as np

    from photo3d.config import Config
    from photo3d.folder import MakeOptions, make_folder

    yy, xx = np.mgrid[0:48, 0:64] / 64.0
    image = np.stack([0.5 + 0.3 * np.sin(9 * xx + c) * np.cos(7 * yy) for c in range(3)], -1)
    disparity = np.ones((48, 64), np.float32)
    disparity[:, 32:] = 2.0
    return make_folder(image.astype(np.float32), out, depth=disparity,
                       options=MakeOptions(config=Config(size=None)))


def _tiny_video(photo, out: Path) -> None:
    """Two frames of the circle path, rendered as a request's videos are: from the
    folder's ``mesh.glb`` read back (:func:`photo3d.output.write_videos` with no mesh),
    textured, one sample per pixel antialiased at depth edges, hole filling, YUV
    conversion and x264. The kernels are compiled for argument types, not sizes: after
    this, a 1024 px request's video compiles nothing (checked on the sample: no new
    signature on any photo3d kernel during the video, benchmarks/results/ui.json)."""
    from photo3d.output import write_videos
    from photo3d.render.animate import VideoSpec
    from photo3d.render.renderer import video_settings

    write_videos(photo, None, out, [VideoSpec(path="circle", size=(64, 48), frames=2)],
                 settings=video_settings())
