"""``photo3d make --no-video`` on hard depth maps, whole process, against the previous commit.

Issue 35 item 2 and issue 36 defect 2. Each run is the command line in a fresh process
(``photo3d make IMAGE --depth DEPTH --no-video``, defaults otherwise: 1024 px, the
``structured`` fill, PLY, GLB and viewer written), timed from start to exit, with its
peak resident set size (``wait4``) and the edges per pass its ``config.json`` records.
The previous commit (``git archive HEAD src``) runs from a temporary folder through
``PYTHONPATH``, alternating with the working tree, in the same session; one unmeasured
run of each first (numba's cache, page cache). Median of ``--runs`` for times, the
maximum for memory. Inputs (the Middlebury motorcycle's left view as a PNG):

- ``sample``: its ground-truth disparity, unknown pixels ``+inf`` (filled from the
  farther row neighbour; what ``photo3d demo`` makes);
- ``raw``: the same disparity with unknown pixels = 0 (a valid disparity: infinitely
  far; holes to the far plane everywhere a matcher gave up);
- with ``--hostile`` (one run each; issue 36): uniform noise, uniform noise in 3x3
  blocks (the worst for memory found), an 8 px checkerboard and a map holding only 1.0
  and 1.0000001, at the photo's size; their peak memory is compared with the estimate
  ``make`` checks (:func:`photo3d.resources.memory_estimate`).

Writes ``benchmarks/results/hard_depth.json``.

Usage: python benchmarks/bench_hard_depth.py [--runs 3] [--hostile] [--ref HEAD]
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from _machine import git_src, save_record, timed_python  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
INPUTS = ("sample", "raw")
HOSTILE = ("noise", "blocks", "checker", "flat")


def write_inputs(folder: Path) -> dict[str, tuple[Path, Path]]:
    """The photo as a PNG and every depth map as ``.npy`` in ``folder``."""
    import numpy as np
    from PIL import Image

    from photo3d.sample import motorcycle

    sample = motorcycle()
    image = folder / "left.png"
    Image.fromarray(np.round(sample.left * 255).astype(np.uint8)).save(image)
    h, w = sample.disparity.shape
    rng = np.random.default_rng(0)
    yy, xx = np.mgrid[0:h, 0:w]
    maps = {
        "sample": sample.disparity,
        "raw": np.where(np.isfinite(sample.disparity), sample.disparity, 0.0),
        "noise": rng.random((h, w)),
        "blocks": np.kron(rng.random((h // 3 + 1, w // 3 + 1)), np.ones((3, 3)))[:h, :w],
        "checker": 1.0 + ((yy // 8 + xx // 8) % 2),
        "flat": np.where(rng.random((h, w)) < 0.5, 1.0, 1.0000001),
    }
    out = {}
    for name, depth in maps.items():
        path = folder / f"{name}.npy"
        np.save(path, np.asarray(depth, np.float32))
        out[name] = (image, path)
    return out


def run_make(src: Path, image: Path, depth: Path, out: Path) -> dict:
    """One whole ``photo3d make`` process from the tree ``src``: wall seconds, peak
    resident memory, the stats and timings of its ``config.json``, its save time."""
    run = timed_python(["-c", "import sys; from photo3d.cli import main; sys.exit(main())",
                        "make", str(image), "--depth", str(depth), "--no-video", "-o", str(out),
                        "--overwrite"], src=src)
    record = json.loads((out / "config.json").read_text())
    save = re.search(r"^time: .*\bsave ([0-9.]+)s", run["stdout"], re.MULTILINE)
    return {"wall_s": run["wall_s"], "cpu_s": run["cpu_s"], "peak_rss_mb": run["peak_rss_mb"],
            "save_s": float(save.group(1)) if save else None,
            "stages": record["timings"], "edges": record["stats"]["edges"],
            "pixels_added": record["stats"]["pixels_added"]}


def summary(runs: list[dict]) -> dict:
    """Median times, maximum memory, the first run's edges and pixels."""
    return {"wall_s": statistics.median(r["wall_s"] for r in runs),
            "cpu_s": statistics.median(r["cpu_s"] for r in runs),
            "save_s": statistics.median(r["save_s"] or 0.0 for r in runs),
            "peak_rss_mb": max(r["peak_rss_mb"] for r in runs),
            "stages": {k: statistics.median(r["stages"][k] for r in runs)
                       for k in runs[0]["stages"]},
            "edges": runs[0]["edges"], "pixels_added": runs[0]["pixels_added"],
            "runs": len(runs)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--hostile", action="store_true",
                        help="also noise, checkerboard and a flat map (one run each)")
    parser.add_argument("--ref", default="HEAD", help="the commit to compare with")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).parent / "results" / "hard_depth.json")
    args = parser.parse_args()

    with tempfile.TemporaryDirectory(prefix="bench_hard_depth_") as tmp:
        tmp = Path(tmp)
        trees = {"previous": git_src(args.ref, tmp / "ref"), "now": ROOT / "src"}
        inputs = write_inputs(tmp)
        cases = list(INPUTS) + (list(HOSTILE) if args.hostile else [])
        for name in trees:  # warm-up: numba's cache of each tree, page cache
            run_make(trees[name], *inputs["sample"], tmp / f"warm_{name}")
        runs: dict = {name: {case: [] for case in cases} for name in trees}
        for case in cases:
            repeat = args.runs if case in INPUTS else 1
            for i in range(repeat):
                for name, src in trees.items():  # alternating, same session
                    r = run_make(src, *inputs[case], tmp / f"{name}_{case}")
                    runs[name][case].append(r)
                    print(f"{case:8s} {name:8s} run {i + 1}: {r['wall_s']:.1f} s, "
                          f"{r['peak_rss_mb']:.0f} MB, edges {r['edges']}", flush=True)

    from photo3d.config import Config
    from photo3d.resources import memory_estimate

    estimate = memory_estimate((500, 741), Config()) / 2**20
    result = {name: {case: summary(rs) for case, rs in per.items()}
              for name, per in runs.items()}
    record = {"ref": args.ref, "estimate_mb": estimate, "median": result, "runs": runs}
    save_record(record, args.out, "hard_depth", "bench_hard_depth.py")
    print(f"\nphoto3d make --no-video, whole process, median of {args.runs} "
          f"(memory: the largest), previous commit ({args.ref}) and now, same session")
    print("| input | version | wall s | ratio | CPU s | save s | peak MB | edges per pass |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for case in cases:
        before = result["previous"][case]["wall_s"]
        for name in trees:
            s = result[name][case]
            print(f"| {case} | {name} | {s['wall_s']:.2f} | {s['wall_s'] / before:.2f} | "
                  f"{s['cpu_s']:.1f} | {s['save_s']:.2f} | {s['peak_rss_mb']:.0f} | "
                  f"{s['edges']} |")
    print(f"memory estimate make checks for this photo: {estimate:.0f} MB")


if __name__ == "__main__":
    main()
