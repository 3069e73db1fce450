"""A quick proxy for choosing the edge alignment's settings (issue 44): ``preprocess`` only.

For the three layered scenes of ``bench_edges.py`` (480 x 320) and each of its depth
conditions, the share of pixels whose preprocessed disparity (back in the input's
units) is off the exact disparity by more than the discontinuity threshold (0.04 of
the exact map's range), mean over the scenes. No rendering, no fill: a few seconds a
variant instead of minutes. ``bench_edges.py`` decides; this narrows the candidates.

Usage: python benchmarks/bench_edges_proxy.py [NAME_PART ...]   (variants whose name
contains one of the parts; default all)
"""

from __future__ import annotations

import itertools
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import _edge_scenes as es  # noqa: E402
import bench_edges as be  # noqa: E402


def variants() -> dict:
    """Name -> Config of every variant."""
    from photo3d.config import Config, PreprocessConfig

    base = Config(size=None, depth_kind="depth", metric=True)
    out = {"exact": base.with_(edges="exact"),
           "exact-g0": base.with_(edges="exact", preprocess=PreprocessConfig(grow_foreground=0))}
    for r, it, sc, g in itertools.product([6, 8, 12], [4, 8], [0.05, 0.1, 0.2], [0.0, 1.0]):
        out[f"r{r} it{it} sc{sc} g{g}"] = base.with_(preprocess=PreprocessConfig(
            align_radius=r, align_iterations=it, align_sigma_color=sc, grow_foreground=g))
    return out


def main() -> None:
    from photo3d.camera import Camera, Intrinsics
    from photo3d.stages.preprocess import preprocess

    k = Intrinsics.default(es.WIDTH, es.HEIGHT)
    scenes = [es.cast(es.scene(seed), Camera(k, np.eye(4))) for seed in range(3)]
    only = sys.argv[1:]
    print("variant", *be.CONDITIONS)
    for name, cfg in variants().items():
        if only and not any(o in name for o in only):
            continue
        t = time.perf_counter()
        row = []
        for cond in be.CONDITIONS:
            errs = []
            for img, z in scenes:
                truth = 1.0 / z
                out = preprocess(img, (1.0 / be.depth_condition(z, cond)).astype(np.float32),
                                 config=cfg)
                lo, hi = out.disparity_range
                off = np.abs(lo + out.disparity * (hi - lo) - truth)
                errs.append(float((off > 0.04 * (truth.max() - truth.min())).mean()))
            row.append(np.mean(errs))
        print(f"{name:24s}", " ".join(f"{v:.4f}" for v in row),
              f"{time.perf_counter() - t:.1f}s", flush=True)


if __name__ == "__main__":
    main()
