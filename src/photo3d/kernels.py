"""The first run's "compiling, once" step: ``make``'s numba kernels compiled ahead.

photo3d's hot loops are numba kernels, compiled on first use and cached on disk
(numba's cache: ``__pycache__`` beside the sources, or ``NUMBA_CACHE_DIR``). The
very first run of an installation, or the first after numba or the sources change,
compiles them all (about 20 s of CPU); every later run loads them in a fraction of a
second. :func:`compile_kernels` does that part first, as one step the command line
shows. On an empty cache with a second core idle it shares the work between two
processes: this one compiles the list from its start while a helper process
(:func:`compile_from_end`) compiles it from its end, until they meet; the helper's
kernels are then loaded from the cache.

The list is every kernel module's ``KERNELS``: each kernel ``make`` runs with its
default options, and the argument types it gives it (``tests/test_kernels.py``
checks ``make`` gives no others, so nothing is compiled twice or left for later).

Example:
    >>> compiled = compile_kernels()   # compiles, or loads from numba's cache
    >>> compile_kernels()              # already in this process: nothing to do
    0
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from photo3d import parallel


def kernels() -> list[tuple[object, tuple[str, ...]]]:
    """``make``'s kernels in the order it runs them: ``(dispatcher, signatures)``
    pairs from the kernel modules' ``KERNELS`` (one pair per kernel)."""
    from photo3d.inpaint.continuation import KERNELS as CONTINUATION
    from photo3d.inpaint.diffusion import KERNELS as DIFFUSION
    from photo3d.inpaint.exemplar import KERNELS as EXEMPLAR
    from photo3d.mesh._charts import KERNELS as CHARTS
    from photo3d.mesh._collapse import KERNELS as COLLAPSE
    from photo3d.mesh._faces import KERNELS as FACES
    from photo3d.mesh._planar import KERNELS as PLANAR
    from photo3d.stages.align import KERNELS as ALIGN
    from photo3d.stages.edges import KERNELS as EDGES
    from photo3d.stages.filters import KERNELS as FILTERS
    from photo3d.stages.merge import KERNELS as MERGE
    from photo3d.stages.regions import KERNELS as REGIONS
    from photo3d.stages.silhouettes import KERNELS as SILHOUETTES

    pairs: dict[object, list[str]] = {}
    for kernel, signature in (*FILTERS, *ALIGN, *EDGES, *SILHOUETTES, *REGIONS, *DIFFUSION,
                              *CONTINUATION, *EXEMPLAR, *MERGE, *FACES, *PLANAR, *CHARTS,
                              *COLLAPSE):
        pairs.setdefault(kernel, []).append(signature)
    return [(kernel, tuple(sigs)) for kernel, sigs in pairs.items()]


def compile_kernels(progress: Callable[[float], None] | None = None, *,
                    helper: bool = True) -> int:
    """Compile, or load from numba's cache, every kernel of :func:`kernels`.

    Args:
        progress: ``progress(fraction)``, called only once something is compiled
            (a warm cache reports nothing).
        helper: once a kernel had to be compiled, start a helper process that
            compiles the list from its end, if a core is idle (:func:`spare_core`):
            two cores share the work.

    Returns:
        How many kernels this process compiled (0: all loaded from the cache).
    """
    from photo3d.kernel_cache import adopt

    todo = kernels()
    if not todo or not hasattr(todo[0][0], "compile"):  # NUMBA_DISABLE_JIT
        return 0
    adopt()  # the wheel's compiled kernels, if they fit: then nothing compiles here
    claims: Path | None = None
    proc = None
    compiled = 0
    shown = -1

    def report(done: int) -> None:
        nonlocal shown
        if compiled and progress is not None and done != shown:
            shown = done
            progress(done / len(todo))

    try:
        start = 0
        for start in range(len(todo) + 1):
            if start == len(todo) or (claims is not None and not _claim(claims, start)):
                break
            if _compile(*todo[start]):
                compiled += 1
                if claims is None and helper and len(todo) - start > 2 and spare_core():
                    claims = Path(tempfile.mkdtemp(prefix="photo3d-compile."))
                    for i in range(start + 1):
                        _claim(claims, i)
                    proc = _start_helper(claims)
            report(_done(claims, start + 1))
        while proc is not None and proc.poll() is None:
            report(_done(claims, start))
            time.sleep(0.1)
        for i in range(start, len(todo)):  # the helper's: loaded now (or compiled,
            compiled += _compile(*todo[i])  # if it could not finish them)
        report(len(todo))
    finally:
        if proc is not None and proc.poll() is None:
            proc.kill()
            proc.wait()
        if claims is not None:
            shutil.rmtree(claims, ignore_errors=True)
    return compiled


@contextmanager
def watch_compiles(busy: Callable[[bool], None]) -> Iterator[None]:
    """Within the block, ``busy(True)`` when numba starts compiling a kernel on first
    use (one outside :func:`kernels`, e.g. the renderer's) and ``busy(False)`` when it
    is done, so a progress bar can say so.

    Example:
        >>> import numba
        >>> seen = []
        >>> with watch_compiles(seen.append):
        ...     _ = numba.njit(lambda x: x + 1)(1)
        >>> seen
        [True, False]
    """
    from numba.core import event

    class Listener(event.Listener):
        depth = 0  # a kernel's helpers compile inside it: one report per kernel

        def on_start(self, ev) -> None:
            self.depth += 1
            if self.depth == 1:
                busy(True)

        def on_end(self, ev) -> None:
            self.depth -= 1
            if self.depth == 0:
                busy(False)

    listener = Listener()
    event.register("numba:compile", listener)
    try:
        yield
    finally:
        event.unregister("numba:compile", listener)


def spare_core(interval: float = 0.1) -> bool:
    """Whether a second core is idle for the helper process: more than one core this
    process may use (:func:`photo3d.parallel.cores`: affinity and cgroup quota), and
    over the next ``interval`` seconds the machine leaves idle this process's core
    (it sleeps meanwhile) and at least ``0.75`` of another. On a busy machine the
    helper would only add its start-up and the numba internals each process compiles
    for itself (about 3.5 s of CPU) to a run that gets no more CPU time for it.

    The idle time is measured now (``/proc/stat`` on Linux), not read from the load
    average, which trails by a minute: right after another run the load average
    still says busy on an idle machine. Where ``/proc/stat`` is missing, the
    1-minute load average below ``cores - 1`` decides.

    Example:
        >>> spare_core() in (True, False)
        True
    """
    if parallel.cores() < 2:  # affinity and cgroup quota
        return False
    idle = parallel.idle_cores(interval)
    if idle is not None:
        return idle >= 1.75
    try:
        load = os.getloadavg()[0]
    except (AttributeError, OSError):  # no load average (Windows)
        load = 0.0
    return load < parallel.cores() - 1


def compile_from_end(folder: str | Path) -> None:
    """The helper process's half of :func:`compile_kernels`: the kernels from the end
    of the list, each claimed first in ``folder`` (an empty file named by its index,
    created only if absent), until one is claimed already; a ``<index>.done`` file
    marks each one compiled."""
    folder = Path(folder)
    todo = kernels()
    for i in reversed(range(len(todo))):
        if not _claim(folder, i):
            return
        _compile(*todo[i])
        (folder / f"{i}.done").touch()


def _compile(kernel, signatures: tuple[str, ...]) -> bool:
    """Compile, or load from the cache, ``kernel`` for ``signatures``; True if any
    was compiled (the cache did not have it)."""
    from numba.core.sigutils import normalize_signature

    missed = sum(kernel.stats.cache_misses.values())
    for signature in signatures:
        # the argument types as a tuple, as a call gives them: numba's cache is keyed
        # by what compile() is given, and a string would be another key
        kernel.compile(tuple(normalize_signature(signature)[0]))
    return sum(kernel.stats.cache_misses.values()) > missed


def _claim(folder: Path, index: int) -> bool:
    """Claim kernel ``index`` for this process; False if the other has it."""
    try:
        os.close(os.open(folder / f"{index}.claim", os.O_CREAT | os.O_EXCL | os.O_WRONLY))
    except FileExistsError:
        return False
    return True


def _done(claims: Path | None, own: int) -> int:
    """Kernels compiled so far: ``own`` here, plus those the helper marked done."""
    return own + (len(list(claims.glob("*.done"))) if claims is not None else 0)


def _start_helper(claims: Path) -> subprocess.Popen | None:
    """Start :func:`compile_from_end` in a new process (None if it cannot start:
    this process then compiles everything itself)."""
    code = "import sys; from photo3d.kernels import compile_from_end; compile_from_end(sys.argv[1])"
    return parallel.spawn_python(code, str(claims))
