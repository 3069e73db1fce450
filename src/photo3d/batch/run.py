"""``run_batch``: many photos to 3D photo folders, resumable, on a local pool or Ray."""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from photo3d.batch.jobs import MakeOptions, PhotoJob
from photo3d.batch.manifest import MANIFEST, ManifestWriter, PhotoResult
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
    """

    ok: int
    failed: int
    skipped: int
    seconds: float
    manifest: Path
    failures: tuple[tuple[str, str], ...] = ()


def check_out_dir(out: Path) -> Path:
    """Create the batch's output folder if needed; refuse one that cannot be written."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise OutputError(f"output {out} exists and is not a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputError(f"cannot create output folder {out}: {err.strerror or err}") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise OutputError(f"output folder {out} is not writable")
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
        KeyboardInterrupt: Ctrl-C; the workers are stopped, nothing partial is
            left and the manifest holds every photo finished so far.

    Example:
        >>> import tempfile, numpy as np
        >>> from photo3d.batch import find_photos
        >>> from photo3d.config import Config
        >>> from photo3d.io.images import write_image
        >>> d = Path(tempfile.mkdtemp()); (d / "depth").mkdir()
        >>> write_image(d / "a.png", np.full((32, 32, 3), 0.5, np.float32))
        >>> np.save(d / "depth" / "a.npy", np.ones((32, 32), np.float32))
        >>> jobs = find_photos(d, depth=d / "depth")
        >>> options = MakeOptions(config=Config(size=None), glb=False, viewer=False)
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
    out = check_out_dir(Path(out))
    start = time.perf_counter()
    counts = {"ok": 0, "failed": 0, "skipped": 0}
    failures: list[tuple[str, str]] = []
    todo = [j for j in jobs if options.overwrite or not is_complete(out / j.name)]
    names = {j.name for j in todo}
    finished = [j for j in jobs if j.name not in names]

    with ManifestWriter(out / MANIFEST) as manifest:
        def record(result: PhotoResult) -> None:
            manifest.add(result)
            counts[result.status] += 1
            if result.status == "failed":
                failures.append((result.name, result.error or ""))
            if progress:
                progress(result, sum(counts.values()), len(jobs))

        for job in finished:
            earlier = manifest.previous.get(job.name, {})
            record(PhotoResult(job.name, "skipped", None, 0.0, str(out / job.name),
                               earlier.get("depth"), tuple(earlier.get("warnings", ()))))
        if todo:
            if engine == "ray":
                from photo3d.batch.ray_engine import run_ray

                run_ray(todo, out, options, workers=workers, address=ray_address,
                        on_result=record)
            else:
                from photo3d.batch.local import cpu_count, run_local

                count = min(workers or cpu_count(), len(todo))
                run_local(todo, out, options, workers=count, on_result=record)
    return BatchSummary(counts["ok"], counts["failed"], counts["skipped"],
                        time.perf_counter() - start, out / MANIFEST, tuple(failures))
