"""Run evaluations over several pairs and write their tables, grids and JSON."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from photo3d.errors import InputError, OutputError
from photo3d.eval.evaluate import METHODS, evaluate, grid, table
from photo3d.eval.stereo_pair import StereoPair
from photo3d.files.atomic import atomic_path, check_writable, write_json, write_text
from photo3d.io.bounded import read_json


def mean_scores(per_pair: dict[str, dict]) -> dict:
    """Average every method/region/metric over the pairs that have it (NaN ignored).

    Args:
        per_pair: ``{pair: {method: {region: {metric: value}}}}``.

    Returns:
        ``{method: {region: {metric: mean}}}``.

    Example:
        >>> mean_scores({"a": {"m": {"all": {"psnr": 20.0}}},
        ...              "b": {"m": {"all": {"psnr": 30.0}}}})
        {'m': {'all': {'psnr': 25.0}}}
    """
    acc: dict = {}
    for scores in per_pair.values():
        for method, regions in scores.items():
            for region, metrics in regions.items():
                for metric, value in metrics.items():
                    acc.setdefault(method, {}).setdefault(region, {}).setdefault(
                        metric, []).append(value)
    return {m: {r: {k: float(np.nanmean(v)) for k, v in ms.items()} for r, ms in rs.items()}
            for m, rs in acc.items()}


def written_files(pairs: Sequence[str]) -> list[str]:
    """The names :func:`run` writes in its folder for ``pairs`` (and nothing else).

    Example:
        >>> written_files(["motorcycle"])
        ['results.json', 'results.md', 'grid_motorcycle.png']
    """
    return ["results.json", "results.md", *(f"grid_{name}.png" for name in pairs)]


def check_results_folder(out: str | Path, *, overwrite: bool) -> Path:
    """Refuse, before the evaluation, an ``out`` that :func:`run` may not write into.

    A new or empty folder is fine. An existing one needs ``overwrite`` and must be a
    results folder :func:`run` wrote (its ``results.json`` holds ``methods`` and
    ``pairs``); then :func:`run` replaces only the files it writes
    (:func:`written_files`) and leaves every other file alone. Returns ``out``.

    Raises:
        OutputError: one line: ``out`` is not a folder, is not empty (without
            ``overwrite``), or is not an evaluation results folder.

    Example:
        >>> import tempfile
        >>> folder = Path(tempfile.mkdtemp())
        >>> _ = (folder / "notes.txt").write_text("mine")
        >>> try:
        ...     check_results_folder(folder, overwrite=True)
        ... except OutputError as err:
        ...     "has no results.json of photo3d eval" in str(err)
        True
    """
    out = Path(out)
    if not out.exists():
        return out
    if not out.is_dir():
        raise OutputError(f"--out {out} exists and is not a folder")
    if not any(out.iterdir()):
        return out
    if not overwrite:
        raise OutputError(f"results folder {out} exists and is not empty (use --overwrite "
                          "to replace the results photo3d eval wrote)")
    try:
        record = read_json(out / "results.json", max_bytes=256 << 20)
        ours = isinstance(record, dict) and {"methods", "pairs"} <= set(record)
    except InputError:
        ours = False
    if not ours:
        raise OutputError(f"--overwrite only replaces results photo3d eval wrote, but {out} "
                          "has no results.json of photo3d eval: choose a new folder")
    return out


DEFAULT_OUT = Path("out/eval")
"""Where ``photo3d eval`` writes without ``-o``: the first free one of ``out/eval``,
``out/eval-2``, ... (:func:`new_results_folder`)."""


def new_results_folder(base: str | Path = DEFAULT_OUT) -> tuple[Path, Path]:
    """Create and return the first of ``base``, ``base-2``, ``base-3``, ... that does not
    exist, so that every run gets a folder of its own and none is replaced.

    The folder is created here (``mkdir``, which fails if another run took the name
    first: then the next name is tried), with its missing parents.

    Returns:
        ``(folder, outermost)``: the new folder, and the outermost folder this call
        created (``folder`` or one of its parents), to remove if the run fails.

    Raises:
        OutputError: one line: no folder can be created there.

    Example:
        >>> import tempfile
        >>> root = Path(tempfile.mkdtemp())
        >>> [new_results_folder(root / "out" / "eval")[0].name for _ in range(3)]
        ['eval', 'eval-2', 'eval-3']
    """
    base = Path(base)
    missing = [p for p in base.parents if not p.exists()]
    try:
        base.parent.mkdir(parents=True, exist_ok=True)
        for number in range(1, 100_000):
            folder = base if number == 1 else base.with_name(f"{base.name}-{number}")
            try:
                folder.mkdir()
            except FileExistsError:
                continue
            return folder, missing[-1] if missing else folder
    except OSError as err:
        raise OutputError(f"cannot create a results folder {base}: "
                          f"{err.strerror or err}") from None
    raise OutputError(f"every results folder {base}, {base}-2, ... exists: choose one with -o")


def _text(name: str) -> str:
    """A pair ``name`` (a file stem) for UTF-8 text: bytes of a file name that is not
    UTF-8 (held as lone surrogates, :func:`os.fsdecode`) become ``\\xNN`` escapes.

    Example:
        >>> import os
        >>> _text(os.fsdecode(b"caf\\xe9")), _text("café")
        ('caf\\\\xe9', 'café')
    """
    return name.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")


def run(pairs: dict[str, Callable[[], StereoPair]], out: str | Path, *,
        methods: Sequence[str] = METHODS, weights=None, lpips: bool = True,
        overwrite: bool = False, progress: Callable[[str], None] | None = None) -> dict:
    """Evaluate ``methods`` on each pair (built lazily) and write ``out/``.

    Writes ``results.json`` (all scores, notes, timings), ``results.md`` (one table
    per pair and the mean over pairs) and ``grid_<pair>.png`` (crops where methods
    differ most), each atomically (:mod:`photo3d.files.atomic`), and nothing else;
    ``out`` must be new or empty unless ``overwrite`` (then it must be a results
    folder of photo3d eval, and only these files are replaced: see
    :func:`check_results_folder`, checked here before the evaluation). Returns the
    JSON record.

    Raises:
        OutputError: ``out`` cannot be created or written, or is not empty (without
            ``overwrite``) or not a results folder (checked before the evaluation);
            files already there are kept as they were.

    Example:
        >>> import tempfile
        >>> from functools import partial
        >>> from photo3d.eval.synthetic import synthetic_pair
        >>> out = Path(tempfile.mkdtemp())
        >>> record = run({"s": partial(synthetic_pair, 0, width=64, height=48)}, out,
        ...              methods=["forward-warp"], lpips=False)
        >>> list(record["pairs"]), sorted(p.name for p in out.iterdir())
        (['s'], ['grid_s.png', 'results.json', 'results.md'])
    """
    from photo3d.io.images import write_image

    out = check_results_folder(out, overwrite=overwrite)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputError(f"cannot create the folder {out}: {err.strerror or err}") from None
    check_writable(out / "results.json")  # before the evaluation
    record: dict = {"methods": list(methods), "pairs": {}}
    md = []
    for name, build in pairs.items():
        if progress:
            progress(f"{name}: loading")
        t = time.perf_counter()
        pair = build()
        result = evaluate(pair, methods, weights=weights, lpips=lpips,
                          progress=(lambda m, n=name: progress(f"{n}: {m}")) if progress else None)
        record["pairs"][name] = {
            "scores": result.scores, "notes": result.notes, "seconds": time.perf_counter() - t,
            "disoccluded_fraction": float(result.regions["disoccluded"].mean()),
            "size": [pair.left.shape[1], pair.left.shape[0]],
        }
        with atomic_path(out / f"grid_{name}.png") as tmp:
            write_image(tmp, grid(pair, result))
        shown = _text(name)
        md += [f"### {shown}", "", table(result), "",
               f"Disoccluded: {100 * result.regions['disoccluded'].mean():.1f} % of the view; "
               f"crops: `grid_{shown}.png`.", ""]
    if len(record["pairs"]) > 1:
        record["mean"] = mean_scores({k: v["scores"] for k, v in record["pairs"].items()})
        from photo3d.eval.evaluate import Evaluation

        md += [f"### mean over {len(record['pairs'])} pairs", "",
               table(Evaluation(scores=record["mean"])), ""]
    write_json(out / "results.json", record)
    write_text(out / "results.md", "\n".join(md))
    return record
