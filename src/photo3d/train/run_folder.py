"""A training run's folder: what it holds, whether a run may use it, its checkpoints.

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

A folder is a run if its ``config.json`` is a :class:`TrainConfig` (:func:`run_config`);
:func:`open_run` checks it can take a run of a config (same architecture, no symbolic
link where the run writes), creates and marks it, and locks it for this process.
:mod:`photo3d.train.run` trains in it.

Only checkpoints the run recorded writing (``checkpoints.json``, updated after each
one is in place) are ever replaced or pruned; anything else in ``checkpoints/`` (a
user's ``step_0000002_best/``, a symbolic link, checkpoints of a run saved before the
record existed) is left alone, and a checkpoint name the run would write that is
taken by something it did not write is refused before the work
(:func:`check_checkpoints`).
"""

from __future__ import annotations

import dataclasses
import os
import re
from pathlib import Path

from photo3d.errors import ConfigError, InputError, OutputError
from photo3d.files.atomic import refuse_symlink, write_json
from photo3d.files.gate import try_lock, unlock
from photo3d.files.staging import remove_made_folders
from photo3d.io.bounded import read_json
from photo3d.train.dataset import KINDS
from photo3d.train.trainer import ARCHITECTURE, TrainConfig

RECORD = "checkpoints.json"
"""The list of the checkpoint folders a run wrote (``{"written": ["step_0000500"]}``)."""
_STEP = re.compile(r"step_([0-9]{7,})")


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
    until :func:`photo3d.train.run.train` starts), so an interrupted data preparation
    leaves a folder that the next run recognises and resumes. Returns ``run_dir`` as a Path.

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
        remove_made_folders(made)
        raise OutputError(f"cannot create the run folder {run_dir}: "
                          f"{err.strerror or err}") from None
    except OutputError:
        remove_made_folders(made)
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
    :func:`release_run`)."""
    key = os.path.realpath(run_dir)
    if key in _HELD:
        return
    fd = try_lock(run_dir)
    if fd is None:
        raise OutputError(f"another photo3d train is running in {run_dir}; wait for it to "
                          "finish or choose another --out folder")
    _HELD[key] = fd


def release_run(run_dir: Path) -> None:
    """Unlock ``run_dir`` (:func:`open_run` locked it); nothing if this process does
    not hold it."""
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


