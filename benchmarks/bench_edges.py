"""Occlusion edges (issue 44): novel views near depth steps, exact scenes and real pairs.

Scenes (``_edge_scenes.py``): three layered scenes (seeds 0-2) with thin structures
(poles 2-10 px, a 2 px wire, a fence, foliage, a box with holes, a ring) over real
photos, 480 x 320 (``make`` at that size: ``Config(size=None)``, spatial parameters
scaled to it as always), cast exactly with 4 x 4 rays per pixel from the input camera
and from 8 cameras of the four standard paths (six circle positions, the end of the
zoom-in and of the dolly zoom; the paths' shifts x 7 in metres: moves of 10-35 cm at
2.5-9 m). ``make`` gets the input view and one of these depth maps (metric depth,
``depth_kind="depth", metric=True``, so the views are rendered at the exact cameras):

- ``exact``: the nearest surface at each pixel centre;
- ``spread1..3``: the near side grown 1-3 px onto the far side (grey dilation of the
  disparity with a disk);
- ``shrunk1..2``: the near side shrunk 1-2 px (grey erosion);
- ``blurred``: like a network's output: disparity averaged over 4 x 4 blocks,
  upsampled bilinearly, Gaussian sigma 1 px.

The Middlebury motorcycle pair (``photo3d.eval.stereo_pair.motorcycle_pair``, 741 x
500, ``make`` at that size) twice: with its ground-truth disparity and with
``photo3d.depth.stereo.stereo_disparity`` of the pair (what ``--right`` computes),
each as metric depth with the pair's calibration, rendered at the right camera and
scored against the real right view. Its depth steps in the right view: the left
ground truth's steps (neighbours more than 4 px of disparity apart) forward-warped,
plus the borders of the disoccluded pixels.

Scores per view (then the mean over views; the median over the three scenes):
LPIPS (AlexNet) and PSNR over the pixels within 4 px of a depth step of the true
view (``steps``), the share of those pixels whose largest channel error is above
0.25 (``gross``), LPIPS and PSNR over the disoccluded pixels (hidden from or outside
the input view) and over the whole view.

Versions: ``ref`` (commit ``--ref``, default e951c93, extracted with ``git
archive``), this tree with its defaults (``new``) and the variants ``--variants``
names (this tree with other settings; ``VARIANTS``). Each version runs every input
in one child process; the children alternate, the renders are scored here. Writes
``benchmarks/results/edges.json`` (``--out``). ``--no-new``, ``--ref ''`` and
``--variants`` run a part of the versions (several parts can run at once, as separate
processes); ``--merge A.json B.json`` joins such parts into one result.

``--time N`` instead times ``make`` of the motorcycle sample at 1024 px with the
defaults (``_make_child.py``: wall and CPU seconds around ``photo3d.make``, its
``preprocess`` stage) for ``ref`` and ``new``, alternating, one unmeasured run of
each first, ``N`` runs each, medians; writes ``benchmarks/results/edges_time.json``.

Usage: python benchmarks/bench_edges.py [--ref e951c93] [--variants exact,grow0]
           [--scenes 3] [--no-pair] [--src SRC] [--no-new] [--time N]
       python benchmarks/bench_edges.py --merge PART.json ... [--out OUT]
"""

from __future__ import annotations

import argparse
import json
import pickle
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _machine import MAKE_CHILD, git_src, save_record, timed_python  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
PATH_SCALE = 7.0  # the paths' shifts (normalised units) -> metres for these scenes
CONDITIONS = ("exact", "spread1", "spread2", "spread3", "shrunk1", "shrunk2", "blurred")
VARIANTS: dict[str, dict] = {
    "exact": {"edges": "exact"},
    "grow0": {"preprocess": {"grow_foreground": 0.0}},
    "grow1": {"preprocess": {"grow_foreground": 1.0}},
    "exact-grow0": {"edges": "exact", "preprocess": {"grow_foreground": 0.0}},
    "soft": {"edges": "soft"},
    "align": {"edges": "align"},
    "iter3": {"preprocess": {"align_iterations": 3}},
    "ramp0": {"preprocess": {"ramp_passes": 0}},
    "ramp8": {"preprocess": {"ramp_passes": 8}},
    "nomedian": {"preprocess": {"filter_windows": []}},
    "nomedian-ramp0": {"preprocess": {"filter_windows": [], "ramp_passes": 0}},
    "median5": {"preprocess": {"filter_windows": [5, 5, 5]}},
    "median3": {"preprocess": {"filter_windows": [3, 3, 3]}},
    "ramp2": {"preprocess": {"ramp_passes": 2}},
    "cmed0": {"preprocess": {"filter_sigma_color": 0.0}},
    "cmed05": {"preprocess": {"filter_sigma_color": 0.05}},
    "cmed2": {"preprocess": {"filter_sigma_color": 0.2}},
    "thin0": {"preprocess": {"filter_thin_width": 0}},
    "thin3": {"preprocess": {"filter_thin_width": 3}},
    "thin7": {"preprocess": {"filter_thin_width": 7}},
    "len0": {"preprocess": {"filter_thin_length": 0}},
    "len16": {"preprocess": {"filter_thin_length": 16}},
    "len64": {"preprocess": {"filter_thin_length": 64}},
}
"""Settings of this tree's variants (nested ``Config.to_dict`` keys)."""

CHILD = r"""
import json, pickle, sys, time
import numpy as np
import photo3d
from photo3d.camera import Camera, Intrinsics
from photo3d.config import Config
from photo3d.render.renderer import RenderSettings

jobs = pickle.load(open(sys.argv[1], "rb"))
overrides = json.loads(sys.argv[3])
out = {}
for name, job in jobs.items():
    base = Config(size=None, depth_kind="depth", metric=True).to_dict()
    for key, value in overrides.items():
        if isinstance(value, dict):
            base[key] = {**base[key], **value}
        else:
            base[key] = value
    config = Config.from_dict(base)
    t = time.perf_counter()
    photo = photo3d.make(job["image"], depth=job["depth"], config=config,
                         intrinsics=Intrinsics(*job["intrinsics"]))
    made = time.perf_counter() - t
    views = [photo.render(Camera(Intrinsics(*k), np.asarray(pose)),
                          settings=RenderSettings(ssaa=2)).color.astype(np.float16)
             for k, pose in job["cameras"]]
    out[name] = {"views": views, "make_s": made}
pickle.dump(out, open(sys.argv[2], "wb"))
"""


def cameras(k):
    """The 8 novel cameras: six circle positions, the zoom-in's and the dolly zoom's
    last frame, translations x :data:`PATH_SCALE`."""
    from dataclasses import replace

    from photo3d.camera import Camera
    from photo3d.render.paths import preset_path

    circle = preset_path("circle", k, frames=8)
    picked = [circle[i] for i in (0, 1, 3, 4, 5, 7)]
    picked.append(preset_path("zoom-in", k, frames=2)[1])
    centre = 9.0 / PATH_SCALE  # the back wall at the centre pixel
    picked.append(preset_path("dolly-zoom-in", k, frames=2, centre_depth=centre)[1])
    out = []
    for cam in picked:
        pose = cam.pose.copy()
        pose[:3, 3] *= PATH_SCALE
        out.append(Camera(replace(cam.intrinsics), pose))
    return out


def depth_condition(z: np.ndarray, name: str) -> np.ndarray:
    """``z (H, W)`` exact depth -> the depth ``make`` gets under condition ``name``."""
    from scipy import ndimage

    d = 1.0 / z
    if name == "exact":
        return z
    if name.startswith(("spread", "shrunk")):
        r = int(name[-1])
        yy, xx = np.mgrid[-r:r + 1, -r:r + 1]
        disk = yy * yy + xx * xx <= r * r
        op = ndimage.grey_dilation if name.startswith("spread") else ndimage.grey_erosion
        return (1.0 / op(d, footprint=disk)).astype(np.float32)
    if name == "blurred":
        h, w = d.shape
        small = d[:h - h % 4, :w - w % 4].reshape(h // 4, 4, w // 4, 4).mean(axis=(1, 3))
        up = ndimage.zoom(small, (h / small.shape[0], w / small.shape[1]), order=1)
        return (1.0 / ndimage.gaussian_filter(up, 1.0)).astype(np.float32)
    raise ValueError(name)


def _near_steps(step: np.ndarray, radius: float = 4.0) -> np.ndarray:
    from scipy import ndimage

    return ndimage.distance_transform_edt(~step) <= radius


def depth_steps(depth: np.ndarray, ratio: float = 1.05) -> np.ndarray:
    """``(H, W) bool``: pixels with a 4-neighbour more than ``ratio`` times nearer or
    farther (both sides of every step)."""
    step = np.zeros(depth.shape, bool)
    for a, b in ((np.s_[:, 1:], np.s_[:, :-1]), (np.s_[1:], np.s_[:-1])):
        jump = np.maximum(depth[a] / depth[b], depth[b] / depth[a]) > ratio
        step[a] |= jump
        step[b] |= jump
    return step


def scene_inputs(count: int):
    """Jobs, truths and masks of ``count`` scenes under every condition."""
    import _edge_scenes as es

    from photo3d.camera import Camera, Intrinsics

    k = Intrinsics.default(es.WIDTH, es.HEIGHT)
    cam0 = Camera(k, np.eye(4))
    cams = cameras(k)
    jobs, truths = {}, {}
    for seed in range(count):
        layers = es.scene(seed)
        image, z = es.cast(layers, cam0)
        views = [es.cast(layers, c) for c in cams]
        masks = [{"steps": _near_steps(depth_steps(dv)),
                  "disoccluded": es.disoccluded(layers, c, cam0)} for c, (_, dv) in
                 zip(cams, views, strict=True)]
        truths[f"scene{seed}"] = ([v for v, _ in views], masks)
        for cond in CONDITIONS:
            jobs[f"scene{seed}/{cond}"] = {
                "image": image, "depth": depth_condition(z, cond),
                "intrinsics": (k.fx, k.fy, k.cx, k.cy, k.width, k.height),
                "cameras": [((c.intrinsics.fx, c.intrinsics.fy, c.intrinsics.cx,
                              c.intrinsics.cy, c.intrinsics.width, c.intrinsics.height),
                             c.pose) for c in cams]}
    return jobs, truths


def pair_inputs():
    """Jobs and truths of the motorcycle pair with its ground truth and stereo depth."""
    from scipy import ndimage

    from photo3d.depth.stereo import stereo_disparity
    from photo3d.eval.stereo_pair import motorcycle_pair
    from photo3d.eval.warp import forward_warp

    pair = motorcycle_pair()
    k, rc = pair.left_camera, pair.right_camera
    gt = pair.disparity
    stereo = stereo_disparity(pair.left, pair.right).disparity.astype(np.float32)
    warp = forward_warp(pair.left, gt)
    filled = np.where(np.isfinite(gt), gt, 0.0)
    jump = np.zeros(gt.shape, bool)
    jump[:, 1:] |= np.abs(np.diff(filled, axis=1)) > 4
    jump[1:] |= np.abs(np.diff(filled, axis=0)) > 4
    marks = forward_warp(np.repeat(jump[..., None], 3, 2).astype(np.float32), gt).color[..., 0]
    holes = warp.disoccluded
    border = holes ^ ndimage.binary_erosion(holes)
    steps = _near_steps((marks > 0.5) | border) & warp.frame
    masks = [{"steps": steps, "disoccluded": warp.disoccluded, "all": warp.frame}]
    jobs = {}
    for name, disp in (("motorcycle/gt", gt), ("motorcycle/stereo", stereo)):
        z = pair.baseline * k.fx / (disp + pair.doffs)
        jobs[name] = {"image": pair.left,
                      "depth": np.where(np.isfinite(z) & (z > 0), z, np.nan).astype(np.float32),
                      "intrinsics": (k.fx, k.fy, k.cx, k.cy, k.width, k.height),
                      "cameras": [((rc.intrinsics.fx, rc.intrinsics.fy, rc.intrinsics.cx,
                                    rc.intrinsics.cy, rc.intrinsics.width,
                                    rc.intrinsics.height), rc.pose)]}
    return jobs, {"motorcycle": ([pair.right], masks)}


def score(view: np.ndarray, truth: np.ndarray, masks: dict) -> dict:
    """The scores of one view (see the module docstring)."""
    from photo3d.eval.lpips import lpips_map
    from photo3d.eval.metrics import psnr

    view = view.astype(np.float32)
    lmap = lpips_map(view, truth)
    err = np.abs(view - truth).max(axis=2)
    out = {}
    regions = {"steps": masks["steps"], "disoccluded": masks["disoccluded"],
               "all": masks.get("all", np.ones(truth.shape[:2], bool))}
    for region, m in regions.items():
        out[f"lpips_{region}"] = float(lmap[m].mean()) if m.any() else float("nan")
        out[f"psnr_{region}"] = psnr(view, truth, m)
    out["gross_steps"] = float((err > 0.25)[regions["steps"]].mean())
    return out


def summarize(per_job: dict[str, dict]) -> dict:
    """Per condition: the median over scenes of each score (mean over views), and the
    motorcycle's rows as they are."""
    out: dict[str, dict] = {}
    for cond in CONDITIONS:
        rows = [v for k, v in per_job.items() if k.startswith("scene") and k.endswith(cond)]
        if rows:
            out[cond] = {m: statistics.median(r[m] for r in rows) for m in rows[0]}
    for k, v in per_job.items():
        if k.startswith("motorcycle"):
            out[k] = v
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ref", default="e951c93", help="commit to compare ('' = none)")
    parser.add_argument("--variants", default="", help=f"of {', '.join(VARIANTS)}")
    parser.add_argument("--scenes", type=int, default=3)
    parser.add_argument("--no-pair", action="store_true", help="skip the motorcycle pair")
    parser.add_argument("--src", type=Path, default=ROOT / "src",
                        help="the new version's src folder (default: this tree's)")
    parser.add_argument("--no-new", action="store_true",
                        help="skip this tree's defaults (ref and variants only)")
    parser.add_argument("--merge", nargs="+", type=Path, metavar="JSON",
                        help="join the versions of these results (runs of this script on "
                             "parts of the versions) into --out instead of running")
    parser.add_argument("--time", type=int, default=0, metavar="N",
                        help="time make on the sample instead, N alternating runs each")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    if args.time:
        out = args.out or ROOT / "benchmarks/results/edges_time.json"
        save_record(time_make(args.ref, args.src, args.time), out, "edges_time",
                    "bench_edges.py")
        return
    args.out = args.out or ROOT / "benchmarks/results/edges.json"
    if args.merge:
        parts = [json.loads(p.read_text()) for p in args.merge]
        record = {k: v for k, v in parts[0].items() if k not in ("benchmark", "machine")}
        record["versions"] = {n: v for p in parts for n, v in p["versions"].items()}
        record["ref"] = next((p["ref"] for p in parts if "ref" in p["versions"]), args.ref)
        record["parts"] = [p["command"] for p in parts]
        save_record(record, args.out, "edges", "bench_edges.py")
        return

    sys.path.insert(0, str(ROOT / "src"))
    jobs, truths = scene_inputs(args.scenes)
    if not args.no_pair:
        pj, pt = pair_inputs()
        jobs.update(pj)
        truths.update(pt)
    versions: dict[str, tuple[Path, dict]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        if args.ref:
            versions["ref"] = (git_src(args.ref, tmp / "ref"), {})
        if not args.no_new:
            versions["new"] = (args.src, {})
        for v in filter(None, args.variants.split(",")):
            versions[v] = (args.src, VARIANTS[v])
        job_file = tmp / "jobs.pkl"
        job_file.write_bytes(pickle.dumps(jobs))
        results: dict[str, dict] = {}
        for name, (src, overrides) in versions.items():
            out_file = tmp / f"{name}.pkl"
            run = timed_python(["-c", CHILD, str(job_file), str(out_file),
                                json.dumps(overrides)], src=src)
            renders = pickle.loads(out_file.read_bytes())
            per_job = {}
            for job, r in renders.items():
                truth_views, masks = truths[job.split("/")[0]]
                scores = [score(v, t, m) for v, t, m in zip(r["views"], truth_views, masks,
                                                            strict=True)]
                per_job[job] = {m: float(np.nanmean([s[m] for s in scores])) for m in scores[0]}
                per_job[job]["make_s"] = r["make_s"]
            results[name] = {"overrides": overrides, "child_wall_s": run["wall_s"],
                             "per_job": per_job, "summary": summarize(per_job)}
            print_summary(name, results[name]["summary"])
    record = {"size": "scenes 480x320, motorcycle 741x500 (make at the input size)",
              "conditions": list(CONDITIONS), "ref": args.ref, "versions": results}
    save_record(record, args.out, "edges", "bench_edges.py")


def time_make(ref: str, src: Path, runs: int) -> dict:
    """``make`` of the sample at 1024 px, ``ref`` and ``src`` alternating (see the
    module docstring)."""
    with tempfile.TemporaryDirectory() as tmp:
        trees = {"ref": git_src(ref, Path(tmp) / "ref"), "new": src}
        times: dict[str, list[dict]] = {name: [] for name in trees}
        for i in range(runs + 1):
            for name, tree in trees.items():
                run = timed_python([str(MAKE_CHILD), "1024"], src=tree)
                child = json.loads(run["stdout"].strip().splitlines()[-1])
                if i:  # the first of each: numba's cache, the page cache
                    times[name].append({"make_s": child["make_s"], "cpu_s": child["cpu_s"],
                                        "preprocess_s": child["stages"]["preprocess"],
                                        "load_1min": run["load_1min"]})
    medians = {name: {k: statistics.median(r[k] for r in rs)
                      for k in ("make_s", "cpu_s", "preprocess_s")}
               for name, rs in times.items()}
    ratio = medians["new"]["make_s"] / medians["ref"]["make_s"]
    print(f"make 1024 px: ref {medians['ref']['make_s']:.2f} s, new "
          f"{medians['new']['make_s']:.2f} s ({ratio:.2f}x); preprocess "
          f"{medians['ref']['preprocess_s']:.2f} -> {medians['new']['preprocess_s']:.2f} s")
    return {"ref": ref, "runs": times, "median": medians, "ratio_make": ratio}


def print_summary(name: str, summary: dict) -> None:
    """One line per condition."""
    print(f"== {name}")
    for cond, s in summary.items():
        print(f"  {cond:18s} steps LPIPS {s['lpips_steps']:.4f} PSNR {s['psnr_steps']:5.2f} "
              f"gross {s['gross_steps']:6.2%} | disocc LPIPS {s['lpips_disoccluded']:.4f} "
              f"PSNR {s['psnr_disoccluded']:5.2f} | all LPIPS {s['lpips_all']:.4f} "
              f"PSNR {s['psnr_all']:5.2f} | make {s['make_s']:.2f} s")
    if "exact" in summary and "spread2" in summary:
        print(f"  spread2 / exact steps LPIPS: "
              f"{summary['spread2']['lpips_steps'] / summary['exact']['lpips_steps']:.2f}")


if __name__ == "__main__":
    main()
