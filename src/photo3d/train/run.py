"""A training run: the loop that trains a net in its run folder, resuming, logging,
sampling, checkpointing and exporting.

:func:`train` opens the run folder (:mod:`photo3d.train.run_folder`: its layout, the
checks and the lock) and, running again in the same folder, resumes from the last
checkpoint; the step count continues and ``steps`` is the total to reach.

Every file is written atomically (:mod:`photo3d.files.atomic`) and every checkpoint
folder is staged (:mod:`photo3d.files.staging`), so an interrupted run never leaves
a half-written one; ``losses.csv`` is appended to, one row per step. A checkpoint
replaces or prunes only checkpoints the run recorded writing (``checkpoints.json``).
"""

from __future__ import annotations

import csv
import io
import math
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from photo3d.errors import ConfigError, InputError
from photo3d.files.atomic import atomic_path, open_append, write_bytes, write_json
from photo3d.files.staging import remove_leftovers, stage_output
from photo3d.io.bounded import read_json
from photo3d.train.dataset import TrainingData
from photo3d.train.grid import sample_grid
from photo3d.train.heldout import HeldoutLog, HeldoutSet, score_diffusion, score_net
from photo3d.train.run_folder import (
    MARKER,
    RECORD,
    check_checkpoints,
    checkpoints,
    open_run,
    release_run,
    written_checkpoints,
)
from photo3d.train.samples import make_batch
from photo3d.train.trainer import TrainConfig, Trainer, to_tensors

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
        elif any(k not in self.columns for k in terms):
            # a resumed run with a new term (e.g. an adversarial weight): widen the
            # header, earlier rows leave the new columns empty
            self.columns = [*self.columns, *(k for k in terms if k not in self.columns)]
            with open(self.path, newline="") as f:
                rows = list(csv.reader(f))[1:]
            n = len(self.columns)
            write_bytes(self.path, _csv_bytes([self.columns, *(r + [""] * (n - len(r))
                                                              for r in rows)]))
        values = {"step": step, "seconds": f"{seconds:.4f}",
                  **{k: f"{v:.6g}" for k, v in terms.items()}}
        with open_append(self.path) as f:
            csv.writer(f).writerow([values.get(c, "") for c in self.columns])


def train(data: TrainingData, run_dir: str | Path, config: TrainConfig, *,
          device=None, features=None, progress: StepProgress | None = None,
          heldout: HeldoutSet | None = None) -> TrainResult:
    """Train ``config.kind`` on ``data`` in ``run_dir`` (resuming if it holds a run).

    Args:
        data: prepared training data (:func:`photo3d.train.dataset.prepare_data`).
        run_dir: the run folder (created).
        config: :class:`TrainConfig`.
        device: torch device (default CUDA when available, else CPU).
        features: VGG-16 features for the colour loss (default: the ImageNet weights).
        progress: ``progress(step, total, losses)`` after each step.
        heldout: colour net only: score it on this set every ``config.heldout_every``
            steps, at the start of a fresh run and at the end, into ``heldout.csv``
            (the diffusion fill once, for reference; :mod:`photo3d.train.heldout`).

    Returns:
        :class:`TrainResult`.

    Raises:
        InputError: the data cannot train this net.
        ConfigError: ``run_dir`` holds a run with another architecture.
        OutputError: ``run_dir`` cannot be created, or a checkpoint name the run would
            write holds something it did not write (:func:`check_checkpoints`).

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
    run_dir = open_run(run_dir, config)
    try:
        return _train(data, run_dir, config, device=device, features=features,
                      progress=progress, heldout=heldout)
    finally:
        release_run(run_dir)


def _train(data: TrainingData, run_dir: Path, config: TrainConfig, *, device, features,
           progress: StepProgress | None, heldout: HeldoutSet | None) -> TrainResult:
    """:func:`train` in the run folder it opened and holds."""
    trainer = Trainer(config, device=device, features=features)
    saved = checkpoints(run_dir)
    check_checkpoints(run_dir, config, start=saved[-1][0] if saved else 0)
    start = _resume(trainer, saved[-1]) if saved else 0
    write_json(run_dir / MARKER, config.to_dict())
    log = _LossLog(run_dir / "losses.csv", start)
    scores = None
    if heldout is not None and config.kind == "color":
        scores = HeldoutLog(run_dir / "heldout.csv", start)
        if not scores.has("diffusion"):
            scores.add(0, "diffusion", score_diffusion(heldout))
        if not scores.has("net", start):
            scores.add(start, "net", score_net(heldout, trainer.net, trainer.device))
    terms: dict[str, float] = {}
    t_run = time.perf_counter()
    step = start
    refine = config.arch == "refine"
    for step in range(start + 1, config.steps + 1):
        t = time.perf_counter()
        samples = make_batch(data, config.kind, size=config.size, batch=config.batch,
                             seed=config.seed, step=step, refine=refine, swap=config.swap)
        batch = to_tensors(samples, trainer.device)
        terms, output = trainer.step(batch)
        _check_finite(terms, step, config)
        log.write(step, time.perf_counter() - t, terms)
        last = step == config.steps
        if step % config.sample_every == 0 or last:
            (run_dir / "samples").mkdir(exist_ok=True)
            with atomic_path(run_dir / "samples" / f"step_{step:07d}.png") as tmp:
                sample_grid(tmp, config.kind, samples, output.cpu().numpy())
        if step % config.checkpoint_every == 0 or last:
            _checkpoint(trainer, run_dir, step)
        if scores is not None and (step % config.heldout_every == 0 or last):
            scores.add(step, "net", score_net(heldout, trainer.net, trainer.device))
        if progress is not None:
            progress(step, config.steps, terms)
    seconds = time.perf_counter() - t_run
    weights = run_dir / f"{config.kind}.safetensors"
    with atomic_path(weights) as tmp:
        trainer.export(tmp)
    return TrainResult(run_dir, start, max(step, start), weights, terms, seconds)


def _check_finite(terms: dict[str, float], step: int, config: TrainConfig) -> None:
    """Raise ConfigError if a loss of ``step`` is NaN or infinite: the net's weights
    are then NaN too, and nothing of the step may be saved."""
    bad = [name for name, value in terms.items() if not math.isfinite(value)]
    if bad:
        raise ConfigError(f"training diverged at step {step} (the {bad[0]} loss is "
                          f"{terms[bad[0]]}, --lr {config.lr:g}); nothing of that step was "
                          "saved: lower --lr (a run resumes from its last checkpoint; a "
                          "new --out folder starts over)")


def _resume(trainer: Trainer, checkpoint: tuple[int, Path]) -> int:
    """Load the checkpoint ``(step, folder)``; a damaged ``state.json`` is one line."""
    step, folder = checkpoint
    path = folder / "state.json"
    try:
        state = read_json(path, max_bytes=1 << 20)
        ok = isinstance(state, dict) and state.get("step") == step
    except (OSError, InputError):
        ok = False
    if not ok:
        raise InputError(f"checkpoint {path} is damaged (not the state of step {step}); "
                         f"remove {folder} to resume from the checkpoint before it")
    return trainer.load(folder)


def _checkpoint(trainer: Trainer, run_dir: Path, step: int) -> None:
    """Write ``checkpoints/step_NNNNNNN/`` (staged, replacing only a checkpoint this run
    wrote), record it, and keep the last :data:`KEEP` of those the run recorded."""
    name = f"step_{step:07d}"
    folder = run_dir / "checkpoints" / name
    written = written_checkpoints(run_dir)

    def owned(existing: Path) -> list[str]:
        return [] if name in written and not folder.is_symlink() else [
            "was not written by this run"]

    (run_dir / "checkpoints").mkdir(exist_ok=True)
    remove_leftovers(folder)  # of a run killed while writing this checkpoint
    with stage_output(folder, overwrite=True, owned=owned) as staging:
        trainer.save(staging.path, step)
        staging.commit()
    written = [w for w in written if w != name] + [name]
    keep = sorted(written, key=lambda w: int(w[5:]))[-KEEP:]
    write_json(run_dir / RECORD, {"written": keep})  # first: a pruned name is never listed
    for old in written:
        path = run_dir / "checkpoints" / old
        if old not in keep and path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
