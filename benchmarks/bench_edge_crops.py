"""How close the cropped joint edge-net runs come to one run over the whole canvas.

The learned backend runs the edge net of a pass on crops of the pass's joint canvas
(``photo3d/inpaint/crops.py``): every synthesis pixel once, with ``halo`` pixels of
surroundings. The authors' edge net normalises each instance, so a crop's outputs
differ slightly from one run over the whole canvas. This takes the first pass of the
motorcycle at 1024 px (the learned backend's patches), the authors' edge architecture
with random weights (seed 0, as ``bench_learned.py``), and compares, inside the
synthesis pixels, the edge probabilities of: crops with halos 32, 48 and 64 px, and
the two horizontal bands of patches used before the crops, against the whole-canvas
run. Writes ``results/edge_crops.json``.

Usage: python benchmarks/bench_edge_crops.py
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _machine import machine_info  # noqa: E402

HALOS = (32, 48, 64)


class _Captured(Exception):
    pass


def first_pass_patches():
    """The patches of the learned backend's first pass on the 1024 px motorcycle."""
    import torch

    import photo3d
    from photo3d.inpaint.learned import LearnedInpainter
    from photo3d.nets import InpaintingNets, build_net
    from photo3d.sample import motorcycle

    class Capture(LearnedInpainter):
        def inpaint(self, patches, *, progress=None, pass_index=0):
            self.patches = list(patches)
            raise _Captured

    nets = {k: build_net(k).eval() for k in ("edge", "depth", "color")}
    backend = Capture(nets=InpaintingNets(**nets, device=torch.device("cpu"), sources={}))
    s = motorcycle()
    try:
        photo3d.make(s.left, depth=np.asarray(s.disparity), inpainter=backend)
    except _Captured:
        return backend.patches
    raise RuntimeError("the pipeline made no patches")


def main() -> None:
    import torch

    from photo3d.camera import DepthMapping
    from photo3d.inpaint.canvas import joint_patch
    from photo3d.inpaint.crops import cover, overlap
    from photo3d.inpaint.netinputs import NetInputs
    from photo3d.inpaint.netrun import run_batched
    from photo3d.nets import build_net

    todo = sorted((p for p in first_pass_patches() if NetInputs.touches(p)),
                  key=lambda p: 2 * p.origin[0] + p.shape[0])
    torch.manual_seed(0)
    net = build_net("edge").eval()
    cpu = torch.device("cpu")
    whole = joint_patch(todo)
    it = NetInputs(whole, DepthMapping())
    syn = it.syn > 0
    x = it.edge_input(it.edges)
    ref = run_batched(net, [x], device=cpu, unit=128)[0][0]

    def compare(got: np.ndarray, mpx: float) -> dict:
        d = np.abs(got - ref)[syn]
        return {"mpx": round(mpx, 3), "mean": float(d.mean()),
                "p99": float(np.quantile(d, 0.99)), "max": float(d.max()),
                "flips": float(((got > 0.002) != (ref > 0.002))[syn].mean())}

    out = {}
    for halo in HALOS:
        crops = cover(syn, halo=halo, unit=128, max_pixels=600_000,
                      phase=getattr(net, "input_multiple", 1))
        got = np.full(syn.shape, np.nan, np.float32)
        for c, o in zip(crops, run_batched(net, [c.take(x) for c in crops], device=cpu,
                                           unit=128), strict=True):
            got[c.slices()] = o[0][c.local()]
        out[f"crops, halo {halo}"] = compare(got, sum(
            (c.window[2] - c.window[0]) * (c.window[3] - c.window[1]) for c in crops) / 1e6)
    # before the crops: two horizontal bands of patches, each its own joint canvas
    cuts = np.linspace(0, len(todo), 3).round().astype(int)
    got, mpx = np.zeros(syn.shape, np.float32), 0.0
    y0, x0 = whole.origin
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        band = joint_patch(todo[a:b])
        bt = NetInputs(band, DepthMapping())
        o = run_batched(net, [bt.edge_input(bt.edges)], device=cpu, unit=128)[0][0]
        mpx += np.prod([-(-n // 128) * 128 for n in band.shape]) / 1e6
        both = overlap((y0, x0, y0 + whole.shape[0], x0 + whole.shape[1]), band.shape,
                       band.origin)
        mine = bt.syn[both[1]] > 0
        view = got[both[0]]
        view[mine] = np.maximum(view[mine], o[both[1]][mine])
    out["bands (before)"] = compare(got, mpx)
    record = {"benchmark": "edge_crops", "canvas": list(whole.shape), "patches": len(todo),
              "reference_mean_probability": float(ref[syn].mean()), "variants": out,
              "machine": machine_info(), "command": "python benchmarks/bench_edge_crops.py"}
    path = Path(__file__).parent / "results" / "edge_crops.json"
    path.write_text(json.dumps(record, indent=2))
    for name, v in out.items():
        print(f"{name:16} {v['mpx']:.3f} Mpx  |diff| mean {v['mean']:.4f}  p99 {v['p99']:.4f}  "
              f"max {v['max']:.4f}  flips at 0.002 {v['flips']:.5f}")


if __name__ == "__main__":
    main()
