"""Concurrency's one home: how many cores this process may use, the share of them
each caller has, and every thread, thread pool, process pool and numba thread count
photo3d starts.

**The budget.** A process may use :func:`cores` cores: its CPU affinity, capped by
the cgroup CPU quota where one is set (a container limited to 2 CPUs on a 64-core
host gets 2, where ``os.cpu_count()`` says 64). The user may set the budget instead
(``--threads N``, or ``PHOTO3D_THREADS``; :func:`set_threads`), also above the core
count. :func:`threads` is the calling thread's budget: the process's, or the share
it was given (:func:`share`; the workers of a pool each get an equal share of the
caller's, a batch worker process ``budget // workers``).

**The pools.** Other modules never start a thread or a pool themselves, never call
``os.cpu_count`` and never set numba's or torch's thread counts (``tests/test_parallel.py``
scans the source; the web servers' own threads and Ray's are the exceptions). They ask:

* :func:`thread_pool` - up to ``threads()`` worker threads (fewer if the work has
  fewer parts), each running numba's parallel kernels on its share of the budget;
  :func:`map_ordered` and :func:`map_completed` map a function over items on one;
* :func:`overlap` - one thread beside the caller, for work that overlaps the
  caller's (a writer, an encoder, the next batch prepared);
  :func:`ahead` - an iterator's next item made on it;
* :func:`process_pool` - worker processes (``spawn``), each with its share;
* :func:`start_thread` - a long-lived service thread (the UI's requests, watchers);
  :func:`later` - a timer;
* :func:`spawn_python` - a helper Python process.

With a budget of one, :func:`thread_pool` and :func:`overlap` run each task in the
calling thread when it is submitted: the same results, no thread started.

Results never depend on the budget: every pool returns results in the order the
work was given, and the stages that split work merge it in a fixed order.

Example:
    >>> with thread_pool() as pool:
    ...     list(pool.map(lambda x: x * x, range(4)))
    [0, 1, 4, 9]
    >>> with share(1):
    ...     threads()
    1
"""

from __future__ import annotations

import functools
import math
import os
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from photo3d.errors import ConfigError

if TYPE_CHECKING:  # loaded when used: `import photo3d` stays light
    import subprocess
    from concurrent.futures import Executor, Future, ProcessPoolExecutor

__all__ = ["ENV", "MAX_THREADS", "Inline", "active_children", "affinity", "ahead", "cores",
           "idle_cores", "later", "library_defaults", "map_completed", "map_ordered", "overlap",
           "process_pool", "process_threads", "quota", "set_threads", "share", "shared_steps",
           "spawn_python", "start_thread", "thread_pool", "thread_safe_kernels", "threads",
           "width", "worker_share"]

ENV = "PHOTO3D_THREADS"
"""The environment variable that sets the process's budget (as ``--threads``)."""
MAX_THREADS = 1024
"""The largest budget ``--threads`` and ``PHOTO3D_THREADS`` take: numba and OpenMP start
a thread per unit of it (``10000`` started 10006 for a 64 px photo; ``10**20`` was a
traceback)."""

T = TypeVar("T")
R = TypeVar("R")

_budget: int | None = None  # set_threads()'s
_local = threading.local()  # .threads: this thread's share, when it was given one


# -- the budget ------------------------------------------------------------------------

def affinity() -> set[int] | None:
    """The cores this process may run on (its CPU affinity); None where the system
    cannot tell (not Linux).

    Example:
        >>> a = affinity()
        >>> a is None or len(a) >= 1
        True
    """
    try:
        return set(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return None


def quota(root: str | Path = "/") -> float | None:
    """The cgroup CPU quota of this process, in CPUs (``1.5``: one and a half
    cores' time per period), the smallest on the way up its cgroup tree; None where
    none is set or cgroups are not there. Reads cgroup v2's ``cpu.max`` and v1's
    ``cpu.cfs_quota_us`` / ``cpu.cfs_period_us``, wherever ``/proc/self/mountinfo``
    says they are mounted.

    Args:
        root: the file system root to read ``proc`` and ``sys`` under (tests give a
            folder that mimics them).

    Example:
        >>> q = quota()
        >>> q is None or q > 0
        True
    """
    root = Path(root)
    try:
        groups = (root / "proc/self/cgroup").read_text().splitlines()
        mounts = (root / "proc/self/mountinfo").read_text().splitlines()
    except OSError:
        return None
    found: list[float] = []
    for line in groups:
        ident, _, rest = line.partition(":")
        controllers, _, path = rest.partition(":")
        v2 = ident == "0" and controllers == ""
        if not v2 and "cpu" not in controllers.split(","):
            continue
        for mount_root, point in _cgroup_mounts(mounts, v2):
            if not (path + "/").startswith(mount_root.rstrip("/") + "/"):
                continue
            inside = path[len(mount_root.rstrip("/")):].strip("/")
            folder = root / point.lstrip("/") / inside
            top = root / point.lstrip("/")
            while True:
                cpus = _read_quota(folder, v2)
                if cpus is not None:
                    found.append(cpus)
                if folder == top or top not in folder.parents:
                    break
                folder = folder.parent
    return min(found) if found else None


def _cgroup_mounts(mounts: list[str], v2: bool) -> list[tuple[str, str]]:
    """``(root, mount point)`` of the cgroup2 mounts (``v2``) or of the cgroup v1
    mounts holding the ``cpu`` controller, from ``/proc/self/mountinfo`` lines."""
    found = []
    for line in mounts:
        left, _, right = line.partition(" - ")
        fields, after = left.split(), right.split()
        if len(fields) < 5 or len(after) < 3:
            continue
        if v2 and after[0] == "cgroup2":
            found.append((fields[3], fields[4]))
        elif not v2 and after[0] == "cgroup" and "cpu" in after[2].split(","):
            found.append((fields[3], fields[4]))
    return found


def _read_quota(folder: Path, v2: bool) -> float | None:
    """The quota set in one cgroup folder, in CPUs; None if none (or unreadable)."""
    try:
        if v2:  # "max 100000" or "150000 100000"
            limit, period = [*(folder / "cpu.max").read_text().split(), "", ""][:2]
        else:
            limit = (folder / "cpu.cfs_quota_us").read_text().strip()
            period = (folder / "cpu.cfs_period_us").read_text().strip()
        if limit in ("max", "-1") or not period:
            return None
        cpus = int(limit) / int(period)
    except (OSError, ValueError, ZeroDivisionError):
        return None
    return cpus if cpus > 0 else None


@functools.lru_cache(maxsize=1)
def cores() -> int:
    """How many cores this process may use: its affinity, capped by its cgroup CPU
    quota rounded up (a quota of 1.5 CPUs gives 2), at least 1. Read once per process.

    Example:
        >>> cores() >= 1
        True
    """
    allowed = affinity()
    count = len(allowed) if allowed else (os.cpu_count() or 1)
    limit = quota()
    if limit is not None:
        count = min(count, math.ceil(limit - 1e-9))
    return max(1, count)


def process_threads() -> int:
    """The process's budget: :func:`set_threads`' value, else ``PHOTO3D_THREADS``,
    else :func:`cores`.

    Raises:
        ConfigError: ``PHOTO3D_THREADS`` is not a whole number from 1 to :data:`MAX_THREADS`.

    Example:
        >>> process_threads() >= 1
        True
    """
    if _budget is not None:
        return _budget
    text = os.environ.get(ENV, "").strip()
    if text:
        return _count(text, ENV)
    return cores()


def threads() -> int:
    """The calling thread's budget: the share it was given (a pool's worker, a
    :func:`share` block), else the process's (:func:`process_threads`).

    Example:
        >>> threads() >= 1
        True
    """
    given = getattr(_local, "threads", None)
    return given if given is not None else process_threads()


def worker_share(workers: int, budget: int | None = None) -> int:
    """Each of ``workers``' share of ``budget`` (default: :func:`threads`), at least 1.

    Example:
        >>> worker_share(4, 16), worker_share(3, 2)
        (4, 1)
    """
    return max(1, (threads() if budget is None else budget) // max(1, workers))


def set_threads(count: int) -> None:
    """Set the process's budget to ``count`` threads (``--threads``): numba's threads
    (for libraries not loaded yet, through ``NUMBA_NUM_THREADS`` and
    ``OMP_NUM_THREADS``, which they read when they load) and torch's, if loaded.

    Raises:
        ConfigError: ``count`` is not from 1 to :data:`MAX_THREADS`.

    Example:
        >>> before = process_threads()
        >>> set_threads(3); process_threads()
        3
        >>> set_threads(before)
    """
    global _budget
    count = _count(count, "--threads")
    _budget = count
    _local.__dict__.pop("threads", None)
    _library_threads(count)


_LIBRARY_ENV = ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS")
"""The variables numba and torch size their pools by when they load."""


def _library_threads(count: int) -> None:
    """numba's and torch's threads to ``count``: set if loaded, else through
    :data:`_LIBRARY_ENV`, which they read when they load."""
    if "numba" not in sys.modules:
        os.environ["NUMBA_NUM_THREADS"] = str(count)
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(count)
    else:
        os.environ["OMP_NUM_THREADS"] = str(count)
    _numba_threads(count)


@contextmanager
def command_threads(count: int | None) -> Iterator[int]:
    """One command's budget: ``count`` threads (``--threads``; :func:`set_threads`)
    while the block runs, the process's earlier budget again after it (a program that
    runs several commands in one process, ``photo3d.cli.main`` from Python, gets each
    its own); ``None``: the process's budget, ``PHOTO3D_THREADS`` checked first.

    Raises:
        ConfigError: ``count`` or ``PHOTO3D_THREADS`` is not a whole number from 1 to
            :data:`MAX_THREADS`.

    Example:
        >>> before = process_threads()
        >>> with command_threads(3) as n:
        ...     n, process_threads()
        (3, 3)
        >>> process_threads() == before
        True
    """
    global _budget
    if count is None:
        yield process_threads()
        return
    before, env = _budget, {name: os.environ.get(name) for name in _LIBRARY_ENV}
    set_threads(count)
    try:
        yield process_threads()
    finally:
        _budget = before
        try:
            restored = process_threads()
        except ConfigError:  # a bad PHOTO3D_THREADS beside --threads: the next command says so
            restored = cores()
        _library_threads(restored)
        for name, value in env.items():  # a library not loaded yet: as it was
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def library_defaults() -> None:
    """Before numba or torch load: size their thread pools by this budget rather than
    by the host's core count (which ignores a cgroup quota), unless the user set
    ``NUMBA_NUM_THREADS`` / ``OMP_NUM_THREADS`` (``import photo3d`` calls this).

    Example:
        >>> library_defaults()  # no effect once numba is loaded
    """
    try:
        budget = str(process_threads())
    except ConfigError:  # reported when the budget is used
        return
    os.environ.setdefault("NUMBA_NUM_THREADS", budget)
    os.environ.setdefault("OMP_NUM_THREADS", budget)


@contextmanager
def share(count: int) -> Iterator[int]:
    """Within the block, the calling thread's budget is ``count`` (numba's threads too).

    Example:
        >>> with share(1) as n:
        ...     n, threads()
        (1, 1)
    """
    before = getattr(_local, "threads", None)
    _enter(count)
    try:
        yield count
    finally:
        if before is None:
            _local.__dict__.pop("threads", None)
            _numba_threads(process_threads())
        else:
            _enter(before)


def shared_steps(items: Iterator[T], count: int) -> Iterator[T]:
    """``items``, each made with the calling thread's budget at ``count`` (a
    generator that may be resumed from different threads: a web framework's).

    Example:
        >>> list(shared_steps((threads() for _ in range(2)), 1))
        [1, 1]
    """
    try:
        while True:
            with share(count):
                try:
                    item = next(items)
                except StopIteration:
                    return
            yield item
    finally:
        close = getattr(items, "close", None)
        if close is not None:
            close()


def _count(value: object, name: str) -> int:
    """``value`` as a thread count from 1 to :data:`MAX_THREADS`, else ConfigError
    naming ``name``."""
    try:
        count = int(str(value))
    except ValueError:
        count = 0
    if not 1 <= count <= MAX_THREADS:
        raise ConfigError(f"{name} must be a whole number from 1 to {MAX_THREADS}, "
                          f"got {value!r}")
    return count


def _enter(count: int) -> None:
    """Give the calling thread the budget ``count`` (and as many numba threads)."""
    _local.threads = max(1, int(count))
    _numba_threads(_local.threads)


def _numba_threads(count: int) -> None:
    """Set the calling thread's numba threads to ``count`` (at most numba's pool), if
    numba is loaded (else it starts with ``NUMBA_NUM_THREADS``, see :func:`set_threads`)."""
    numba = sys.modules.get("numba")
    if numba is None or not hasattr(numba, "set_num_threads"):
        return
    numba.set_num_threads(max(1, min(count, numba.config.NUMBA_NUM_THREADS)))


# -- thread pools ----------------------------------------------------------------------

class Inline:
    """An executor that runs each task in the calling thread as it is submitted (a
    budget of one: the same results, no thread).

    Example:
        >>> Inline().submit(pow, 2, 5).result()
        32
    """

    def submit(self, fn: Callable[..., T], /, *args: Any, **kwargs: Any) -> Future[T]:
        """Run ``fn(*args, **kwargs)`` now; its result (or exception) in a Future."""
        from concurrent.futures import Future

        future: Future = Future()
        future.set_running_or_notify_cancel()
        try:
            future.set_result(fn(*args, **kwargs))
        except Exception as err:  # handed to the caller by result(), as a pool does
            future.set_exception(err)
        return future

    def map(self, fn: Callable[..., T], *iterables: Any) -> Iterator[T]:
        """``fn`` over ``iterables``, each result computed when it is asked for."""
        return map(fn, *iterables)

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        """Nothing to stop."""

    def __enter__(self) -> Inline:
        return self

    def __exit__(self, *exc: object) -> None:
        self.shutdown()


def width(most: int | None = None) -> int:
    """How many threads :func:`thread_pool` ``(most)`` has: ``min(most, threads())``,
    at least 1.

    Example:
        >>> width(1), width() == threads()
        (1, True)
    """
    budget = threads()
    return budget if most is None else max(1, min(int(most), budget))


def thread_pool(most: int | None = None, *, name: str = "work") -> Executor | Inline:
    """A pool of ``min(most, threads())`` worker threads, each with an equal share of
    the caller's budget for numba's parallel kernels; with one, an :class:`Inline`
    executor. Use it as a context manager.

    Args:
        most: the work's parts (no more threads than that); None: the budget.
        name: the threads' names, ``photo3d-<name>_<i>``.

    Example:
        >>> with thread_pool(2, name="doc") as pool:
        ...     [f.result() for f in [pool.submit(len, "ab"), pool.submit(len, "c")]]
        [2, 1]
    """
    size = width(most)
    if size == 1:
        return Inline()
    return _pool(size, name, worker_share(size))


def map_ordered(fn: Callable[[T], R], items: Sequence[T], *,
                name: str = "map") -> Iterator[R]:
    """``fn(item)`` for each of ``items`` on a :func:`thread_pool`, yielded in order
    (with a budget of one, each computed when it is asked for).

    Example:
        >>> list(map_ordered(abs, [-1, 2, -3]))
        [1, 2, 3]
    """
    if threads() < 2 or len(items) < 2:
        yield from (fn(item) for item in items)
        return
    with thread_pool(len(items), name=name) as pool:
        yield from pool.map(fn, items)


def map_completed(fn: Callable[[T], R], items: Sequence[T], *,
                  name: str = "map") -> Iterator[tuple[int, R]]:
    """``(i, fn(items[i]))`` for each item on a :func:`thread_pool`, as each is done:
    submitted in the order given (give the largest first, so that no thread is left
    with one at the end while the others wait); with a budget of one, in order, each
    computed when it is asked for.

    Example:
        >>> sorted(map_completed(abs, [-1, 2]))
        [(0, 1), (1, 2)]
    """
    if threads() < 2 or len(items) < 2:
        yield from ((i, fn(item)) for i, item in enumerate(items))
        return
    from concurrent.futures import as_completed

    with thread_pool(len(items), name=name) as pool:
        futures = {pool.submit(fn, item): i for i, item in enumerate(items)}
        for future in as_completed(futures):
            yield futures[future], future.result()


def overlap(*, name: str = "overlap") -> Executor | Inline:
    """One thread beside the caller, for work that overlaps the caller's own (a
    writer, the video encoder, the frame's fill during the first pass): its tasks run
    in order, each on one numba thread. With a budget of one, an :class:`Inline`
    executor. Use it as a context manager.

    Example:
        >>> with overlap(name="doc") as side:
        ...     later = side.submit(sum, [1, 2, 3])
        ...     later.result()
        6
    """
    if threads() < 2:
        return Inline()
    return _pool(1, name, 1)


def _pool(size: int, name: str, share_each: int) -> Executor:
    """A thread pool that stops with the process (:mod:`photo3d.files.signals`): each
    task first checks that no signal asked the process to stop, and leaving its
    ``with`` block by an exception (Ctrl-C, an error) cancels the tasks not started,
    then waits for the running ones, which stop at their next check."""
    return _stopping_pool()(size, thread_name_prefix=f"photo3d-{name}", initializer=_enter,
                            initargs=(share_each,))


@functools.cache
def _stopping_pool() -> type:
    """:func:`_pool`'s executor class (made when first needed: ``concurrent.futures``
    loads then)."""
    from concurrent.futures import ThreadPoolExecutor

    class StoppingPool(ThreadPoolExecutor):
        def submit(self, fn, /, *args, **kwargs):
            return super().submit(_checked, fn, *args, **kwargs)

        def __exit__(self, exc_type, exc, traceback):
            self.shutdown(wait=True, cancel_futures=exc_type is not None)
            return False

    return StoppingPool


def _checked(fn: Callable[..., T], /, *args: Any, **kwargs: Any) -> T:
    """``fn(*args, **kwargs)`` unless a signal asked the process to stop."""
    from photo3d.files.stop import check

    check()
    return fn(*args, **kwargs)


def ahead(items: Iterator[T], *, name: str = "ahead") -> Iterator[T]:
    """``items``, each next one made on an :func:`overlap` thread while the caller
    works on the one before (the same items in the same order; an exception is
    raised where ``items`` raised it).

    Example:
        >>> list(ahead(iter(range(3))))
        [0, 1, 2]
    """
    end = object()
    with overlap(name=name) as side:
        coming = side.submit(next, items, end)
        while (item := coming.result()) is not end:
            coming = side.submit(next, items, end)
            yield item


def start_thread(target: Callable[[], object], *, name: str, daemon: bool = True,
                 threads: int | None = None) -> threading.Thread:
    """Start a long-lived thread (the UI's requests and sweeper, a watcher) running
    ``target()``; when a signal asks the process to stop, the interruption its work
    raises (:func:`photo3d.files.stop.check`) ends the thread without a traceback.

    Args:
        target: the thread's work.
        name: the thread's name (``photo3d-`` is prefixed).
        daemon: the process may exit while it runs.
        threads: its budget (a share of the caller's); None: the process's.

    Example:
        >>> seen = []
        >>> start_thread(lambda: seen.append(threads()), name="doc", threads=1).join()
        >>> seen
        [1]
    """

    def run() -> None:
        if threads is not None:
            _enter(threads)
        try:
            target()
        except KeyboardInterrupt:  # a signal asked the process to stop (its work checks
            pass                   # photo3d.files.stop.check): the thread ends quietly

    thread = threading.Thread(target=run, name=f"photo3d-{name}", daemon=daemon)
    thread.start()
    return thread


def later(seconds: float, fn: Callable[..., object], *args: object) -> threading.Timer:
    """Call ``fn(*args)`` on a daemon thread ``seconds`` from now (a timer).

    Raises:
        RuntimeError: no thread can start (the interpreter is shutting down).

    Example:
        >>> done = threading.Event()
        >>> later(0.01, done.set).join()
        >>> done.is_set()
        True
    """
    timer = threading.Timer(seconds, fn, args)
    timer.daemon = True
    timer.start()
    return timer


# -- processes -------------------------------------------------------------------------

def process_pool(workers: int, *, initializer: Callable[..., object] | None = None,
                 initargs: tuple = ()) -> ProcessPoolExecutor:
    """``workers`` worker processes (``spawn``: nothing of this process's threads or
    torch state is forked), each with a budget of :func:`worker_share` of the
    caller's, set (:func:`set_threads`) before ``initializer(*initargs)`` runs.

    Example:
        >>> with process_pool(1) as pool:
        ...     pool.submit(abs, -3).result()
        3
    """
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    context = multiprocessing.get_context("spawn")
    return ProcessPoolExecutor(workers, mp_context=context, initializer=_process_start,
                               initargs=(worker_share(workers), initializer, initargs))


def _process_start(budget: int, initializer: Callable[..., object] | None,
                   initargs: tuple) -> None:
    """A worker process's start: its budget, then the caller's initializer."""
    set_threads(budget)
    if initializer is not None:
        initializer(*initargs)


def active_children() -> list:
    """The live child processes of this process's pools (:func:`process_pool`).

    Example:
        >>> isinstance(active_children(), list)
        True
    """
    import multiprocessing

    return multiprocessing.active_children()


def spawn_python(code: str, *args: str) -> subprocess.Popen | None:
    """Start ``python -c code args...`` (this interpreter), its output discarded;
    None if it cannot start.

    Example:
        >>> proc = spawn_python("pass")
        >>> proc is None or proc.wait() == 0
        True
    """
    import subprocess

    if not sys.executable:
        return None
    try:
        return subprocess.Popen([sys.executable, "-c", code, *args], stdin=subprocess.DEVNULL,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    except OSError:
        return None


def idle_cores(interval: float) -> float | None:
    """How many of this process's cores (:func:`affinity`) the machine left idle, on
    average, over the next ``interval`` seconds (``/proc/stat``'s idle and iowait
    time of each); None where it cannot tell. The cgroup quota is not counted here:
    :func:`cores` caps by it.

    Example:
        >>> idle = idle_cores(0.05)
        >>> idle is None or 0.0 <= idle <= len(affinity() or range(os.cpu_count() or 1))
        True
    """
    allowed = affinity()

    def times() -> tuple[int, int]:
        idle = total = 0
        with open("/proc/stat", encoding="ascii") as f:
            for line in f:
                name, *values = line.split()
                if not name.startswith("cpu") or name == "cpu":
                    continue
                if allowed is not None and int(name[3:]) not in allowed:
                    continue
                fields = [int(v) for v in values[:8]]  # user .. steal; guest is in user
                idle += fields[3] + fields[4]
                total += sum(fields)
        return idle, total

    try:
        idle0, total0 = times()
        time.sleep(interval)
        idle1, total1 = times()
    except (OSError, ValueError, IndexError):
        return None
    count = len(allowed) if allowed is not None else (os.cpu_count() or 1)
    if total1 <= total0:
        return None
    return count * (idle1 - idle0) / (total1 - total0)


# -- numba's threading layer -----------------------------------------------------------

def thread_safe_kernels() -> bool:
    """Have numba run parallel kernels of several threads at once (frames rendered at
    once, the UI's workers) if it can: its OpenMP and TBB threading layers can, its
    fallback (``workqueue``) cannot: it aborts the process. When no parallel kernel
    has run yet, a thread-safe layer is chosen if one is installed. Returns whether
    parallel kernels may run in several threads at once.

    Example:
        >>> thread_safe_kernels() in (True, False)
        True
    """
    import importlib

    import numba

    try:
        return numba.threading_layer() != "workqueue"  # already chosen in this process
    except ValueError:  # not chosen yet: choose a thread-safe one if there is one
        pass
    for layer in ("tbbpool", "omppool"):
        try:
            importlib.import_module(f"numba.np.ufunc.{layer}")
        except ImportError:
            continue
        if numba.config.THREADING_LAYER == "default":
            numba.config.THREADING_LAYER = "threadsafe"
        return numba.config.THREADING_LAYER in ("threadsafe", "tbb", "omp", "safe")
    return False
