"""Runs requests for the web page and the API: checks the uploads, waits for the
warm-up, gives each request its own folder, and stops cleanly with the server.

Nothing here imports Gradio: :mod:`photo3d.ui.page` hands over the paths of the
uploaded files and a progress callback, and shows the :class:`~photo3d.ui.job.JobResult`
or the one-line :class:`RequestError`.

Example:
    >>> import tempfile
    >>> from photo3d.ui.warmup import Warmup
    >>> from photo3d.ui.workspace import Workspace
    >>> root = Path(tempfile.mkdtemp())
    >>> warm = Warmup(root); warm.skip()
    >>> runner = Runner(Workspace(root / "ws", ttl=60), warm, upload_root=root / "up",
    ...                 max_bytes=1000)
    >>> next(runner.run(None, options=JobOptions()))
    Traceback (most recent call last):
    photo3d.ui.runner.RequestError: no photo: choose a photo first
"""

from __future__ import annotations

import logging
import os
import threading
from collections.abc import Callable, Iterator
from pathlib import Path

from photo3d.errors import Photo3DError
from photo3d.ui.job import JobCancelled, JobOptions, JobResult, redact, run_job
from photo3d.ui.warmup import Warmup
from photo3d.ui.workspace import Workspace, check_upload

log = logging.getLogger(__name__)


class RequestError(Photo3DError):
    """One line for the client: what was wrong with the request (a bad file, a photo
    too large, an option out of range) or why it could not be made."""


class Runner:
    """Makes 3D photos for requests, each in its own folder of ``workspace``.

    Args:
        workspace: the requests' folders.
        warmup: requests wait for it before they start.
        upload_root: the folder the web framework stores uploads in; only files
            inside it are read (:func:`~photo3d.ui.workspace.check_upload`).
        max_bytes: largest upload accepted.
        overlap: a request may start once the warm-up has compiled what ``make``
            needs (numba's threading layer runs parallel kernels of two threads at
            once); False waits for the whole warm-up.
    """

    def __init__(self, workspace: Workspace, warmup: Warmup, *, upload_root: Path,
                 max_bytes: int, overlap: bool = False) -> None:
        self.workspace = workspace
        self.warmup = warmup
        self.phase = "make" if overlap else "all"
        self.upload_root = Path(upload_root)
        self.max_bytes = max_bytes
        self.cancel = threading.Event()
        self._active = 0
        self._idle = threading.Condition()

    def run(self, photo: str | None, *, options: JobOptions, depth: str | None = None,
            right: str | None = None, name: str | None = None,
            progress: Callable[[float, str], None] | None = None) -> Iterator[JobResult]:
        """Make the uploaded ``photo`` (and ``depth`` or ``right``) with ``options``.

        Args:
            photo, depth, right: paths of uploaded files, or None.
            options: the client's choices.
            name: the photo's name as the client sent it (default: the file's).
            progress: ``progress(fraction, label)`` (a label's first report and then
                steps of at least 0.5 %).

        Yields:
            :class:`~photo3d.ui.job.JobResult` s as :func:`~photo3d.ui.job.run_job`
            does (the 3D photo, then with its videos); the files stay until the
            workspace's ``ttl`` after the last one.

        Raises:
            RequestError: one line for the client (no server path in it).
        """
        if photo is None:
            raise RequestError("no photo: choose a photo first")
        given = [Path(p) for p in (photo, depth, right) if p is not None]
        uploads = given + [Path(os.path.realpath(p)) for p in given]  # as messages name them
        try:
            files = [None if p is None else check_upload(p, upload_root=self.upload_root,
                                                         workspace=self.workspace,
                                                         max_bytes=self.max_bytes, what=what)
                     for p, what in ((photo, "photo"), (depth, "depth map"),
                                     (right, "right view"))]
            yield from self._run(*files, options=options, name=name or Path(photo).name,
                                 progress=progress)
        except JobCancelled:
            raise RequestError("the server is stopping; this request was not finished") from None
        except Photo3DError as err:
            raise RequestError(self._private(str(err), uploads)) from err
        except MemoryError:
            raise RequestError("out of memory: try a smaller working size") from None
        except Exception as err:  # a bug: logged in full, one line for the client
            log.exception("photo3d ui: request failed")
            line = self._private(f"{type(err).__name__}: {err}", uploads).splitlines()[0]
            raise RequestError(f"internal error ({line}); see the server's log") from err

    def _private(self, text: str, uploads: list[Path]) -> str:
        """``text`` without the server's folders: uploads by their names, the
        workspace and the upload folder as ``...``."""
        text = redact(text, uploads)
        for root in (self.workspace.root, self.upload_root):
            for form in {str(root), os.path.realpath(root)}:
                text = text.replace(form, "...")
        return text

    def _run(self, photo: Path, depth: Path | None, right: Path | None, *,
             options: JobOptions, name: str, progress) -> Iterator[JobResult]:
        shown = [-1.0, ""]

        def report(fraction: float, label: str) -> None:
            if progress is None:
                return
            if label != shown[1] or fraction - shown[0] >= 0.005:
                shown[:] = [fraction, label]
                progress(fraction, label)

        with self._idle:
            self._active += 1
        try:
            while not self.warmup.wait(0.25, phase=self.phase):
                if self.cancel.is_set():
                    raise JobCancelled("the server is stopping")
                report(0.0, "waiting for the warm-up")
            with self.workspace.request() as folder:
                yield from run_job(photo, folder, options=options, depth=depth, right=right,
                                   name=name, progress=report, cancel=self.cancel)
        finally:
            with self._idle:
                self._active -= 1
                self._idle.notify_all()

    def stop(self, timeout: float = 10.0) -> bool:
        """Make running requests stop at their next progress report (their partial
        output is removed) and wait for them; False if some still run after
        ``timeout`` seconds."""
        self.cancel.set()
        with self._idle:
            return self._idle.wait_for(lambda: self._active == 0, timeout)
