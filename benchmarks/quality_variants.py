"""Disoccluded quality of the learned backend's variants (issues 14 and 18).

``old-perpatch``: the compact weights before issue 14 (uncentred colour net, in
``OLD_WEIGHTS``), one net run per patch, same context depth in every pass (before
issue 18); ``new-perpatch``: the shipped (centred, fine-tuned) colour net, per patch;
``new-shared``: the shipped nets on shared canvases; a name ending in
``-whole-fills`` turns off the merge's fill rules (steps inside one fill tear only
along the edge paths; fills clamped to their context's depth range) and the edge
paths, as before issue 18's point 3. Scores the
motorcycle pair and the first N synthetic scenes with ``photo3d.eval.evaluate``;
writes ``results/compact_quality.json`` (merged over invocations).

Usage: python benchmarks/quality_variants.py VARIANT N [OLD_WEIGHTS]
"""

import json
import sys
import time
from functools import partial
from pathlib import Path

import torch

import photo3d.inpaint.learned as L
from photo3d.eval.evaluate import evaluate
from photo3d.eval.stereo_pair import motorcycle_pair
from photo3d.eval.synthetic import synthetic_pair

torch.set_num_threads(1)
variant = sys.argv[1]
weights = sys.argv[3] if variant.startswith("old") else None
if variant.endswith("perpatch"):
    L.LearnedInpainter.__init__.__kwdefaults__["share"] = False
    L.LearnedInpainter.later_context = 1.0
if variant.endswith("-whole-fills"):  # before issue 18's fill rules (merge, edge paths)
    import photo3d.stages.merge as M
    M.merge_fills.__kwdefaults__["link_fills"] = M.take.__kwdefaults__["clamp"] = False
    L.LearnedInpainter.__init__.__kwdefaults__["paths"] = False
pairs = {"motorcycle": motorcycle_pair} | {f"synthetic{i}": partial(synthetic_pair, i)
                                           for i in range(int(sys.argv[2]))}
path = Path(__file__).parent / "results" / "compact_quality.json"
record = json.loads(path.read_text()) if path.is_file() else {"variants": {}}
record["command"] = "python benchmarks/quality_variants.py VARIANT 2 OLD_WEIGHTS"
for name, pair in pairs.items():
    t = time.time()
    d = evaluate(pair(), ["learned"], weights=weights).scores["learned"]["disoccluded"]
    scores = {k: round(float(v), 4) for k, v in d.items()} | {"s": round(time.time() - t)}
    record["variants"].setdefault(variant, {})[name] = scores
    print(variant, name, scores, flush=True)
    path.write_text(json.dumps(record, indent=1))
