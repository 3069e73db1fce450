"""The local engine: a pool of worker processes, each with its models loaded once.

Built on :func:`photo3d.parallel.process_pool` (``spawn`` processes, so nothing of
the parent's threads or torch state is forked). Each worker builds one
:class:`~photo3d.batch.worker.PhotoMaker` in its initializer and gets a budget of
``threads // workers`` (numba's, torch's and every pool's in it), so the pool does not
oversubscribe the CPU. At most ``workers`` photos are in flight, so when a worker dies (killed for
memory, a crash in native code) the photos it may have held are known: a new
pool makes them again one at a time, and a photo that kills its worker twice
alone is recorded as failed. What the dead worker had staged is removed.

Workers exit when the batch process dies, even of SIGKILL
(:func:`exit_with_parent`).

Ctrl-C: workers ignore SIGINT; the parent stops submitting, sends SIGTERM to its
workers, and each worker busy with a photo removes its temporary output folder
before it exits (``save`` cleans up on any exception); once they are gone the
parent removes anything left of the photos that were in flight, so nothing
partial is left. The signal handlers are :mod:`photo3d.files.signals`'
(:func:`~photo3d.files.signals.worker_signals`,
:func:`~photo3d.files.signals.sigint_ignored`).
"""

from __future__ import annotations

import os
import signal
import sys
import time
from collections import deque
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Executor, wait
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

from photo3d.batch.jobs import MakeOptions, PhotoJob
from photo3d.batch.manifest import PhotoResult
from photo3d.batch.worker import PhotoMaker, discard_partial, one_line
from photo3d.files.signals import Interrupted, sigint_ignored, worker_signals
from photo3d.parallel import active_children, process_pool, start_thread

_PR_SET_PDEATHSIG = 1  # linux/prctl.h
_maker: PhotoMaker | None = None
_init_error: str | None = None
_busy = False


def _is_busy() -> bool:
    return _busy


def exit_with_parent(parent: int, *, poll: float = 1.0) -> None:
    """Have this worker process get SIGTERM when ``parent`` (the batch) dies.

    On Linux the kernel sends it (``prctl(PR_SET_PDEATHSIG)``); everywhere a
    daemon thread also checks every ``poll`` seconds that the parent is still
    ``parent``. SIGTERM makes a busy worker remove its temporary output first
    (:func:`~photo3d.files.signals.worker_signals`).
    """
    if sys.platform.startswith("linux"):
        import ctypes

        try:
            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)
        except (OSError, AttributeError):  # no prctl: the thread below is enough
            pass

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(poll)
        os.kill(os.getpid(), signal.SIGTERM)

    start_thread(watch, name="parent-watch")


def _init(options: MakeOptions, parent: int) -> None:
    global _maker, _init_error
    worker_signals(busy=_is_busy)  # SIGTERM raises Interrupted in _run, else exits
    exit_with_parent(parent)  # also when it died before this line: getppid() differs
    try:
        _maker = PhotoMaker(options)
    except Exception as err:  # each photo then fails with this message
        _init_error = one_line(err)


def _run(job: PhotoJob, out_dir: Path) -> PhotoResult:
    global _busy
    if _maker is None:
        return PhotoResult(job.name, "failed", _init_error, 0.0, str(Path(out_dir) / job.name))
    _busy = True
    try:
        return _maker(job, out_dir)
    except Interrupted:
        os._exit(1)  # the output's temporary folder is already gone
    finally:
        _busy = False


def run_local(jobs: Sequence[PhotoJob], out_dir: Path, options: MakeOptions, *,
              workers: int, on_result: Callable[[PhotoResult], None]) -> None:
    """Make every job on a pool of ``workers`` processes; ``on_result`` once for each.

    When a worker dies, the photos in flight are made again, each alone, so the
    one that kills its worker is known; a photo whose worker died while making it
    alone is tried once more, then recorded as failed.

    Raises:
        KeyboardInterrupt: after stopping the workers cleanly.
    """
    queue = deque(jobs)
    crashes: dict[str, int] = {}
    alone: set[str] = set()  # in flight when a worker died: made one at a time
    while queue:  # each worker with its share of the budget (parallel.process_pool)
        pool = process_pool(workers, initializer=_init, initargs=(options, os.getpid()))
        running: dict = {}
        try:
            while queue or running:
                while queue and len(running) < workers and not (
                        running and (queue[0].name in alone
                                     or any(j.name in alone for j in running.values()))):
                    with sigint_ignored():  # workers start with it ignored
                        future = pool.submit(_run, queue[0], out_dir)
                    running[future] = queue.popleft()
                done, _ = wait(running, return_when=FIRST_COMPLETED)
                for future in done:
                    result = future.result()  # BrokenProcessPool: a worker died
                    running.pop(future)
                    on_result(result)
        except BrokenProcessPool:
            pool.shutdown(wait=True, cancel_futures=True)  # every worker of it is gone
            lost = []
            for future, job in running.items():
                if future.done() and not future.cancelled() and future.exception() is None:
                    on_result(future.result())  # finished before the pool broke
                else:
                    lost.append(job)
            for job in reversed(lost):
                discard_partial(Path(out_dir) / job.name)
                if len(lost) == 1:  # alone: its own crash (with others: not known whose)
                    crashes[job.name] = crashes.get(job.name, 0) + 1
                if crashes.get(job.name, 0) >= 2:
                    on_result(PhotoResult(job.name, "failed", "the worker process making "
                                          "this photo died twice (out of memory?)", 0.0,
                                          str(Path(out_dir) / job.name)))
                else:
                    alone.add(job.name)  # made again, alone, so a culprit is known
                    queue.appendleft(job)
            running = {}
        except BaseException:
            _stop(pool)
            for job in running.values():  # belt and braces: all workers are gone now
                discard_partial(Path(out_dir) / job.name)
            raise
        finally:
            pool.shutdown(wait=True, cancel_futures=True)


def _stop(pool: Executor) -> None:
    """Stop the pool's workers now (SIGTERM: busy ones clean up their output first)."""
    pool.shutdown(wait=False, cancel_futures=True)
    children = active_children()
    for child in children:
        child.terminate()
    for child in children:
        child.join(timeout=60)
        if child.is_alive():
            child.kill()
