"""The context rules of issue 27 (item 4), one at a time, on the stereo pairs.

Scores the right view of the Middlebury motorcycle and the mean of the synthetic
scenes (disoccluded pixels, as ``bench_quality.py``) with ``RegionConfig`` variants:
the paper's contexts (``thin_context=0``, ``context_around=False``), the thin-context
search alone, both rules (the default), and "every bounding pixel at or behind the
region" (``thin_context`` so large that every context counts as thin). Writes
``benchmarks/results/contexts.json``.

Usage: python benchmarks/bench_contexts.py [--methods structured,diffusion] [--synthetic 5]
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _machine import save_record  # noqa: E402

from photo3d.config import Config  # noqa: E402
from photo3d.eval.evaluate import evaluate  # noqa: E402
from photo3d.eval.stereo_pair import motorcycle_pair  # noqa: E402
from photo3d.eval.synthetic import synthetic_pair  # noqa: E402

VARIANTS = {
    "paper": dict(thin_context=0.0, context_around=False),
    "thin only": dict(thin_context=0.5, context_around=False),
    "thin + around (default)": dict(thin_context=0.5, context_around=True),
    "every pixel behind": dict(thin_context=1e9, context_around=False),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--methods", default="structured,diffusion")
    parser.add_argument("--synthetic", type=int, default=5)
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).parent / "results" / "contexts.json")
    args = parser.parse_args()
    methods = args.methods.split(",")
    pairs = {"motorcycle": motorcycle_pair(),
             **{f"synthetic{i}": synthetic_pair(i) for i in range(args.synthetic)}}
    scores: dict = {}
    for variant, rules in VARIANTS.items():
        base = Config()
        config = replace(base, regions=replace(base.regions, **rules))
        scores[variant] = {}
        for name, pair in pairs.items():
            result = evaluate(pair, methods, config=config)
            scores[variant][name] = {m: result.scores[m]["disoccluded"] for m in methods}
            print(f"{variant:26s} {name:11s} " + "  ".join(
                f"{m} {result.scores[m]['disoccluded']['lpips']:.4f}" for m in methods),
                flush=True)
    synth = [n for n in pairs if n.startswith("synthetic")]
    rows = []
    for variant in VARIANTS:
        for m in methods:
            moto = scores[variant]["motorcycle"][m]
            rows.append(f"| {variant} | {m} | {moto['lpips']:.4f} | {moto['psnr']:.2f} | " + (
                f"{np.mean([scores[variant][n][m]['lpips'] for n in synth]):.4f} | "
                f"{max(scores[variant][n][m]['lpips'] for n in synth):.4f} |" if synth else
                "- | - |"))
    markdown = "\n".join([
        "Disoccluded pixels of the right view.", "",
        "| contexts | fill | motorcycle LPIPS | motorcycle PSNR | synthetic mean LPIPS "
        "| synthetic worst LPIPS |", "| --- | --- | --- | --- | --- | --- |", *rows])
    save_record({"scores": scores, "variants": VARIANTS, "markdown": markdown}, args.out,
                "contexts", "bench_contexts.py")
    print(markdown)


if __name__ == "__main__":
    main()
