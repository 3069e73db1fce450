"""Run evaluations over several pairs and write their tables, grids and JSON."""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from photo3d.eval.evaluate import METHODS, evaluate, grid, table
from photo3d.eval.stereo_pair import StereoPair


def mean_scores(per_pair: dict[str, dict]) -> dict:
    """Average every method/region/metric over the pairs that have it."""
    acc: dict = {}
    for scores in per_pair.values():
        for method, regions in scores.items():
            for region, metrics in regions.items():
                for metric, value in metrics.items():
                    acc.setdefault(method, {}).setdefault(region, {}).setdefault(
                        metric, []).append(value)
    return {m: {r: {k: float(np.nanmean(v)) for k, v in ms.items()} for r, ms in rs.items()}
            for m, rs in acc.items()}


def run(pairs: dict[str, Callable[[], StereoPair]], out: str | Path, *,
        methods: Sequence[str] = METHODS, weights=None, lpips: bool = True,
        progress: Callable[[str], None] | None = None) -> dict:
    """Evaluate ``methods`` on each pair (built lazily) and write ``out/``.

    Writes ``results.json`` (all scores, notes, timings), ``results.md`` (one table
    per pair and the mean over pairs) and ``grid_<pair>.png`` (crops where methods
    differ most). Returns the JSON record.
    """
    from photo3d.io.images import write_image

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
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
        write_image(out / f"grid_{name}.png", grid(pair, result))
        md += [f"### {name}", "", table(result), "",
               f"Disoccluded: {100 * result.regions['disoccluded'].mean():.1f} % of the view; "
               f"crops: `grid_{name}.png`.", ""]
    if len(record["pairs"]) > 1:
        record["mean"] = mean_scores({k: v["scores"] for k, v in record["pairs"].items()})
        from photo3d.eval.evaluate import Evaluation

        md += [f"### mean over {len(record['pairs'])} pairs", "",
               table(Evaluation(scores=record["mean"])), ""]
    (out / "results.json").write_text(json.dumps(record, indent=2))
    (out / "results.md").write_text("\n".join(md))
    return record
