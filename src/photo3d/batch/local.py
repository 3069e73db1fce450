"""The local engine: a pool of worker processes, each with its models loaded once.

Built on :class:`concurrent.futures.ProcessPoolExecutor` (``spawn`` processes, so
nothing of the parent's threads or torch state is forked). Each worker builds one
:class:`~photo3d.batch.worker.PhotoMaker` in its initializer and gets
``cores // workers`` numba/torch threads, so the pool does not oversubscribe the
CPU. At most ``workers`` photos are in flight, so when a worker dies (killed for
memory, a crash in native code) the photos it may have held are known: they are
tried once more, then recorded as failed, and a new pool carries on.

Ctrl-C: workers ignore SIGINT; the parent stops submitting, sends SIGTERM to its
workers, and each worker busy with a photo removes its temporary output folder
before it exits (``save`` cleans up on any exception); once they are gone the
parent removes anything left of the photos that were in flight, so nothing
partial is left. The signal handlers are :mod:`photo3d.files.signals`'
(:func:`~photo3d.files.signals.worker_signals`,
:func:`~photo3d.files.signals.sigint_ignored`).
"""

from __future__ import annotations

import multiprocessing
import os
from collections import deque
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

from photo3d.batch.jobs import MakeOptions, PhotoJob
from photo3d.batch.manifest import PhotoResult
from photo3d.batch.worker import PhotoMaker, discard_partial, one_line
from photo3d.files.signals import Interrupted, sigint_ignored, worker_signals

_maker: PhotoMaker | None = None
_init_error: str | None = None
_busy = False


def cpu_count() -> int:
    """CPU cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def set_threads(threads: int) -> None:
    """Limit numba's (and torch's, if loaded) CPU threads in this process."""
    import sys

    import numba

    numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(max(1, threads))
    else:  # torch (depth model, learned nets) may be imported later: it reads this then
        os.environ["OMP_NUM_THREADS"] = str(max(1, threads))


def _is_busy() -> bool:
    return _busy


def _init(options: MakeOptions, threads: int) -> None:
    global _maker, _init_error
    worker_signals(busy=_is_busy)  # SIGTERM raises Interrupted in _run, else exits
    set_threads(threads)
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
    """Make every job on a pool of ``workers`` processes; ``on_result`` for each.

    Raises:
        KeyboardInterrupt: after stopping the workers cleanly.
    """
    threads = max(1, cpu_count() // workers)
    queue = deque(jobs)
    crashes: dict[str, int] = {}
    context = multiprocessing.get_context("spawn")
    while queue:
        pool = ProcessPoolExecutor(workers, mp_context=context, initializer=_init,
                                   initargs=(options, threads))
        running: dict = {}
        try:
            while queue or running:
                while queue and len(running) < workers:
                    job = queue.popleft()
                    with sigint_ignored():  # workers start with it ignored
                        running[pool.submit(_run, job, out_dir)] = job
                done, _ = wait(running, return_when=FIRST_COMPLETED)
                for future in done:
                    job = running.pop(future)
                    on_result(future.result())
        except BrokenProcessPool:
            for job in running.values():  # one of these killed its worker
                crashes[job.name] = crashes.get(job.name, 0) + 1
                if crashes[job.name] >= 2:
                    on_result(PhotoResult(job.name, "failed", "the worker process making "
                                          "this photo died (out of memory?)", 0.0,
                                          str(Path(out_dir) / job.name)))
                else:
                    queue.appendleft(job)
        except BaseException:
            _stop(pool)
            for job in running.values():  # belt and braces: all workers are gone now
                discard_partial(Path(out_dir) / job.name)
            raise
        finally:
            pool.shutdown(wait=True, cancel_futures=True)


def _stop(pool: ProcessPoolExecutor) -> None:
    """Stop the pool's workers now (SIGTERM: busy ones clean up their output first)."""
    pool.shutdown(wait=False, cancel_futures=True)
    children = multiprocessing.active_children()
    for child in children:
        child.terminate()
    for child in children:
        child.join(timeout=60)
        if child.is_alive():
            child.kill()
