"""The writers of several export formats on a pool of threads (``photo3d export`` and
``make --export``): what several formats share is built once (the splats, the light
textured mesh of ``mesh.usdz`` and the quilt), on the pool beside the rest, and the
thread that builds it goes on with the slowest file made of it."""

from __future__ import annotations

import contextlib
import functools
import importlib
from collections.abc import Callable, Sequence
from concurrent.futures import Executor, Future
from pathlib import Path
from typing import TYPE_CHECKING

from photo3d.export.formats import SPLATS_MODULE, Format
from photo3d.owned import recording
from photo3d.structures.ldi import LDI

if TYPE_CHECKING:
    from photo3d.structures.mesh import TexturedMesh
    from photo3d.structures.splats import Splats


def submit_writers(pool: Executor, ldi: LDI, targets: Sequence[tuple[Format, Path]], *,
                   density: str = "adaptive", spz_version: int = 3,
                   splat_fit: bool = True, mesh: TexturedMesh | None = None,
                   light_error: float | None = None,
                   record_in: Path | None = None,
                   splats: Splats | None = None) -> list[Future]:
    """Have ``pool`` write each ``(format, path)`` of ``targets``; returns the writers'
    futures, in the order of ``targets``.

    What several formats share is made once, each by one job of the pool: the light
    textured mesh that ``mesh.usdz`` and the quilt are made of (``mesh`` if given, as
    :func:`photo3d.output.save_photo` gives the one of ``mesh.glb``; else built by
    the pool's first job, with ``light_error``, None:
    :data:`~photo3d.mesh.light.LIGHT_ERROR`), and the splats when more than one
    splat format is asked for (the second job: with their colours fitted, about
    as long as the light mesh, so on two threads the two overlap). The thread that
    built one goes on with the slowest file made of it, and submits the others then
    (:func:`_chain`), so no thread waits for a build while a file could be written.
    Call :func:`preload` before the pool's threads (or any other) start.

    Args:
        pool: runs the jobs (:func:`~photo3d.parallel.thread_pool`: the writes, zlib and
            numpy release the GIL).
        ldi: the 3D photo's layered depth image.
        targets: what to write where (:func:`check_formats`' formats, each once).
        density: splat formats: ``"adaptive"`` or ``"dense"``.
        spz_version: ``splats.spz``'s version (3 or 4).
        splat_fit: fit the splats' colours (:mod:`photo3d.export.splat_fit`).
        mesh: the light textured mesh of ``ldi`` if already built.
        light_error: its error bound when it is built here (pixels).
        record_in: a 3D photo folder whose ``config.json`` records each file as it
            is moved into place (:func:`photo3d.owned.recording`); None: no record.
        splats: the splats of ``ldi`` with ``density`` (and ``splat_fit``) if already
            built.

    Example:
        >>> import numpy as np, pathlib, tempfile
        >>> from photo3d.export.formats import FORMATS
        >>> from photo3d.stages.ldi import from_image
        >>> ldi = from_image(np.full((16, 16, 3), 0.5, np.float32), np.ones((16, 16), np.float32))
        >>> out = pathlib.Path(tempfile.mkdtemp())
        >>> from photo3d.parallel import thread_pool
        >>> with thread_pool(2) as pool:
        ...     jobs = submit_writers(pool, ldi, [(FORMATS["splats.spz"], out / "a.spz"),
        ...                                       (FORMATS["splats.ply"], out / "a.ply")])
        ...     [job.result() for job in jobs]
        [None, None]
        >>> sorted(p.name for p in out.iterdir())
        ['a.ply', 'a.spz']
    """
    options: dict[str, object] = {"density": density, "spz_version": spz_version,
                                  "fit": splat_fit}

    def write(fmt: Format, path: Path, shared: dict[str, object]) -> None:
        known = options | shared  # shared: what _chain built, or the mesh given
        given = {k: known[k] for k in fmt.options if k in known}
        with recording(record_in) if record_in is not None else contextlib.nullcontext():
            fmt.load()(ldi, path, **given)

    builds: dict[str, Callable[[], object] | None] = {"mesh": None, "splats": None}
    if mesh is None and any("mesh" in f.options for f, _ in targets):
        from photo3d.mesh.light import LIGHT_ERROR, build_light_mesh

        builds["mesh"] = functools.partial(build_light_mesh, ldi, max_error=(
            LIGHT_ERROR if light_error is None else light_error))
    if splats is None and sum(f.module == SPLATS_MODULE for f, _ in targets) > 1:  # built once
        from photo3d.export.splats import build_splats

        builds["splats"] = functools.partial(build_splats, ldi, density=density,
                                             fit=splat_fit)
    given: dict[str, object] = {"mesh": mesh} if mesh is not None else {}
    if splats is not None:  # built already (counted against SPZ's limit)
        given["splats"] = splats
    order = sorted(range(len(targets)), key=lambda i: _SLOWEST_FIRST.index(targets[i][0].name))
    jobs: dict[int, Future] = {}
    for shared in ("mesh", "splats", None):  # the light mesh first: the longest chain
        group = [i for i in order if _shares(targets[i][0]) == shared]
        work = [functools.partial(write, *targets[i]) for i in group]
        if shared is not None and builds[shared] is not None:
            futures = _chain(pool, builds[shared], shared, work)
        else:
            futures = [pool.submit(job, given) for job in work]
        jobs |= dict(zip(group, futures, strict=True))
    return [jobs[i] for i in range(len(targets))]


_SLOWEST_FIRST = ("quilt", "splats.spz", "mesh.usdz", "splats.glb", "splats.ply")
"""The formats by the time their writer takes on the bundled sample (1.05, 0.30,
0.08, 0.08 and 0.05 s): a thread free takes the slowest first, so that none is left
alone with it at the end."""


def _shares(fmt: Format) -> str | None:
    """What ``fmt``'s writer takes that several formats share: ``"mesh"`` (the light
    textured mesh), ``"splats"`` or None."""
    return "mesh" if "mesh" in fmt.options else "splats" if fmt.module == SPLATS_MODULE else None


def _chain(pool: Executor, build: Callable[[], object], name: str,
           writers: Sequence[Callable[[dict[str, object]], None]]) -> list[Future]:
    """One job of ``pool`` that runs ``build()`` and then, in the same thread, the
    first of ``writers`` with ``{name: what it built}``, once it has submitted the
    others to ``pool``: no thread waits for the build, and the thread that built it
    goes on with the slowest writer. Returns a future per writer, which ends when
    that writer has ended (with the build's exception if the build failed: then no
    writer runs)."""
    from concurrent.futures import CancelledError

    futures: list[Future] = [Future() for _ in writers]

    def end(future: Future, job: Future) -> None:  # a job's end, copied into future
        if job.cancelled():
            future.set_exception(CancelledError())
        elif job.exception() is not None:
            future.set_exception(job.exception())
        else:
            future.set_result(job.result())

    def run() -> None:  # never raises: every future ends
        try:
            shared = {name: build()}
        except BaseException as err:  # noqa: BLE001 - handed to the callers by result()
            for future in futures:
                future.set_exception(err)
            return
        for writer, future in zip(writers[1:], futures[1:], strict=True):
            try:
                job = pool.submit(writer, shared)
            except BaseException as err:  # noqa: BLE001 - a pool shut down: the caller
                future.set_exception(err)  # is leaving
                continue
            job.add_done_callback(functools.partial(end, future))
        try:
            writers[0](shared)
        except BaseException as err:  # noqa: BLE001 - handed to the caller by result()
            futures[0].set_exception(err)
        else:
            futures[0].set_result(None)

    def ended(job: Future) -> None:  # stopped before it ran (a signal, a shutdown)
        if job.cancelled() or job.exception() is not None:
            for future in futures:
                if not future.done():
                    end(future, job)

    pool.submit(run).add_done_callback(ended)
    return futures


def preload(formats: Sequence[Format]) -> None:
    """Import the modules of ``formats`` that must not be imported while other
    threads run; call it before the writer threads start. The light mesh's numba
    kernels are loaded too (:func:`photo3d.mesh.light.load_kernels`), here in the
    calling thread, where a signal stops the loading at once (in a writer thread it
    could not: the process would stop a second later).

    usd-core's libraries, as they load, take the GIL back while the dynamic loader's
    lock is held; a thread running numpy meanwhile holds the GIL and waits for that
    lock (numpy calls ``dladdr`` to decide whether it may reuse a temporary array),
    and both wait for ever (seen once in about eight runs of ``photo3d export`` with
    all five formats, when ``mesh.usdz``'s writer thread imported usd-core while the
    quilt's built its mesh). A missing package is left for the writer to report
    (``MissingExtra``).

    Example:
        >>> from photo3d.export.formats import FORMATS
        >>> preload([FORMATS["splats.spz"]])  # nothing to import
    """
    if any("mesh" in fmt.options for fmt in formats):
        from photo3d.mesh.light import load_kernels

        load_kernels()
    for fmt in formats:
        for module in fmt.preload:
            try:
                importlib.import_module(module)
            except ImportError:  # the writer raises MissingExtra naming the extra
                break
