"""Novel-view quality on real and synthetic stereo pairs, all methods side by side.

Runs ``photo3d eval`` on the Middlebury motorcycle pair and on synthetic layered
scenes (seeds 0..N-1); writes ``results/quality/`` (tables, crop grids, JSON) and
``results/quality.json``.

Usage: python benchmarks/bench_quality.py [--synthetic 5] [--methods ...] [--weights DIR]
"""

from __future__ import annotations

import argparse
import json
import sys
from functools import partial
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from _machine import machine_info  # noqa: E402

from photo3d.eval.evaluate import METHODS  # noqa: E402
from photo3d.eval.report import run  # noqa: E402
from photo3d.eval.stereo_pair import motorcycle_pair  # noqa: E402
from photo3d.eval.synthetic import synthetic_pair  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--synthetic", type=int, default=5)
    parser.add_argument("--methods", default=",".join(METHODS))
    parser.add_argument("--weights", type=Path)
    parser.add_argument("--out", type=Path, default=Path(__file__).parent / "results")
    args = parser.parse_args()
    methods = args.methods.split(",")
    real = run({"motorcycle": motorcycle_pair}, args.out / "quality" / "real",
               methods=methods, weights=args.weights, overwrite=True, progress=print)
    synth = None
    if args.synthetic:
        synth = run({f"synthetic{i}": partial(synthetic_pair, i)
                     for i in range(args.synthetic)},
                    args.out / "quality" / "synthetic", methods=methods, weights=args.weights,
                    overwrite=True, progress=print)
    record = {"benchmark": "quality", "machine": machine_info(), "real": real,
              "synthetic": synth,
              "command": " ".join(["python", "benchmarks/bench_quality.py", *sys.argv[1:]])}
    (args.out / "quality.json").write_text(json.dumps(record, indent=2))
    print((args.out / "quality" / "real" / "results.md").read_text())
    if synth is not None:
        print((args.out / "quality" / "synthetic" / "results.md").read_text())


if __name__ == "__main__":
    main()
