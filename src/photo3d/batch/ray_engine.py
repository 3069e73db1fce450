"""The Ray engine: the same batch on a Ray cluster (or a local Ray), extra ``photo3d[ray]``.

Workers are Ray actors (one CPU each by default), each holding one
:class:`~photo3d.batch.worker.PhotoMaker`, so models load once per actor; Ray's
:class:`ray.util.ActorPool` hands the photos out (no scheduler of ours). Photos
are read and written through their paths: on a cluster, the input, depth and
output folders must be on a file system every node sees at the same path (NFS,
a mounted bucket, ...), and photo3d must be installed on every node.

Connects to ``address`` (``--ray-address``), else to ``RAY_ADDRESS``, else starts
a local Ray on this machine. Ctrl-C kills the actors (actor tasks cannot be
interrupted) and removes the temporary folders of the photos they were making. An
actor that dies (out of memory, a crash) stops the batch with a one-line error;
the same command resumes it.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from photo3d.batch.jobs import MakeOptions, PhotoJob
from photo3d.batch.manifest import PhotoResult
from photo3d.batch.worker import PhotoMaker, discard_partial
from photo3d.errors import ConfigError, Photo3DError, require


def _ray():
    return require("ray", "ray", purpose="--engine ray", package="Ray")


class _Actor:
    """The body of a Ray actor: one PhotoMaker, with its CPU threads limited."""

    def __init__(self, options: MakeOptions, threads: int) -> None:
        from photo3d.batch.local import set_threads

        set_threads(threads)
        self.maker = PhotoMaker(options)

    def make(self, job: PhotoJob, out_dir: str) -> PhotoResult:
        return self.maker(job, Path(out_dir))


def connect(address: str | None = None, *, local_cpus: int | None = None) -> str:
    """Connect to Ray (``address``, else ``RAY_ADDRESS``, else a new local Ray).

    Returns:
        ``"local"`` or the address connected to.
    """
    ray = _ray()
    address = address or os.environ.get("RAY_ADDRESS") or None
    if ray.is_initialized():
        return "running"
    options = dict(logging_level=logging.ERROR, log_to_driver=False, include_dashboard=False)
    try:
        if address:
            ray.init(address=address, **options)
            return address
        ray.init(num_cpus=local_cpus, object_store_memory=200 * 1024**2, **options)
    except (ConnectionError, RuntimeError, ValueError) as err:
        text = " ".join(str(err).split())[:200]
        raise Photo3DError(f"cannot connect to Ray at {address or 'a new local Ray'}: "
                           f"{text}") from None
    return "local"


def run_ray(jobs: Sequence[PhotoJob], out_dir: Path, options: MakeOptions, *,
            workers: int | None, address: str | None,
            on_result: Callable[[PhotoResult], None]) -> None:
    """Make every job on Ray actors; ``on_result`` for each (in the driver).

    ``workers``: number of actors (default: the cluster's CPUs, at most one per photo).
    """
    if workers is not None and workers < 1:
        raise ConfigError(f"--workers must be at least 1, got {workers}")
    ray = _ray()
    started = connect(address, local_cpus=workers)
    try:
        cpus = int(ray.cluster_resources().get("CPU", 1))
        count = max(1, min(workers or cpus, len(jobs)))
        threads = max(1, cpus // count) if started == "local" else 1
        actor = ray.remote(num_cpus=1)(_Actor)
        actors = [actor.remote(options, threads) for _ in range(count)]
        pool = ray.util.ActorPool(actors)
        out = str(Path(out_dir).resolve())
        # absolute paths: actors may run elsewhere, in another working directory
        jobs = [PhotoJob(j.name, j.image.resolve(), j.depth.resolve() if j.depth else None)
                for j in jobs]
        pending = {job.name: job for job in jobs}
        try:
            for job in jobs:
                pool.submit(lambda a, j: a.make.remote(j, out), job)
            while pool.has_next():
                try:
                    result = pool.get_next_unordered()
                except ray.exceptions.RayError as err:  # an actor died (memory, crash)
                    text = " ".join(str(err).split())[:200]
                    raise Photo3DError(f"a Ray worker died ({text}); run the same command "
                                       "again to resume") from None
                pending.pop(result.name, None)
                on_result(result)
        except BaseException:
            for a in actors:
                ray.kill(a)
            time.sleep(1.0)  # ray.kill returns before the actor processes are gone
            for job in pending.values():
                discard_partial(Path(out) / job.name)
            raise
    finally:
        if started == "local":
            ray.shutdown()
