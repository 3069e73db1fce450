"""Shared driver of the benchmarks that score every evaluation pair the same way."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from functools import partial
from pathlib import Path

from _machine import save_record

from photo3d.eval.stereo_pair import motorcycle_pair
from photo3d.eval.synthetic import synthetic_pair


def score_all_pairs(score_pair: Callable, benchmark: str, script: str, doc: str) -> dict:
    """Score the motorcycle pair and ``--synthetic N`` synthetic scenes with
    ``score_pair(pair) -> {variant: {"lpips": ..., ...}}``, print each pair's LPIPS
    and write ``results/<benchmark>.json`` (``--out`` changes the folder)."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("--synthetic", type=int, default=5)
    parser.add_argument("--out", type=Path, default=Path(__file__).parent / "results")
    args = parser.parse_args()
    pairs = {"motorcycle": motorcycle_pair} | {f"synthetic{i}": partial(synthetic_pair, i)
                                               for i in range(args.synthetic)}
    scores = {}
    for name, make_pair in pairs.items():
        scores[name] = score_pair(make_pair())
        print(name, {k: round(v["lpips"], 4) for k, v in scores[name].items()}, flush=True)
    return save_record({"scores": scores}, args.out / f"{benchmark}.json", benchmark, script)
