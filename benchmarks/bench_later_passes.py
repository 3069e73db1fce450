"""New depth edges per inpainting pass with good, poor and random fills (issue 18).

Each inpainting pass finds the next pass's edges where new pixels meet across a
depth step. A poor or random net must not make later passes explode. This runs
``photo3d.make`` on the motorcycle sample (ground-truth disparity, 1024 px) with:
diffusion, structured, the shipped compact nets, the authors' architectures with
random weights and the compact architectures with random weights, each with the
merge's fill rules on (the default: steps inside one fill tear only along the
backend's reported edges, which the learned backend gives as one-pixel paths
continuing context edges; fills clipped to their context's depth range) and off (as
before issue 18's point 3). Records edges and pixels added per pass and the
inpainting time, one fresh process per case (rows of cases not run are kept from
``--out``); then scores diffusion and structured
(disoccluded pixels, motorcycle and ``--synthetic`` scenes) with the rules off and on.

Usage: python benchmarks/bench_later_passes.py [--cases a,b,...] [--synthetic 5] [--out FILE]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from _machine import run_child, save_record  # noqa: E402

CASES = ("diffusion", "structured", "compact", "authors-random", "compact-random")

CHILD = r"""
import json, resource, sys, time
import numpy as np
import photo3d
import photo3d.stages.merge as M
from photo3d.sample import motorcycle

case, rules = sys.argv[1], sys.argv[2] == "on"
if not rules:
    M.merge_fills.__kwdefaults__["link_fills"] = M.take.__kwdefaults__["clamp"] = False
backend, name = None, case
if case in ("compact", "authors-random", "compact-random"):
    from photo3d.eval.evaluate import random_nets
    from photo3d.inpaint.learned import LearnedInpainter, bundled_weights
    name = "learned"
    if case == "compact":
        backend = LearnedInpainter(weights=bundled_weights(), paths=rules)
    else:
        arch = None if case == "authors-random" else json.loads(
            (bundled_weights() / "training.json").read_text())["architecture"]
        backend = LearnedInpainter(nets=random_nets(0, arch), paths=rules)
s = motorcycle()
cfg = photo3d.Config(size=1024, inpainter=name)
t = time.perf_counter()
photo = photo3d.make(s.left, depth=np.asarray(s.disparity), config=cfg, inpainter=backend)
print(json.dumps({"make_s": time.perf_counter() - t, "inpaint_s": photo.timings["inpaint"],
                  "edges": photo.stats["edges"], "added": photo.stats["pixels_added"],
                  "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""

SCORES = r"""
import json, sys
from functools import partial
import photo3d.stages.merge as M
from photo3d.eval.evaluate import evaluate
from photo3d.eval.stereo_pair import motorcycle_pair
from photo3d.eval.synthetic import synthetic_pair

if sys.argv[1] == "off":
    M.merge_fills.__kwdefaults__["link_fills"] = M.take.__kwdefaults__["clamp"] = False
pairs = {"motorcycle": motorcycle_pair} | {
    f"synthetic{i}": partial(synthetic_pair, i) for i in range(int(sys.argv[2]))}
out = {}
for name, pair in pairs.items():
    for method, sc in evaluate(pair(), ["diffusion", "structured"]).scores.items():
        out.setdefault(method, {})[name] = {
            k: float(v) for k, v in sc["disoccluded"].items()}
print(json.dumps(out))
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--synthetic", type=int, default=5,
                    help="synthetic scenes scored (with the motorcycle) for diffusion and "
                         "structured, rules off and on; 0: no scores")
    ap.add_argument("--out", type=Path,
                    default=Path(__file__).parent / "results" / "later_passes.json")
    args = ap.parse_args()
    old = json.loads(args.out.read_text()) if args.out.is_file() else {}
    rec = {"results": old.get("results", {})}  # cases not run keep their rows
    for case in args.cases.split(","):
        for rules in ("off", "on"):
            r = run_child(CHILD, case, rules)
            rec["results"].setdefault(case, {})[rules] = r
            print(f"{case:15s} rules {rules:3s}  edges {r['edges']}  inpaint "
                  f"{r['inpaint_s']:.1f} s", flush=True)
    if args.synthetic:
        both = {rules: run_child(SCORES, rules, args.synthetic) for rules in ("off", "on")}
        methods = [m for m, v in both["on"].items() if isinstance(v, dict)]
        rec["scores"] = {m: {p: {rules: both[rules][m][p] for rules in both}
                             for p in both["on"][m]} for m in methods}
    save_record(rec, args.out, "later_passes", "bench_later_passes.py")


if __name__ == "__main__":
    main()
