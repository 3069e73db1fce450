"""Runs requests for the web page and the API: checks the uploads, waits for the
warm-up and for one of the ``workers`` places, gives each request its own folder,
and stops a request when it is cancelled or the server stops.

Each request has its own cancel event: set (the client cancelled, or the server
stops), the request stops at its next progress report and its folder is removed.
A request holds one of ``workers`` places from its start to its very end, so no
more than ``workers`` photos are ever made at once, whatever clients do;
:meth:`Runner.submit` runs a request in a thread of its own, so the web framework's
handler can give up on it (a cancel) without leaving it running unseen.

Nothing here imports Gradio: :mod:`photo3d.ui.page` hands over the paths of the
uploaded files and shows the :class:`~photo3d.ui.job.JobResult` s or the one-line
:class:`RequestError`.

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
from photo3d.parallel import shared_steps, start_thread, worker_share
from photo3d.ui.job import JobCancelled, JobOptions, JobResult, redact, run_job
from photo3d.ui.warmup import Warmup
from photo3d.ui.workspace import Workspace, check_upload

log = logging.getLogger(__name__)

Listener = Callable[[str, object], None]
"""``listener(kind, value)`` of :meth:`Runner.submit`: ``("progress", (fraction,
label))``, ``("result", JobResult)``, then ``("done", None)`` or ``("error",
RequestError)``."""


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
        workers: photos made at once; a request waits for a place.
        overlap: a request may start once the warm-up has compiled what ``make``
            needs (numba's threading layer runs parallel kernels of two threads at
            once); False waits for the whole warm-up.
    """

    def __init__(self, workspace: Workspace, warmup: Warmup, *, upload_root: Path,
                 max_bytes: int, workers: int = 1, overlap: bool = False) -> None:
        self.workspace = workspace
        self.warmup = warmup
        self.phase = "make" if overlap else "all"
        self.upload_root = Path(upload_root)
        self.max_bytes = max_bytes
        self.workers = workers
        self._places = threading.BoundedSemaphore(workers)
        self._idle = threading.Condition()
        self._running: set[threading.Event] = set()  # cancel events of running requests
        self._making = 0  # requests holding a place
        self._stopping = False

    @property
    def making(self) -> int:
        """Requests making a photo now (holding one of the ``workers`` places)."""
        with self._idle:
            return self._making

    def run(self, photo: str | None, *, options: JobOptions, depth: str | None = None,
            right: str | None = None, name: str | None = None,
            progress: Callable[[float, str], None] | None = None,
            cancel: threading.Event | None = None) -> Iterator[JobResult]:
        """Make the uploaded ``photo`` (and ``depth`` or ``right``) with ``options``.

        Args:
            photo, depth, right: paths of uploaded files, or None.
            options: the client's choices.
            name: the photo's name as the client sent it (default: the file's).
            progress: ``progress(fraction, label)`` (a label's first report and then
                steps of at least 0.5 %).
            cancel: this request's cancel event: once set, the request stops at its
                next progress report and its folder is removed.

        Yields:
            :class:`~photo3d.ui.job.JobResult` s as :func:`~photo3d.ui.job.run_job`
            does (the 3D photo, then with its videos); the files stay until the
            workspace's ``ttl`` after the last one.

        Raises:
            RequestError: one line for the client (no server path in it).
        """
        if photo is None:
            raise RequestError("no photo: choose a photo first")
        cancel = cancel or threading.Event()
        given = [Path(p) for p in (photo, depth, right) if p is not None]
        uploads = given + [Path(os.path.realpath(p)) for p in given]  # as messages name them
        with self._idle:
            if self._stopping:
                raise RequestError("the server is stopping; this request was not started")
            self._running.add(cancel)
        try:
            files = [None if p is None else check_upload(p, upload_root=self.upload_root,
                                                         workspace=self.workspace,
                                                         max_bytes=self.max_bytes, what=what)
                     for p, what in ((photo, "photo"), (depth, "depth map"),
                                     (right, "right view"))]
            yield from self._run(*files, options=options, name=name or Path(photo).name,
                                 progress=progress, cancel=cancel)
        except JobCancelled:
            line = ("the server is stopping; this request was not finished" if self._stopping
                    else "the request was cancelled")
            raise RequestError(line) from None
        except Photo3DError as err:
            raise RequestError(self._private(str(err), uploads)) from err
        except MemoryError:
            raise RequestError("out of memory: try a smaller working size") from None
        except Exception as err:  # a bug: logged in full, one line for the client
            log.exception("photo3d ui: request failed")
            line = self._private(f"{type(err).__name__}: {err}", uploads).splitlines()[0]
            raise RequestError(f"internal error ({line}); see the server's log") from err
        finally:
            with self._idle:
                self._running.discard(cancel)
                self._idle.notify_all()

    def submit(self, photo: str | None, *, options: JobOptions, listener: Listener,
               depth: str | None = None, right: str | None = None,
               name: str | None = None) -> threading.Event:
        """:meth:`run` in a thread of its own, telling ``listener`` what happens
        (:data:`Listener`); returns the request's cancel event (set it to stop the
        request at its next progress report and remove its folder)."""
        cancel = threading.Event()

        def work() -> None:
            try:
                for result in self.run(photo, options=options, depth=depth, right=right,
                                       name=name, cancel=cancel,
                                       progress=lambda f, label: listener("progress",
                                                                          (f, label))):
                    listener("result", result)
            except RequestError as err:
                listener("error", err)
            else:
                listener("done", None)

        start_thread(work, name="ui-request")
        return cancel

    def _private(self, text: str, uploads: list[Path]) -> str:
        """``text`` without the server's folders: uploads by their names, the
        workspace and the upload folder as ``...``."""
        text = redact(text, uploads)
        for root in (self.workspace.uploads, self.workspace.root, self.upload_root):
            for form in {str(root), os.path.realpath(root)}:
                text = text.replace(form, "...")
        return text

    def _run(self, photo: Path, depth: Path | None, right: Path | None, *,
             options: JobOptions, name: str, progress,
             cancel: threading.Event) -> Iterator[JobResult]:
        shown = [-1.0, ""]

        def report(fraction: float, label: str) -> None:
            if progress is None:
                return
            if label != shown[1] or fraction - shown[0] >= 0.005:
                shown[:] = [fraction, label]
                progress(fraction, label)

        while not self.warmup.wait(0.25, phase=self.phase):
            if cancel.is_set():
                raise JobCancelled("cancelled")
            report(0.0, "waiting for the warm-up")
        while not self._places.acquire(timeout=0.25):
            if cancel.is_set():
                raise JobCancelled("cancelled")
            report(0.0, "waiting for the previous request to stop")
        with self._idle:
            self._making += 1
        try:
            with self.workspace.request() as folder:
                try:
                    # each request on its share of the budget (--workers at once)
                    yield from shared_steps(run_job(
                        photo, folder, options=options, depth=depth, right=right, name=name,
                        progress=report, cancel=cancel), worker_share(self.workers))
                except JobCancelled:
                    self.workspace.discard(folder)
                    raise
        finally:
            with self._idle:
                self._making -= 1
            self._places.release()

    def stop(self, timeout: float = 10.0) -> bool:
        """Make running requests stop at their next progress report (their folders
        are removed), refuse new ones, and wait for them; False if some still run
        after ``timeout`` seconds."""
        with self._idle:
            self._stopping = True
            for cancel in self._running:
                cancel.set()
            return self._idle.wait_for(lambda: not self._running, timeout)
