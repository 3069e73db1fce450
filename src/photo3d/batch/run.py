"""``run_batch``: many photos to 3D photo folders, resumable, on a local pool or Ray."""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from photo3d.batch.jobs import MakeOptions, PhotoJob, output_problem
from photo3d.batch.lock import batch_lock
from photo3d.batch.manifest import (
    MANIFEST,
    ManifestRecords,
    ManifestWriter,
    PhotoResult,
    check_manifest,
    json_text,
)
from photo3d.batch.worker import discard_partial
from photo3d.errors import ConfigError, OutputError
from photo3d.output import is_complete

ENGINES = ("local", "ray")

PhotoProgress = Callable[[PhotoResult, int, int], None]
"""``progress(result, done, total)`` after each photo (skipped ones included)."""


@dataclass(frozen=True)
class BatchSummary:
    """How a batch went.

    Attributes:
        ok: photos made in this run.
        failed: photos that failed (each with its message in the manifest).
        skipped: photos finished by an earlier run.
        seconds: wall time of the run.
        manifest: the manifest file.
        failures: ``(name, error)`` of each failed photo.
        notes: one-line warnings about the batch itself (bad manifest lines).
    """

    ok: int
    failed: int
    skipped: int
    seconds: float
    manifest: Path
    failures: tuple[tuple[str, str], ...] = ()
    notes: tuple[str, ...] = ()


def check_out_dir(out: Path) -> Path:
    """Create the batch's output folder if needed; refuse one that cannot be written,
    or whose manifest is a symbolic link or a file photo3d did not write
    (:func:`~photo3d.batch.manifest.check_manifest`)."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise OutputError(f"output {out} exists and is not a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputError(f"cannot create output folder {out}: {err.strerror or err}") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise OutputError(f"output folder {out} is not writable")
    check_manifest(out / MANIFEST)
    return out


def run_batch(jobs: Sequence[PhotoJob], out: str | Path, options: MakeOptions | None = None,
              *, engine: str = "local", workers: int | None = None,
              ray_address: str | None = None,
              progress: PhotoProgress | None = None) -> BatchSummary:
    """Make every photo of ``jobs`` into ``out/<name>/``, skipping finished ones.

    A photo counts as finished when its folder is complete (folders are written
    atomically, so an interrupted photo leaves none); failed photos are tried again
    on the next run. Every result is recorded in ``out/batch.jsonl`` as soon as it
    is known.

    Every job gets exactly one result: a job whose name cannot be an output folder
    inside ``out`` (:func:`~photo3d.batch.jobs.output_problem`) fails alone, a
    photo whose manifest record is unreadable is made again (``notes`` says so),
    and the temporary folders that killed workers of an earlier run left are
    removed first.

    Args:
        jobs: from :func:`photo3d.batch.find_photos`.
        out: the output folder (created if needed).
        options: the ``make`` options (default: ``photo3d make``'s).
        engine: ``"local"`` (a process pool) or ``"ray"``.
        workers: processes or Ray actors (default: the CPU cores, or the Ray
            cluster's CPUs).
        ray_address: the Ray cluster (default: ``RAY_ADDRESS``, else a local Ray).
        progress: called after each photo.

    Returns:
        :class:`BatchSummary`.

    Raises:
        OutputError: another batch is writing ``out`` (``out/batch.lock``), the
            manifest is a symbolic link or cannot be written (full disk).
        KeyboardInterrupt: Ctrl-C; the workers are stopped, nothing partial is
            left and the manifest holds every photo finished so far.

    Example:
        >>> import tempfile, numpy as np
        >>> from photo3d.batch import find_photos
        >>> from photo3d.config import Config
        >>> from photo3d.save_options import SaveOptions
        >>> from photo3d.io.images import write_image
        >>> d = Path(tempfile.mkdtemp()); (d / "depth").mkdir()
        >>> write_image(d / "a.png", np.full((32, 32, 3), 0.5, np.float32))
        >>> np.save(d / "depth" / "a.npy", np.ones((32, 32), np.float32))
        >>> jobs = find_photos(d, depth=d / "depth")
        >>> options = MakeOptions(config=Config(size=None),
        ...                       save=SaveOptions(glb=False, viewer=False))
        >>> s = run_batch(jobs, d / "out", options, workers=1)
        >>> s.ok, s.failed, s.skipped
        (1, 0, 0)
        >>> run_batch(jobs, d / "out", options, workers=1).skipped
        1
    """
    if engine not in ENGINES:
        raise ConfigError(f"engine must be one of {', '.join(ENGINES)}, got {engine!r}")
    if workers is not None and workers < 1:
        raise ConfigError(f"--workers must be at least 1, got {workers}")
    options = options or MakeOptions()
    if engine == "ray":
        from photo3d.batch.ray_engine import require_ray

        require_ray()  # before anything is written
    out = check_out_dir(Path(out))
    start = time.perf_counter()
    results: dict[str, PhotoResult] = {}  # by job name: every photo ends up here once

    with batch_lock(out), ManifestWriter(out / MANIFEST) as manifest:
        def record(result: PhotoResult) -> None:
            manifest.add(result)
            results[result.name] = result
            if progress:
                progress(result, len(results), len(jobs))

        notes = _notes(manifest.previous)
        good = []
        for job in jobs:
            problem = output_problem(job.name)
            if problem is None:
                good.append(job)
            else:
                record(PhotoResult(job.name, "failed", f"{job.image.name}: {problem} "
                                   "(rename the photo)", 0.0, ""))
        for job in good:  # what killed workers of an earlier run left (not a live make's)
            if _inside(out / job.name, out):
                discard_partial(out / job.name)
        bad = manifest.previous.bad
        todo = [replace(j, redo=json_text(j.name) in bad) for j in good
                if options.overwrite or json_text(j.name) in bad or not is_complete(out / j.name)]
        names = {j.name for j in todo}
        for job in good:
            if job.name not in names:
                earlier = manifest.previous.records.get(json_text(job.name), {})
                record(PhotoResult(job.name, "skipped", None, 0.0, str(out / job.name),
                                   earlier.get("depth"), tuple(earlier.get("warnings", ()))))
        if todo:
            if engine == "ray":
                from photo3d.batch.ray_engine import run_ray

                run_ray(todo, out, options, workers=workers, address=ray_address,
                        on_result=record)
            else:
                from photo3d.batch.local import run_local
                from photo3d.parallel import threads

                count = min(workers or threads(), len(todo))
                run_local(todo, out, options, workers=count, on_result=record)
        for job in todo:  # an engine that lost a photo must not hide it
            if job.name not in results:
                record(PhotoResult(job.name, "failed", "no result came back for this photo",
                                   0.0, str(out / job.name)))
    counts = {status: sum(r.status == status for r in results.values())
              for status in ("ok", "failed", "skipped")}
    failures = tuple((r.name, r.error or "") for r in results.values() if r.status == "failed")
    return BatchSummary(counts["ok"], counts["failed"], counts["skipped"],
                        time.perf_counter() - start, out / MANIFEST, failures, notes)


def _notes(previous: ManifestRecords) -> tuple[str, ...]:
    """One line about the earlier manifest's bad lines, if any."""
    if not previous.problems:
        return ()
    shown = "; ".join(previous.problems[:3]) + ("; ..." if len(previous.problems) > 3 else "")
    return (f"{MANIFEST}: {len(previous.problems)} bad line(s) left out ({shown}); "
            "the photos they name are made again",)


def _inside(path: Path, out: Path) -> bool:
    """Whether ``path``'s folder is really inside ``out`` (no link leads elsewhere)."""
    real = os.path.realpath(path.parent)
    return os.path.commonpath([real, os.path.realpath(out)]) == os.path.realpath(out)
