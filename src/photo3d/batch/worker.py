"""Making the photos of a batch, one after another, with the models loaded once.

A :class:`PhotoMaker` lives in each worker (a pool process or a Ray actor): it
builds the inpainter once (the learned nets load here) and keeps the monocular
depth model cached after its first use, then turns :class:`PhotoJob` s into
output folders exactly as ``photo3d make`` does. A photo that fails becomes a
``failed`` :class:`PhotoResult` with a one-line message; it never stops the
others.

:func:`write_output` and :func:`is_complete` say what a finished output folder is;
how it is written (atomically, through a hidden temporary sibling folder staged
before the work and renamed into place at the end) is
:func:`photo3d.output.stage_photo`'s business, and :func:`discard_partial` removes
what a killed worker left of it.
"""

from __future__ import annotations

import os
import socket
import time
from pathlib import Path

from photo3d.batch.jobs import MakeOptions, PhotoJob
from photo3d.batch.manifest import PhotoResult
from photo3d.errors import Photo3DError
from photo3d.output import LDI_FILE

_MARKERS = (LDI_FILE, "config.json")


def write_output(photo, out, options: MakeOptions) -> Path:
    """Write one photo's output folder atomically (what ``photo3d make`` writes).

    ``out`` is a folder or the :class:`~photo3d.files.staging.Staging` of one. Nothing
    appears at the output until everything (meshes, viewer, videos) is written.
    """
    return photo.save(out, overwrite=options.overwrite, ply=options.ply, glb=options.glb,
                      viewer=options.viewer, videos=list(options.videos),
                      render_settings=options.render_settings)


def is_complete(out: Path) -> bool:
    """True if ``out`` is a finished 3D photo folder (written by :func:`write_output`).

    Example:
        >>> import tempfile
        >>> is_complete(Path(tempfile.mkdtemp()))
        False
    """
    out = Path(out)
    return out.is_dir() and all((out / name).is_file() for name in _MARKERS)


def discard_partial(out: Path) -> None:
    """Remove what an interrupted :func:`write_output` of ``out`` may have left behind.

    (The temporary sibling folders ``.NAME.XXXXXXXX.tmp`` of a writer that was
    killed; only call this when no other process is writing ``out``.)
    """
    from photo3d.files.staging import remove_leftovers

    remove_leftovers(out)


def one_line(err: BaseException) -> str:
    """An exception as one line: its message, or its type and message if unexpected.

    Example:
        >>> one_line(ValueError("bad\\nvalue"))
        'ValueError: bad value'
    """
    text = " ".join(str(err).split())
    if isinstance(err, Photo3DError):
        return text
    return f"{type(err).__name__}: {text}" if text else type(err).__name__


class PhotoMaker:
    """Makes the 3D photos of a batch, one at a time, with the inpainter built once.

    Args:
        options: what ``photo3d make`` would take besides the photo and its depth.

    Raises:
        Photo3DError: the inpainter cannot be built (unknown name, bad weights).

    Example:
        >>> import tempfile, numpy as np
        >>> from photo3d.config import Config
        >>> from photo3d.io.images import write_image
        >>> d = Path(tempfile.mkdtemp())
        >>> write_image(d / "a.png", np.full((32, 32, 3), 0.5, np.float32))
        >>> np.save(d / "a.npy", np.ones((32, 32), np.float32))
        >>> maker = PhotoMaker(MakeOptions(config=Config(size=None), glb=False, viewer=False))
        >>> result = maker(PhotoJob("a", d / "a.png", d / "a.npy"), d / "out")
        >>> result.status, is_complete(d / "out" / "a")
        ('ok', True)
        >>> maker(PhotoJob("b", d / "b.png"), d / "out").error.startswith("image file not found")
        True
    """

    def __init__(self, options: MakeOptions) -> None:
        from photo3d.inpaint import get_inpainter

        self.options = options
        self.worker = f"{socket.gethostname()}:{os.getpid()}"
        self.inpainter = get_inpainter(options.config.inpainter,
                                       **dict(options.inpainter_options))

    def __call__(self, job: PhotoJob, out_dir: Path) -> PhotoResult:
        """Make ``job``'s photo into ``out_dir / job.name``; never raises for a bad photo."""
        start = time.perf_counter()
        out = Path(out_dir) / job.name
        depth = None
        warnings: tuple[str, ...] = ()
        try:
            if is_complete(out) and not self.options.overwrite:
                return PhotoResult(job.name, "skipped", None, 0.0, str(out))
            from photo3d.output import stage_photo

            inputs = [job.image] + ([job.depth] if job.depth is not None else [])
            with stage_photo(out, overwrite=self.options.overwrite, inputs=inputs) as staging:
                est = self._depth(job)
                depth, warnings = est.source, est.warnings
                self._make(job, est, staging)
        except Exception as err:  # recorded in the manifest, the batch goes on
            return PhotoResult(job.name, "failed", one_line(err), time.perf_counter() - start,
                               str(out), depth, warnings, self.worker)
        return PhotoResult(job.name, "ok", None, time.perf_counter() - start, str(out),
                           depth, warnings, self.worker)

    def _depth(self, job: PhotoJob):
        from photo3d.depth.sources import resolve_depth

        if job.depth is not None:
            return resolve_depth(job.image, depth=job.depth, kind=self.options.depth_kind)
        return resolve_depth(job.image, fallback_model=self.options.depth_model or "default")

    def _make(self, job: PhotoJob, est, staging) -> None:
        from photo3d.depth.sources import load_photo
        from photo3d.pipeline import make

        image = est.image if est.image is not None else load_photo(job.image)
        config = self.options.config.with_(depth_kind=est.kind)
        photo = make(image, depth=est.depth, config=config, inpainter=self.inpainter)
        write_output(photo, staging, self.options)
