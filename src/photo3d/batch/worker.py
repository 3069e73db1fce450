"""Making the photos of a batch, one after another, with the models loaded once.

A :class:`PhotoMaker` lives in each worker (a pool process or a Ray actor): it
builds the inpainter once (the learned nets load here) and keeps the monocular
depth model cached after its first use, then turns :class:`PhotoJob` s into
output folders with :func:`photo3d.folder.make_folder`, the function ``photo3d
make`` runs. A photo that fails becomes a ``failed`` :class:`PhotoResult` with a
one-line message; it never stops the others.

What a finished output folder is, is :func:`photo3d.output.is_complete`'s business
(re-exported here); how it is written (atomically, through a hidden temporary
sibling folder staged before the work and renamed into place at the end) is
:func:`photo3d.output.stage_photo`'s, and :func:`discard_partial` removes what a
killed worker left of it.
"""

from __future__ import annotations

import dataclasses
import os
import socket
import time
import warnings
from pathlib import Path

from photo3d.batch.jobs import MakeOptions, PhotoJob
from photo3d.batch.manifest import PhotoResult
from photo3d.errors import Photo3DError
from photo3d.output import is_complete

__all__ = ["PhotoMaker", "discard_partial", "is_complete", "one_line"]


def discard_partial(out: Path, *, wait: float = 0.0) -> None:
    """Remove what killed writers of the output folder ``out`` left: its temporary
    sibling folders ``.NAME.XXXXXXXX.tmp`` that no process holds any more, at any
    age (a batch calls this once the workers that made ``out`` are gone). A live
    writer's folder (a ``photo3d make -o OUT/NAME`` running beside the batch) is
    kept: it holds its lock (:func:`photo3d.files.temps.hold`).

    ``wait``: seconds to keep trying while a folder is still held (a worker the batch
    killed may hold it a moment longer: its process is ending), checked every 50 ms.
    """
    import time

    from photo3d.files.temps import remove_orphans, temp_entries

    deadline = time.monotonic() + wait
    while True:
        remove_orphans(out, age=0.0)
        held = [p for p in temp_entries(out, suffixed=False) if p.is_dir() and not p.is_symlink()]
        if not held or time.monotonic() >= deadline:
            return
        time.sleep(0.05)


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

    Each photo goes through :func:`photo3d.folder.make_folder` with ``options``, as
    in ``photo3d make``, with its depth map from the depth folder if it has one.
    ``options.depth_kind`` is what those maps hold: a photo without one keeps its
    embedded map's or the depth model's own kind.

    Args:
        options: what ``photo3d make`` would take besides the photo and its depth.

    Raises:
        Photo3DError: the inpainter cannot be built (unknown name, bad weights).

    Example:
        >>> import tempfile, numpy as np
        >>> from photo3d.config import Config
        >>> from photo3d.save_options import SaveOptions
        >>> from photo3d.io.images import write_image
        >>> d = Path(tempfile.mkdtemp())
        >>> write_image(d / "a.png", np.full((32, 32, 3), 0.5, np.float32))
        >>> np.save(d / "a.npy", np.ones((32, 32), np.float32))
        >>> maker = PhotoMaker(MakeOptions(config=Config(size=None),
        ...                                    save=SaveOptions(glb=False, viewer=False)))
        >>> result = maker(PhotoJob("a", d / "a.png", d / "a.npy"), d / "out")
        >>> result.status, is_complete(d / "out" / "a")
        ('ok', True)
        >>> maker(PhotoJob("b", d / "b.png"), d / "out").error.startswith("image file not found")
        True
    """

    def __init__(self, options: MakeOptions) -> None:
        self.options = options
        self.worker = f"{socket.gethostname()}:{os.getpid()}"
        self.inpainter = options.inpainter()

    def __call__(self, job: PhotoJob, out_dir: Path) -> PhotoResult:
        """Make ``job``'s photo into ``out_dir / job.name``; never raises for a bad photo."""
        from photo3d.folder import make_folder

        start = time.perf_counter()
        out = Path(out_dir) / job.name
        seen: dict = {"depth": None, "warnings": ()}

        def on_depth(est, image) -> None:
            seen.update(depth=est.source, warnings=est.warnings)

        options = self.options
        if job.depth is None:  # --depth-kind describes the depth folder's maps
            options = dataclasses.replace(options, depth_kind=None)
        if job.redo:  # its manifest record was unreadable: made again
            options = dataclasses.replace(options, overwrite=True)
        # other warnings (a multi-page TIFF's, ...) go into the manifest too, not raw
        # onto the worker's stderr
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                if is_complete(out) and not options.overwrite:
                    return PhotoResult(job.name, "skipped", None, 0.0, str(out))
                make_folder(job.image, out, options=options, depth=job.depth,
                            inpainter=self.inpainter, on_depth=on_depth)
            except Exception as err:  # recorded in the manifest, the batch goes on
                error = one_line(err)
            else:
                error = None
        notes = (*seen["warnings"], *(" ".join(str(w.message).split()) for w in caught))
        return PhotoResult(job.name, "failed" if error else "ok", error,
                           time.perf_counter() - start, str(out), seen["depth"], notes,
                           self.worker)
