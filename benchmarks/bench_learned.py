"""Benchmark ``photo3d.make`` with the learned inpainter on the motorcycle pair.

The three nets have the authors' architectures with random weights (inference time
does not depend on the values; note that random edge nets predict edges almost
everywhere, so every patch takes the edge net's two repeats, a worst case). Each run
is a fresh process; building the nets is not timed, the time is measured around
``photo3d.make`` only, and the backend reports the seconds spent inside each net.
Each run alternates with a ``make`` with the diffusion fill (``_make_child.py``), the
reference of the ratio printed. Prints a table and writes
``benchmarks/results/learned.json``.

``--nets`` instead times each net alone on 256x256 and 512x512 inputs (batch 1, best
of ``--repeats`` after one warm-up), in torch and, when ``onnxruntime`` is importable
(extra path via ``--onnx-path``), exported to ONNX (opset 17) and run by
onnxruntime's CPU provider; writes ``benchmarks/results/learned_nets.json``.

``--edge-unit 8 --precision bf16`` measures the backend's opt-in speed-ups
(results in ``learned_fast.json``).

Usage: python benchmarks/bench_learned.py [--runs 3] [--size 1024] [--per-patch] [--edge-unit 8]
           [--precision bf16]
       python benchmarks/bench_learned.py --nets [--repeats 8] [--onnx-path DIR]
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from _machine import machine_info, run_child, run_make  # noqa: E402

CHILD = r"""
import json, os, resource, sys, time
from collections import Counter
import numpy as np, torch
import photo3d
from photo3d.sample import motorcycle
from photo3d.inpaint.learned import LearnedInpainter, padded_shape
from photo3d.nets import InpaintingNets, build_net

class Counted(torch.nn.Module):
    def __init__(self, net):
        super().__init__()
        self.net, self.items, self.mpx = net, 0, 0.0
    def forward(self, x):
        self.items += x.shape[0]
        self.mpx += x.shape[0] * x.shape[2] * x.shape[3] / 1e6
        return self.net(x)

class Recording(LearnedInpainter):
    passes, per_pass = [], []
    def inpaint(self, patches, *, progress=None, pass_index=0):
        self.passes.append([padded_shape(*p.shape) for p in patches])
        before = {k: (n.items, n.mpx) for k, n in nets.items()}
        out = super().inpaint(patches, progress=progress, pass_index=pass_index)
        self.per_pass.append({k: {"runs": n.items - before[k][0],
                                  "mpx": round(n.mpx - before[k][1], 2)}
                              for k, n in nets.items()})
        return out

torch.manual_seed(0)
nets = {k: Counted(build_net(k).eval()) for k in ("edge", "depth", "color")}
backend = Recording(nets=InpaintingNets(**nets, device=torch.device("cpu"), sources={}),
                    edge_unit=int(sys.argv[2]), precision=sys.argv[3],
                    share=sys.argv[4] == "shared")
if sys.argv[4] != "shared":
    backend.later_context = 1.0
s = motorcycle()
cfg = photo3d.Config(size=int(sys.argv[1]), inpainter="learned")
load0, ru0 = os.getloadavg()[0], resource.getrusage(resource.RUSAGE_SELF)
t = time.perf_counter()
photo = photo3d.make(s.left, depth=np.asarray(s.disparity), config=cfg, inpainter=backend)
wall = time.perf_counter() - t
ru1 = resource.getrusage(resource.RUSAGE_SELF)
cpu = ru1.ru_utime + ru1.ru_stime - ru0.ru_utime - ru0.ru_stime
shapes = Counter(f"{h}x{w}" for p in backend.passes for h, w in p)
print(json.dumps({
    "make_s": wall, "stages": photo.timings, "stats": photo.stats,
    "net_s": backend.timings,
    "net_runs": {k: n.items for k, n in nets.items()},
    "net_mpx": {k: round(n.mpx, 2) for k, n in nets.items()},
    "patches_per_pass": [len(p) for p in backend.passes],
    "nets_per_pass": backend.per_pass,
    "padded_shapes": dict(shapes.most_common()),
    "threads": torch.get_num_threads(),
    "cpu_s": cpu, "load_before": load0, "load_after": os.getloadavg()[0],
    "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
}))
"""


NETS = r"""
import json, sys, tempfile, time, warnings
from pathlib import Path
import numpy as np, torch
from photo3d.nets import build_net
if sys.argv[2]:
    sys.path.append(sys.argv[2])
try:
    import onnxruntime as ort
except ImportError:
    ort = None
repeats, cin, out = int(sys.argv[1]), {"edge": 7, "depth": 4, "color": 6}, {}
torch.manual_seed(0)
tmp = Path(tempfile.mkdtemp())
for kind in ("edge", "depth", "color"):
    net = build_net(kind).eval()
    for size in (256, 512):
        x = torch.rand(1, cin[kind], size, size)
        x[:, -2:] = (x[:, -2:] > 0.5).float()
        runs = {"torch": lambda: net(x)}
        if ort is not None:
            path = tmp / f"{kind}{size}.onnx"
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                torch.onnx.export(net, (x,), str(path), dynamo=False, opset_version=17,
                                  input_names=["x"], output_names=["y"])
            opts = ort.SessionOptions()
            opts.intra_op_num_threads = torch.get_num_threads()
            sess = ort.InferenceSession(str(path), opts, providers=["CPUExecutionProvider"])
            xn = x.numpy()
            runs["onnx"] = lambda: sess.run(None, {"x": xn})[0]
        best = {}
        with torch.inference_mode():
            for name, fn in runs.items():
                fn()
            for _ in range(repeats):  # interleaved, so both see the same machine load
                for name, fn in runs.items():
                    t = time.perf_counter()
                    fn()
                    best[name] = min(best.get(name, 1e9), time.perf_counter() - t)
        out[f"{kind} {size}"] = best
print(json.dumps({"best_s": out, "threads": torch.get_num_threads(),
                  "onnxruntime": None if ort is None else ort.__version__}))
"""


def nets_only(repeats: int, onnx_path: str, out_path: Path) -> None:
    out = subprocess.run([sys.executable, "-c", NETS, str(repeats), onnx_path],
                         capture_output=True, text=True, check=True)
    result = json.loads(out.stdout.strip().splitlines()[-1])
    record = {"benchmark": "learned_nets", **result, "machine": machine_info(),
              "command": " ".join(["python", "benchmarks/bench_learned.py", *sys.argv[1:]])}
    out_path.parent.mkdir(parents=True, exist_ok=True)
    out_path.write_text(json.dumps(record, indent=2))
    print(f"best of {repeats}, batch 1, {result['threads']} threads, "
          f"onnxruntime {result['onnxruntime']}")
    print(f"{'net':12} {'torch s':>8} {'onnx s':>8} {'onnx gain':>9}")
    for key, best in result["best_s"].items():
        onnx = best.get("onnx")
        gain = f"{1 - onnx / best['torch']:9.0%}" if onnx else f"{'-':>9}"
        print(f"{key:12} {best['torch']:8.3f} {onnx or float('nan'):8.3f} {gain}")


def run_once(size: int, edge_unit: int, precision: str, mode: str) -> dict:
    return run_child(CHILD, size, edge_unit, precision, mode)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--nets", action="store_true", help="time each net alone")
    parser.add_argument("--repeats", type=int, default=8)
    parser.add_argument("--onnx-path", default="", help="extra sys.path for onnxruntime")
    parser.add_argument("--edge-unit", type=int, default=128,
                        help="edge-net padding unit (authors: 128; opt-in speed-up: 8)")
    parser.add_argument("--precision", default="fp32", choices=("fp32", "bf16"))
    parser.add_argument("--per-patch", action="store_true",
                        help="one net run per patch, same context in every pass (before "
                             "issue 18) instead of shared canvases")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    results = Path(__file__).parent / "results"
    if args.nets:
        nets_only(args.repeats, args.onnx_path, args.out or results / "learned_nets.json")
        return
    fast = args.edge_unit != 128 or args.precision != "fp32"
    name = "learned_fast" if fast else "learned"
    args.out = args.out or results / (name + ("_per_patch" if args.per_patch else "") + ".json")
    mode = "per-patch" if args.per_patch else "shared"

    # Warm-up: numba's cache for the pipeline's own kernels (the nets need none).
    subprocess.run([sys.executable, "-c", "import numpy as np, photo3d; photo3d.make("
                    "np.random.rand(64, 64, 3), depth=np.random.rand(64, 64) + 1)"],
                   check=True, capture_output=True)
    runs, diffusion = [], []
    for _ in range(args.runs):  # interleaved: both see the same machine load
        diffusion.append(run_make(args.size, "--inpainter", "diffusion"))
        runs.append(run_once(args.size, args.edge_unit, args.precision, mode))
    med = {
        "diffusion_make_s": statistics.median(r["make_s"] for r in diffusion),
        "diffusion_peak_rss_mb": max(r["peak_rss_mb"] for r in diffusion),
        "make_s": statistics.median(r["make_s"] for r in runs),
        "stages": {k: statistics.median(r["stages"][k] for r in runs) for k in runs[0]["stages"]},
        "net_s": {k: statistics.median(r["net_s"][k] for r in runs) for k in runs[0]["net_s"]},
        "peak_rss_mb": max(r["peak_rss_mb"] for r in runs),
    }
    first = runs[0]
    patches = sum(first["patches_per_pass"])
    record = {"benchmark": "make_learned", "size": args.size,
              "options": {"edge_unit": args.edge_unit, "precision": args.precision,
                          "mode": mode},
              "weights": "random, authors' architectures", "runs": runs, "median": med,
              "machine": machine_info(),
              "command": " ".join(["python", "benchmarks/bench_learned.py", *sys.argv[1:]])}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(record, indent=2))

    ws = first["stats"]["working_size"]
    print(f"motorcycle {ws[0]}x{ws[1]}, learned inpainter, random weights, "
          f"{args.runs} runs (median), {record['machine']['cpu']}, "
          f"{record['machine']['cores']} cores, {first['threads']} torch threads")
    print(f"diffusion make in the same run: {med['diffusion_make_s']:.1f} s; learned / "
          f"diffusion = {med['make_s'] / med['diffusion_make_s']:.1f}x")
    print(f"make: {med['make_s']:.1f} s  (" + ", ".join(
        f"{k} {v:.1f}" for k, v in med["stages"].items()) + ")")
    print(f"patches per pass {first['patches_per_pass']} (total {patches}); padded shapes "
          + ", ".join(f"{k}: {v}" for k, v in list(first["padded_shapes"].items())[:6]))
    print(f"{'net':6} {'runs':>6} {'Mpx':>8} {'seconds':>9} {'s/run':>7} {'s/Mpx':>7}")
    for k in ("edge", "depth", "color"):
        sec, n, mpx = med["net_s"][k], first["net_runs"][k], first["net_mpx"][k]
        print(f"{k:6} {n:6d} {mpx:8.1f} {sec:9.1f} {sec / max(n, 1):7.2f} "
              f"{sec / max(mpx, 1e-9):7.2f}")
    for k, per in enumerate(first["nets_per_pass"]):
        print(f"pass {k}: " + ", ".join(f"{n} {v['runs']} runs {v['mpx']:.2f} Mpx"
                                        for n, v in per.items()))
    print(f"edges per pass {first['stats']['edges']}")
    total = sum(med["net_s"].values())
    print(f"nets: {total:.1f} s = {total / max(patches, 1):.2f} s per patch; "
          f"peak memory {med['peak_rss_mb']:.0f} MB")
    if "cpu_s" in first:  # < the core count: the process did not get the whole machine
        print(f"cores used (CPU time / wall time of make): {first['cpu_s'] / first['make_s']:.2f}"
              f" of {record['machine']['cores']}; load average {first['load_before']:.1f} "
              f"before, {first['load_after']:.1f} after")
    print("individual make times: " + ", ".join(f"{r['make_s']:.1f}" for r in runs))


if __name__ == "__main__":
    main()
