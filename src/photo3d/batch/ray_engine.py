"""The Ray engine: the same batch on a Ray cluster (or a local Ray), extra ``photo3d[ray]``.

Workers are Ray actors (one CPU each by default), each holding one
:class:`~photo3d.batch.worker.PhotoMaker`, so models load once per actor; each
actor makes one photo at a time. Photos are read and written through their
paths: on a cluster, the input, depth and output folders must be on a file
system every node sees at the same path (NFS, a mounted bucket, ...), and
photo3d must be installed on every node.

Connects to ``address`` (``--ray-address``), else to ``RAY_ADDRESS``, else starts
a local Ray on this machine. Connecting leaves this process' signal
handlers (and :mod:`faulthandler`) as they were, so Ctrl-C, SIGTERM and SIGHUP
act as with the local engine (:mod:`photo3d.files.signals`): the actors are
killed (actor tasks cannot be interrupted), the photos that had finished are
recorded, and the temporary folders of the photos being made are removed.

An actor that dies (killed for memory, a crash in native code, its node lost)
costs only its photo: what it had staged is removed and a new actor makes it again
(on a node with a free CPU: once nothing is left to send, idle actors are killed so
that a cluster that lost a node can place it), and a photo whose actor dies twice is
recorded as failed, as the local engine does.

Each actor reserves one CPU on a cluster (its share of the machine's on a local Ray)
and takes as many threads (:func:`granted_threads`), so a node of N CPUs runs N
actors of one thread each. How to run it on a real cluster: docs/speed.md, "Many
photos on a Ray cluster".
"""

from __future__ import annotations

import faulthandler
import logging
import os
import re
import signal
import socket
import time
from collections import deque
from collections.abc import Callable, Sequence
from pathlib import Path

from photo3d.batch.jobs import MakeOptions, PhotoJob
from photo3d.batch.manifest import PhotoResult
from photo3d.batch.worker import PhotoMaker, discard_partial, one_line
from photo3d.errors import ConfigError, Photo3DError, require
from photo3d.parallel import threads, worker_share

_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP")
                 if hasattr(signal, name))


def require_ray():
    """The ``ray`` module, or :class:`~photo3d.errors.MissingExtra` naming the extra.

    Example:
        >>> try:
        ...     ok = require_ray().__name__ == "ray"
        ... except ImportError as err:  # Ray is an extra
        ...     ok = "photo3d[ray]" in str(err)
        >>> ok
        True
    """
    return require("ray", "ray", purpose="--engine ray", package="Ray")


class _Actor:
    """The body of a Ray actor: one PhotoMaker, with a thread budget of the CPUs Ray
    gave it (:func:`granted_threads`)."""

    def __init__(self, options: MakeOptions) -> None:
        from photo3d.parallel import set_threads

        set_threads(granted_threads())  # the actor's budget: numba's, torch's, the pools'
        self.error: str | None = None
        try:
            self.maker = PhotoMaker(options)
        except Exception as err:  # each photo then fails with this message
            self.error = one_line(err)

    def make(self, job: PhotoJob, out_dir: str) -> PhotoResult:
        if self.error is not None:
            return PhotoResult(job.name, "failed", self.error, 0.0, str(Path(out_dir) / job.name))
        return self.maker(job, Path(out_dir))

    def where(self) -> tuple[str, int]:
        """``(host name, process id)`` of this actor."""
        return socket.gethostname(), os.getpid()


def granted_threads(resources: dict[str, float] | None = None) -> int:
    """An actor's thread budget: the CPUs Ray reserved for it (``resources``, default
    this Ray worker's, ``get_assigned_resources()``), whole ones, at least 1.

    On a cluster each actor asks for one CPU, so it gets one thread whatever the
    node's core count; on a local Ray each asks for its share of the CPUs.

    Example:
        >>> granted_threads({"CPU": 1.0}), granted_threads({"CPU": 4.0}), granted_threads({})
        (1, 4, 1)
    """
    if resources is None:
        resources = require_ray().get_runtime_context().get_assigned_resources()
    return max(1, int(resources.get("CPU", 0)))


def connect(address: str | None = None, *, local_cpus: int | None = None) -> str:
    """Connect to Ray (``address``, else ``RAY_ADDRESS``, else a new local Ray).

    ``ray.init`` sets its own SIGTERM handler (``sys.exit``) and turns on
    :mod:`faulthandler`; both are put back as they were.

    Returns:
        ``"running"`` (Ray was initialized already), ``"local"`` or the address
        connected to.
    """
    ray = require_ray()
    address = address or os.environ.get("RAY_ADDRESS") or None
    if ray.is_initialized():
        return "running"
    options = dict(logging_level=logging.ERROR, log_to_driver=False, include_dashboard=False)
    handlers = {signum: signal.getsignal(signum) for signum in _SIGNALS}
    fault = faulthandler.is_enabled()
    try:
        if address:
            ray.init(address=address, **options)
            return address
        # "local": a new Ray of this process's own, even where another Ray runs on this
        # machine (ray.init would join that one, and refuse num_cpus)
        ray.init(address="local", num_cpus=local_cpus, object_store_memory=200 * 1024**2,
                 **options)
    except (ConnectionError, RuntimeError, ValueError) as err:
        text = " ".join(str(err).split())[:200]
        raise Photo3DError(f"cannot connect to Ray at {address or 'a new local Ray'}: "
                           f"{text}") from None
    finally:
        _restore(handlers, fault)
    return "local"


def _restore(handlers: dict, fault: bool) -> None:
    """Put back the signal handlers (main thread only) and faulthandler's state."""
    try:
        for signum, handler in handlers.items():
            if handler is not None:  # None: set outside Python, cannot be put back
                signal.signal(signum, handler)
    except ValueError:  # not the main thread: Ray set none either
        pass
    if not fault and faulthandler.is_enabled():
        faulthandler.disable()


def run_ray(jobs: Sequence[PhotoJob], out_dir: Path, options: MakeOptions, *,
            workers: int | None, address: str | None,
            on_result: Callable[[PhotoResult], None]) -> None:
    """Make every job on Ray actors; ``on_result`` once for each (in the driver).

    ``workers``: number of actors (default: the cluster's CPUs, at most one per
    photo). Each actor reserves one CPU on a cluster, its share of this machine's
    CPUs on a local Ray, and takes as many threads (:func:`granted_threads`). A photo
    whose actor dies (or its node) is made again on a new actor; when that one dies
    too, the photo is recorded as failed.

    Raises:
        KeyboardInterrupt: after killing the actors, recording the photos that had
            finished and removing what the others had staged.
    """
    if workers is not None and workers < 1:
        raise ConfigError(f"--workers must be at least 1, got {workers}")
    ray = require_ray()
    started = connect(address, local_cpus=workers or threads())
    try:
        cpus = int(ray.cluster_resources().get("CPU", 1))
        count = max(1, min(workers or cpus, len(jobs)))
        # a local Ray's actors share this machine's CPUs; a cluster's reserve one each
        # (a larger share could fit no node of a cluster of small nodes)
        per_actor = worker_share(count, cpus) if started == "local" else 1
        out = Path(out_dir).resolve()  # absolute: actors may run elsewhere, in another cwd
        jobs = [PhotoJob(j.name, j.image.resolve(), j.depth.resolve() if j.depth else None,
                         j.redo) for j in jobs]
        _Pool(ray, ray.remote(num_cpus=per_actor)(_Actor), count,
              (options,)).run(jobs, out, on_result)
    finally:
        if started != "running":  # a Ray this call started or connected to
            ray.shutdown()


def _why(err: BaseException) -> str:
    """Ray's error about a dead actor in short: its first sentence and the exit type.

    Example:
        >>> _why(RuntimeError("It died. class_name: A ... Worker exit type: SYSTEM_ERROR x"))
        'RuntimeError: It died. (exit type SYSTEM_ERROR)'
    """
    text = one_line(err)
    kind = re.search(r"Worker exit type: (\w+)", text)
    cut = text.find(". ")
    text = text[:cut + 1] if cut > 0 else text
    return text[:200] + (f" (exit type {kind.group(1)})" if kind else "")


class _Pool:
    """``count`` actors, one photo at a time each; a dead actor is replaced.

    A photo is only sent to an actor that has started (its :meth:`_Actor.where` came
    back), and once no photo is left to send, the actors with nothing to do are
    killed: a cluster that lost a node may have no CPU for a replacement actor while
    the others hold theirs, and the photos left then go to the actors that remain.
    When an actor died, none is running or started and the cluster has had no CPU
    for :data:`_NO_CPU_S` (its nodes lost, none back: an autoscaler may add one
    meanwhile), the photos left are recorded as failed; so are they when ``count`` +
    :data:`_START_FAILURES` actors in a row die before they start and no actor is left.

    When an actor dies (its process, or its node), its process is waited for
    (:meth:`_wait_gone`) before what its photo had staged is removed, so that nothing
    it still writes is left behind.

    Stopping (Ctrl-C, SIGTERM, an error) kills every actor and waits until their
    processes are gone before removing what the photos in flight had staged: an actor
    that was still starting its photo when the kill was sent must not create its
    temporary folder after that removal. Each actor reports its host and process id
    first (:meth:`_Actor.where`, run before any photo: an actor runs its tasks in the
    order they were sent), which is how its end is seen on this host.
    """

    def __init__(self, ray, actor, count: int, args: tuple) -> None:
        self.ray, self.actor, self.count, self.args = ray, actor, count, args
        self.started: dict = {}  # actor handle -> ObjectRef of its where()

    def _start(self, starting: dict) -> None:
        actor = self.actor.remote(*self.args)
        self.started[actor] = ref = actor.where.remote()
        starting[ref] = actor

    def run(self, jobs: Sequence[PhotoJob], out: Path,
            on_result: Callable[[PhotoResult], None]) -> None:
        ray = self.ray
        queue = deque(jobs)
        running: dict = {}  # ObjectRef of make() -> (actor, job)
        starting: dict = {}  # ObjectRef of where() -> actor, not started yet
        idle: list = []  # started actors with nothing to do
        sending: list[PhotoJob] = []  # a job being sent (not in running yet)
        deaths: dict[str, int] = {}
        failed_starts = 0  # actors in a row that died before they started
        no_cpu_since: float | None = None  # the cluster had no CPU since, after a death
        try:
            for _ in range(self.count):
                self._start(starting)
            while queue or running:
                while queue and idle:
                    sending[:] = [queue[0]]  # until it is in running: see _stop
                    ref = idle[-1].make.remote(queue[0], str(out))
                    running[ref] = (idle.pop(), queue.popleft())
                    sending.clear()
                if not queue:  # their CPUs may be what a replacement actor waits for
                    self._kill([*idle, *starting.values()])
                    idle.clear()
                    starting.clear()
                    if not running:
                        break
                elif not (running or starting or idle):  # every actor died: a new one
                    self._start(starting)
                done, _ = ray.wait([*running, *starting], num_returns=1, timeout=_CHECK_S)
                if done or running or not (deaths or failed_starts):
                    no_cpu_since = None
                elif ray.cluster_resources().get("CPU"):
                    no_cpu_since = None
                elif no_cpu_since is None:
                    no_cpu_since = time.monotonic()
                elif time.monotonic() - no_cpu_since >= _NO_CPU_S:  # nodes lost, none back
                    self._fail_all(queue, out, on_result, "the Ray cluster has no CPU left")
                for ref in done:
                    if ref in starting:
                        actor = starting.pop(ref)
                        try:
                            ray.get(ref)
                        except ray.exceptions.RayError as err:  # died starting (its node?)
                            self._kill([actor])
                            failed_starts += 1
                            if failed_starts < self.count + _START_FAILURES:
                                if queue:
                                    self._start(starting)
                            elif not (running or idle):  # no actor left to make them
                                self._fail_all(queue, out, on_result, "no Ray actor could "
                                               f"start ({failed_starts} died): {_why(err)}")
                        else:
                            failed_starts = 0
                            idle.append(actor)
                        continue
                    actor, job = running[ref]  # until recorded: see _stop
                    try:
                        result = ray.get(ref)
                    except ray.exceptions.RayError as err:  # its actor died (memory, crash)
                        where = self.started.get(actor)
                        self._kill([actor])
                        if where is not None:  # nothing it still writes is left behind
                            self._wait_gone([where], deadline=time.monotonic() + _GONE_S)
                        discard_partial(out / job.name)
                        del running[ref]
                        self._start(starting)
                        deaths[job.name] = deaths.get(job.name, 0) + 1
                        if deaths[job.name] < 2:
                            queue.appendleft(job)  # again, on another actor
                            continue
                        result = PhotoResult(job.name, "failed", "the Ray actor making this "
                                             "photo died twice (out of memory? its node "
                                             f"lost?): {_why(err)}", 0.0, str(out / job.name))
                    else:
                        del running[ref]
                        idle.append(actor)
                    on_result(result)
        except BaseException:
            self._stop(running, sending, out, on_result)
            raise
        finally:  # every actor is gone at the end
            self._kill(list(self.started))

    @staticmethod
    def _fail_all(queue: deque, out: Path, on_result: Callable[[PhotoResult], None],
                  why: str) -> None:
        """Record every photo left in ``queue`` as failed with ``why``, and empty it."""
        while queue:
            job = queue.popleft()
            on_result(PhotoResult(job.name, "failed", why, 0.0, str(out / job.name)))

    def _stop(self, running: dict, sending: list[PhotoJob], out: Path,
              on_result: Callable[[PhotoResult], None]) -> None:
        """Record the photos that finished meanwhile, kill every actor, wait for them to
        be gone, then remove what the others had staged."""
        ray = self.ray
        try:
            refs = list(running)
            done = ray.wait(refs, num_returns=len(refs), timeout=0)[0] if refs else []
            for ref in done:
                try:
                    result = ray.get(ref, timeout=0)
                except ray.exceptions.RayError:  # died: cleaned up below
                    continue
                running.pop(ref)
                on_result(result)
        finally:
            started = dict(self.started)
            self._kill(list(started))
            self._wait_gone(started.values(), deadline=time.monotonic() + _GONE_S)
            # an actor that died of the signal itself was not waited for above: its
            # process may hold its staged folder a moment longer
            held = time.monotonic() + _HELD_S
            for job in [*(job for _, job in running.values()), *sending]:
                discard_partial(out / job.name, wait=max(0.0, held - time.monotonic()))

    def _kill(self, actors: list) -> None:
        for actor in actors:
            self.started.pop(actor, None)
            self.ray.kill(actor)

    def _wait_gone(self, where_refs, *, deadline: float) -> None:
        """Wait (until ``deadline``) for the processes of killed actors to end.

        An actor whose ``where()`` never ran made no photo. Ray's kill returns before the
        process is gone; an actor on another host is given :data:`_REMOTE_S` seconds.
        """
        ray, host, remote = self.ray, socket.gethostname(), False
        for ref in where_refs:
            try:
                name, pid = ray.get(ref, timeout=max(0.0, deadline - time.monotonic()))
            except ray.exceptions.RayError:  # killed before it ran: no photo started
                continue
            if name != host:
                remote = True
                continue
            while _alive(pid) and time.monotonic() < deadline:
                time.sleep(0.02)
        if remote:
            time.sleep(_REMOTE_S)


_GONE_S = 30.0
"""Longest wait for killed actors' processes to end before cleaning up."""
_HELD_S = 1.0
"""Longest wait, when stopping, for killed actors' staged folders to be let go (all of
them: a Ctrl-C stops a command within 2 s)."""
_REMOTE_S = 1.0
"""Wait after killing actors on other hosts (their processes cannot be watched)."""
_CHECK_S = 10.0
"""How often a batch waiting for actors to start checks that the cluster has a CPU."""
_NO_CPU_S = 60.0
"""How long a batch whose actors died waits for the cluster to have a CPU again."""
_START_FAILURES = 2
"""Actors dying in a row before they start, beyond the pool's size, after which no
more are started: the actors left make the remaining photos, or, with none left, the
photos are recorded as failed."""


def _alive(pid: int) -> bool:
    """Whether process ``pid`` of this host still runs (a zombie does not).

    Example:
        >>> _alive(os.getpid())
        True
    """
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            return f.read().rpartition(b")")[2].split()[0] != b"Z"
    except FileNotFoundError:  # gone meanwhile (no /proc at all: os.kill said it runs)
        return not os.path.isdir("/proc")
    except (OSError, IndexError):
        return True
