"""A training run in a folder: resume, loss log, sample grids, checkpoints, export.

``RUN_DIR`` layout::

    config.json                   the TrainConfig of the latest invocation
    data/                         prepared targets and region pool (reused if unchanged)
    losses.csv                    one row per step: step, seconds, loss terms
    heldout.csv                   held-out scores every heldout_every steps (with a
                                  held-out set; photo3d.train.heldout)
    samples/step_0000500.png      inputs | regions | output | target, 4 samples
    checkpoints/step_0000500/     see photo3d.train.trainer (the last 2 are kept)
    checkpoints.json              the checkpoint folders this run wrote (and kept)
    <kind>.safetensors            the final weights (photo3d make --weights RUN_DIR/..)

Running again in the same folder resumes from the last checkpoint; the step count
continues and ``steps`` is the total to reach.

Every file is written atomically (:mod:`photo3d.files.atomic`) and every checkpoint
folder is staged (:mod:`photo3d.files.staging`), so an interrupted run never leaves
a half-written one; ``losses.csv`` is appended to, one row per step.

Only checkpoints the run recorded writing (``checkpoints.json``, updated after each
one is in place) are ever replaced or pruned; anything else in ``checkpoints/`` (a
user's ``step_0000002_best/``, a symbolic link, checkpoints of a run saved before the
record existed) is left alone, and a checkpoint name the run would write that is
taken by something it did not write is refused before the work
(:func:`check_checkpoints`).
"""

from __future__ import annotations

import csv
import dataclasses
import io
import os
import re
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from photo3d.errors import ConfigError, InputError, OutputError
from photo3d.files.atomic import (
    atomic_path,
    open_append,
    refuse_symlink,
    write_bytes,
    write_json,
)
from photo3d.files.gate import try_lock, unlock
from photo3d.files.staging import remove_leftovers, stage_output
from photo3d.io.bounded import read_json
from photo3d.train.dataset import KINDS, TrainingData
from photo3d.train.grid import sample_grid
from photo3d.train.heldout import HeldoutLog, HeldoutSet, score_diffusion, score_net
from photo3d.train.samples import make_batch
from photo3d.train.trainer import ARCHITECTURE, TrainConfig, Trainer, to_tensors

StepProgress = Callable[[int, int, dict[str, float]], None]
"""``progress(step, total, losses)`` after every optimisation step."""
KEEP = 2
"""Checkpoints kept in ``checkpoints/``."""
RECORD = "checkpoints.json"
"""The list of the checkpoint folders a run wrote (``{"written": ["step_0000500"]}``)."""
_STEP = re.compile(r"step_([0-9]{7,})")


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
    found = [(int(m.group(1)), p) for p in folder.glob("step_*")
             if (m := _STEP.fullmatch(p.name)) and p.is_dir() and (p / "state.json").is_file()]
    return sorted(found)


def written_checkpoints(run_dir: str | Path) -> list[str]:
    """The names of the checkpoint folders the run in ``run_dir`` recorded writing
    (:data:`RECORD`; none if it is missing or damaged).

    Example:
        >>> import tempfile
        >>> written_checkpoints(tempfile.mkdtemp())
        []
    """
    path = Path(run_dir) / RECORD
    try:
        if path.is_symlink() or path.stat().st_size > 1 << 20:
            return []
        written = read_json(path, max_bytes=1 << 20).get("written")
    except (OSError, InputError, AttributeError):
        return []
    if not isinstance(written, list):
        return []
    return [w for w in written if isinstance(w, str) and _STEP.fullmatch(w)]


def check_checkpoints(run_dir: str | Path, config: TrainConfig, *, start: int = 0) -> None:
    """Refuse, before the work, a checkpoint name the run will write that holds
    something the run did not write (nothing is replaced but its own checkpoints).

    ``start``: the step the run resumes from.

    Raises:
        OutputError: one line naming the folder.

    Example:
        >>> import tempfile
        >>> run = Path(tempfile.mkdtemp())
        >>> (run / "checkpoints" / "step_0000004").mkdir(parents=True)
        >>> try:
        ...     check_checkpoints(run, TrainConfig("depth", levels=3, size=32, steps=4))
        ... except OutputError as err:
        ...     print(str(err).split(" exists")[0].endswith("step_0000004"))
        True
    """
    folder = Path(run_dir) / "checkpoints"
    if not folder.is_dir():
        return
    ours = set(written_checkpoints(run_dir))
    every = config.checkpoint_every
    for entry in folder.iterdir():
        m = _STEP.fullmatch(entry.name)
        if m is None or entry.name in ours:
            continue
        step = int(m.group(1))
        if start < step <= config.steps and (step % every == 0 or step == config.steps):
            raise OutputError(f"{entry} exists and this run did not write it; move it away "
                              "(nothing was written)")


MARKER = "config.json"
"""The file that makes a folder a photo3d training run (a :class:`TrainConfig` as JSON)."""
_MARKER_KEYS = frozenset({"kind", "width", "size", "batch", "steps"})


def run_config(run_dir: str | Path) -> dict | None:
    """The saved config of the photo3d training run in ``run_dir``, None if it holds none.

    A folder is a training run if its :data:`MARKER` is a JSON object of
    :class:`TrainConfig` fields (at least ``kind``, ``width``, ``size``, ``batch`` and
    ``steps``, with a known ``kind``).

    Raises:
        OutputError: ``run_dir`` exists, is not empty and is not a photo3d training
            run (one line, naming the reason); nothing is written.

    Example:
        >>> import tempfile
        >>> run_config(tempfile.mkdtemp()) is None
        True
    """
    run_dir = Path(run_dir)
    if not run_dir.exists():
        return None
    if not run_dir.is_dir():
        raise OutputError(f"run folder {run_dir} exists and is not a folder")
    if not any(run_dir.iterdir()):
        return None
    path = run_dir / MARKER
    reason = ""
    try:
        if not os.path.lexists(path):
            raise FileNotFoundError(path)
        old = read_json(path, max_bytes=1 << 20)
    except FileNotFoundError:
        reason = f"it has no {MARKER}"
    except (OSError, InputError) as err:
        reason = f"its {MARKER} cannot be read ({str(err).splitlines()[0]})"
    else:
        fields = {f.name for f in dataclasses.fields(TrainConfig)}
        if (not isinstance(old, dict) or not _MARKER_KEYS <= set(old) <= fields
                or old["kind"] not in KINDS):
            reason = f"its {MARKER} is not a photo3d training config"
    if reason:
        raise OutputError(f"run folder {run_dir} is not empty and is not a photo3d training run "
                          f"({reason}); choose a new folder")
    return old


def check_run(run_dir: str | Path, config: TrainConfig) -> None:
    """Check, writing nothing, that ``run_dir`` can take (or resume) a run of ``config``.

    Raises:
        OutputError: ``run_dir`` is not a folder, or not empty and not a photo3d
            training run (:func:`run_config`), or one of :data:`RUN_FILES` (or the
            final weights) in it is a symbolic link.
        ConfigError: it holds a run of another architecture.
    """
    old = run_config(run_dir)
    if old is not None:
        _check_architecture(Path(run_dir), old, config)
    for name in (*RUN_FILES, f"{config.kind}.safetensors"):
        refuse_symlink(Path(run_dir) / name, hint="remove it, or choose a new --out folder")


def open_run(run_dir: str | Path, config: TrainConfig) -> Path:
    """:func:`check_run`, then create ``run_dir`` and mark it as a run (its config).

    The marker is written only in a new run (a run being resumed keeps its config
    until :func:`train` starts), so an interrupted data preparation leaves a folder
    that the next run recognises and resumes. Returns ``run_dir`` as a Path.

    The folder is locked for this process (``flock``), so a second ``train`` on it
    is refused (``another photo3d train is running in RUN_DIR``) until this one ends.

    Raises:
        OutputError: as :func:`check_run`; another process holds the folder; or the
            folder or its marker cannot be written (read-only or full disk: one
            line, and the folders this call created are removed again).
    """
    run_dir = Path(run_dir)
    check_run(run_dir, config)
    made = [p for p in (*reversed(run_dir.parents), run_dir) if not p.exists()]
    try:
        run_dir.mkdir(parents=True, exist_ok=True)
        _hold(run_dir)
        if not (run_dir / MARKER).is_file():
            write_json(run_dir / MARKER, config.to_dict())
    except OSError as err:  # a read-only or full disk: one line, no empty folder left
        _remove_made(made)
        raise OutputError(f"cannot create the run folder {run_dir}: "
                          f"{err.strerror or err}") from None
    except OutputError:
        _remove_made(made)
        raise
    return run_dir


RUN_FILES = (MARKER, RECORD, "losses.csv", "heldout.csv", "samples", "checkpoints", "data")
"""What a run writes in its folder (and ``<kind>.safetensors``): none may be a
symbolic link (:func:`check_run`), so nothing is written outside the folder."""

_HELD: dict[str, int] = {}
"""Run folders this process holds (real path -> the locked descriptor)."""


def _hold(run_dir: Path) -> None:
    """Lock ``run_dir`` for this process (once): a second ``train`` on the same folder
    is refused instead of both writing it. The lock goes with the process (or
    :func:`_release`)."""
    key = os.path.realpath(run_dir)
    if key in _HELD:
        return
    fd = try_lock(run_dir)
    if fd is None:
        raise OutputError(f"another photo3d train is running in {run_dir}; wait for it to "
                          "finish or choose another --out folder")
    _HELD[key] = fd


def _release(run_dir: Path) -> None:
    fd = _HELD.pop(os.path.realpath(run_dir), None)
    if fd is not None:
        unlock(fd)


_DEFAULTS = {"center": False, "arch": "partialconv", "channels": 16, "edges": True}
"""Values of the fields a run's config.json may lack (written before they existed)."""


def _check_architecture(run_dir: Path, old: dict, config: TrainConfig) -> None:
    unused = ("levels", "center") if config.kind == "edge" else ("blocks", "gan")
    if config.kind == "depth":
        unused += ("center",)
    if config.arch == "refine":
        unused = ("width", "center", "gan")
    else:
        unused += ("channels", "edges")
    for name in ARCHITECTURE:
        if name in unused:
            continue
        if old.get(name, _DEFAULTS.get(name)) != getattr(config, name):
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
        _release(run_dir)


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


def _remove_made(made: list[Path]) -> None:
    """Remove the folders of ``made`` (innermost last in the list) that are still empty."""
    for path in reversed(made):
        try:
            path.rmdir()
        except OSError:
            return
