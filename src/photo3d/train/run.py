"""A training run in a folder: resume, loss log, sample grids, checkpoints, export.

``RUN_DIR`` layout::

    config.json                   the TrainConfig of the latest invocation
    data/                         prepared targets and region pool (reused if unchanged)
    losses.csv                    one row per step: step, seconds, loss terms
    samples/step_0000500.png      inputs | regions | output | target, 4 samples
    checkpoints/step_0000500/     see photo3d.train.trainer (the last 2 are kept)
    <kind>.safetensors            the final weights (photo3d make --weights RUN_DIR/..)

Running again in the same folder resumes from the last checkpoint; the step count
continues and ``steps`` is the total to reach.

Every file is written atomically (:mod:`photo3d.files.atomic`) and every checkpoint
folder is staged (:mod:`photo3d.files.staging`), so an interrupted run never leaves
a half-written one; ``losses.csv`` is appended to, one row per step.
"""

from __future__ import annotations

import csv
import io
import json
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from photo3d.errors import ConfigError
from photo3d.files.atomic import atomic_path, write_bytes, write_json
from photo3d.files.staging import remove_leftovers, stage_output
from photo3d.train.dataset import TrainingData
from photo3d.train.grid import sample_grid
from photo3d.train.samples import make_batch
from photo3d.train.trainer import ARCHITECTURE, TrainConfig, Trainer, to_tensors

StepProgress = Callable[[int, int, dict[str, float]], None]
"""``progress(step, total, losses)`` after every optimisation step."""
KEEP = 2
"""Checkpoints kept in ``checkpoints/``."""


@dataclass(frozen=True)
class TrainResult:
    """What a run did.

    Attributes:
        run_dir: the run folder.
        start_step: the step it resumed from (0 for a fresh run).
        step: the step reached.
        weights: the exported ``<kind>.safetensors``.
        losses: the last step's loss terms (empty if no step ran).
        seconds: wall time of the optimisation steps.
    """

    run_dir: Path
    start_step: int
    step: int
    weights: Path
    losses: dict[str, float]
    seconds: float


def checkpoints(run_dir: str | Path) -> list[tuple[int, Path]]:
    """Complete checkpoints of a run, ``(step, folder)`` in increasing step order.

    Example:
        >>> import tempfile
        >>> checkpoints(tempfile.mkdtemp())
        []
    """
    folder = Path(run_dir) / "checkpoints"
    if not folder.is_dir():
        return []
    found = [(int(p.name.split("_")[1]), p) for p in folder.glob("step_*")
             if p.is_dir() and p.name.split("_")[1].isdigit() and (p / "state.json").is_file()]
    return sorted(found)


def check_resumable(run_dir: Path, config: TrainConfig) -> None:
    """Raise :class:`ConfigError` if ``run_dir`` holds a run of another architecture."""
    path = run_dir / "config.json"
    if not path.is_file():
        return
    old = json.loads(path.read_text())
    unused = ("levels", "center") if config.kind == "edge" else ("blocks", "gan")
    if config.kind == "depth":
        unused += ("center",)
    for name in ARCHITECTURE:
        if name in unused:
            continue
        if old.get(name, False if name == "center" else None) != getattr(config, name):
            raise ConfigError(f"{run_dir} holds a {old.get('kind')} run with {name} "
                              f"{old.get(name)}, not {getattr(config, name)}: resume with the "
                              "same options or use a new --out folder")


def _csv_bytes(rows: list[list]) -> bytes:
    text = io.StringIO(newline="")
    csv.writer(text).writerows(rows)
    return text.getvalue().encode()


class _LossLog:
    """``losses.csv``, truncated to ``start`` on resume so steps never repeat.

    The header and the truncated log are written atomically; rows are appended.
    """

    def __init__(self, path: Path, start: int) -> None:
        self.path = path
        self.columns: list[str] | None = None
        if path.is_file():
            with open(path, newline="") as f:
                rows = list(csv.reader(f))
            if rows:
                self.columns = rows[0]
                kept = [r for r in rows[1:] if r and int(r[0]) <= start]
                write_bytes(path, _csv_bytes([rows[0], *kept]))

    def write(self, step: int, seconds: float, terms: dict[str, float]) -> None:
        if self.columns is None:
            self.columns = ["step", "seconds", *terms]
            write_bytes(self.path, _csv_bytes([self.columns]))
        values = {"step": step, "seconds": f"{seconds:.4f}",
                  **{k: f"{v:.6g}" for k, v in terms.items()}}
        with open(self.path, "a", newline="") as f:
            csv.writer(f).writerow([values.get(c, "") for c in self.columns])


def train(data: TrainingData, run_dir: str | Path, config: TrainConfig, *,
          device=None, features=None, progress: StepProgress | None = None) -> TrainResult:
    """Train ``config.kind`` on ``data`` in ``run_dir`` (resuming if it holds a run).

    Args:
        data: prepared training data (:func:`photo3d.train.dataset.prepare_data`).
        run_dir: the run folder (created).
        config: :class:`TrainConfig`.
        device: torch device (default CUDA when available, else CPU).
        features: VGG-16 features for the colour loss (default: the ImageNet weights).
        progress: ``progress(step, total, losses)`` after each step.

    Returns:
        :class:`TrainResult`.

    Raises:
        InputError: the data cannot train this net.
        ConfigError: ``run_dir`` holds a run with another architecture.

    Example:
        >>> import tempfile
        >>> import numpy as np
        >>> from photo3d.train.dataset import Target
        >>> from photo3d.train.pairs import RegionPair
        >>> ctx = np.zeros((24, 24), bool); ctx[:, :10] = True
        >>> photo = Target(np.full((32, 32, 3), 0.5, np.float32), np.full((32, 32), 0.5,
        ...                np.float32), np.zeros((32, 32), bool))
        >>> data = TrainingData(["a"], np.array([True]), [RegionPair(ctx, ~ctx, 1)], [photo])
        >>> cfg = TrainConfig("depth", levels=3, width=0.125, size=32, batch=2, steps=2)
        >>> r = train(data, tempfile.mkdtemp(), cfg, device="cpu")
        >>> r.step, r.weights.name
        (2, 'depth.safetensors')
    """
    data.check(config.kind)
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    check_resumable(run_dir, config)
    write_json(run_dir / "config.json", config.to_dict())
    trainer = Trainer(config, device=device, features=features)
    saved = checkpoints(run_dir)
    start = trainer.load(saved[-1][1]) if saved else 0
    log = _LossLog(run_dir / "losses.csv", start)
    terms: dict[str, float] = {}
    t_run = time.perf_counter()
    step = start
    for step in range(start + 1, config.steps + 1):
        t = time.perf_counter()
        samples = make_batch(data, config.kind, size=config.size, batch=config.batch,
                             seed=config.seed, step=step)
        batch = to_tensors(samples, trainer.device)
        terms, output = trainer.step(batch)
        log.write(step, time.perf_counter() - t, terms)
        last = step == config.steps
        if step % config.sample_every == 0 or last:
            (run_dir / "samples").mkdir(exist_ok=True)
            with atomic_path(run_dir / "samples" / f"step_{step:07d}.png") as tmp:
                sample_grid(tmp, config.kind, samples, output.cpu().numpy())
        if step % config.checkpoint_every == 0 or last:
            _checkpoint(trainer, run_dir, step)
        if progress is not None:
            progress(step, config.steps, terms)
    seconds = time.perf_counter() - t_run
    weights = run_dir / f"{config.kind}.safetensors"
    with atomic_path(weights) as tmp:
        trainer.export(tmp)
    return TrainResult(run_dir, start, max(step, start), weights, terms, seconds)


def _checkpoint(trainer: Trainer, run_dir: Path, step: int) -> None:
    """Write ``checkpoints/step_NNNNNNN/`` (staged, replacing one already there) and
    keep the last :data:`KEEP`."""
    folder = run_dir / "checkpoints" / f"step_{step:07d}"
    remove_leftovers(folder)  # of a run killed while writing this checkpoint
    with stage_output(folder, overwrite=True, owned=_run_owned) as staging:
        trainer.save(staging.path, step)
        staging.commit()
    for _, old in checkpoints(run_dir)[:-KEEP]:
        shutil.rmtree(old)


def _run_owned(folder: Path) -> list[str]:
    """``checkpoints/`` belongs to the run: whatever is there may be replaced."""
    return []
