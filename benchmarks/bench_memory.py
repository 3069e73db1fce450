"""Peak memory of every command against the estimate it checks before the work.

Each run is its own process; its peak resident set is the larger of ``os.wait4``'s
``ru_maxrss`` (its largest process) and the sum over its process tree sampled every
20 ms (``batch``'s workers). ``photo3d.resources`` states each command's estimate
(one model: named terms, linear in what the command holds); the table compares them.

    python benchmarks/bench_memory.py            # make's sizes: results/memory.json
    python benchmarks/bench_memory.py --commands # every command: results/memory_commands.json

``--commands`` runs the full-size worst cases: ``make`` of the worst depth map found
(3x3 blocks of uniform noise, the Middlebury motorcycle's 741x500 left view) at
1024 px with ``--export splats.spz``; ``export`` of that 3D photo (its LDI at make's
limit, 2 pixels per lattice position) in every format and ``mesh.usdz`` alone;
``render --still`` at 4000x4000 and ``--ssaa 2`` at 3000x3000, and of a small 3D
photo (256 px) magnified to 6000x6000 and 9000x9000 (``--ssaa 1``: the holes the
magnified view leaves run the pyramid fill at full size); a 4-frame video;
``depth`` of a 4000x4000 PNG and its 16-bit map; ``batch`` of two photos on two
workers at 512 px; a UI request at 1024 px; two training steps. About 10 minutes on
2 cores; the largest peak is about 8 GB (the 9000x9000 still; ``--skip-9000``).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

from _machine import machine_info
from _peak import peak

HERE = Path(__file__).parent
SIZES = (256, 512, 1024)


def measure(cmd: list[str], cwd: Path) -> int:
    """Peak resident bytes of ``cmd`` (which must succeed) and its children
    (:func:`_peak.peak`)."""
    rss, status, err = peak(cmd, cwd=cwd)
    if status:
        raise SystemExit(f"{' '.join(cmd)} failed: {err}")
    return rss


def peak_rss(size: int, out: Path) -> tuple[int, int]:
    """``(peak bytes, working pixels incl. border)`` of one demo run at ``size``."""
    cmd = [sys.executable, "-m", "photo3d", "demo", "-o", str(out), "--size", str(size),
           "--no-video", "--no-glb", "-q"]
    rss = measure(cmd, out.parent)
    meta = json.loads((out / "config.json").read_text())
    w, h = meta["stats"]["working_size"]
    from photo3d.config import Config

    border = 2 * Config(size=size).spatial(Config().regions.border, max(w, h))
    return rss, (w + border) * (h + border)


def make_sizes() -> None:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for size in SIZES:
            rss, pixels = peak_rss(size, Path(tmp) / f"d{size}")
            rows.append({"size": size, "pixels": pixels, "peak_mb": round(rss / 1e6, 1)})
    slopes = [(b["peak_mb"] - a["peak_mb"]) * 1e6 / (b["pixels"] - a["pixels"])
              for a, b in zip(rows, rows[1:], strict=False)]
    lines = ["| --size | working pixels (with border) | peak memory |", "| --- | --- | --- |"]
    lines += [f"| {r['size']} | {r['pixels']:,} | {r['peak_mb']:.0f} MB |" for r in rows]
    lines += ["", "Bytes per extra working pixel between consecutive sizes: "
              + ", ".join(f"{s:.0f}" for s in slopes) + "."]
    record = {"command": "python benchmarks/bench_memory.py", "machine": machine_info(),
              "runs": rows, "bytes_per_pixel": slopes, "markdown": "\n".join(lines)}
    (HERE / "results" / "memory.json").write_text(json.dumps(record, indent=2))
    print(record["markdown"])


def _inputs(folder: Path) -> None:
    """The motorcycle's left view with its noise-block depth, a 4000x4000 photo and
    its 16-bit depth PNG, and two small photos for batch."""
    import numpy as np
    from PIL import Image

    from photo3d.sample import motorcycle

    sample = motorcycle()
    Image.fromarray(np.round(sample.left * 255).astype(np.uint8)).save(folder / "left.png")
    h, w = sample.disparity.shape
    rng = np.random.default_rng(0)
    blocks = rng.random((h // 3 + 1, w // 3 + 1)).repeat(3, 0).repeat(3, 1)[:h, :w]
    np.save(folder / "blocks.npy", blocks.astype(np.float32))
    n = 4000
    img = (rng.random((n // 8, n // 8, 3)) * 255).astype(np.uint8).repeat(8, 0).repeat(8, 1)
    Image.fromarray(img).save(folder / "big.png")
    d = np.full((n, n), 1000, np.uint16)
    d[:, n // 2:] = 3000
    Image.fromarray(d).save(folder / "big_depth.png")
    for sub in ("in", "depth"):
        (folder / sub).mkdir()
    for name in ("a", "b"):
        (folder / "in" / f"{name}.png").write_bytes((folder / "left.png").read_bytes())
        np.save(folder / "depth" / f"{name}.npy", blocks.astype(np.float32))


def commands(skip_9000: bool) -> None:
    from photo3d.config import Config
    from photo3d.io.npz import ldi_pixels
    from photo3d.resources import (
        depth_memory_estimate,
        export_memory_estimate,
        memory_estimate,
        render_memory_estimate,
    )
    from photo3d.resources.make import batch_estimate
    from photo3d.save_options import EXPORT_FORMATS

    py = [sys.executable, "-m", "photo3d"]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        _inputs(t)

        def row(name: str, cmd: list[str], estimate: int) -> None:
            peak = measure(cmd, t)
            rows.append({"case": name, "peak_mb": round(peak / 1e6), "estimate_mb":
                         round(estimate / 1e6), "ratio": round(peak / estimate, 2)})
            print(rows[-1], flush=True)

        shape = (500, 741)
        row("make, noise blocks, 1024 px, --export splats.spz",
            py + ["make", "left.png", "--depth", "blocks.npy", "-o", "noise", "--no-video",
                  "--export", "splats.spz", "-q"],
            memory_estimate(shape, Config(), ("splats.spz",)))
        row("make, noise blocks, 256 px", py + ["make", "left.png", "--depth", "blocks.npy",
                                               "-o", "small", "--size", "256", "--no-video",
                                               "-q"],
            memory_estimate(shape, Config(size=256)))
        ldi, small = ldi_pixels(t / "noise" / "photo3d.npz"), ldi_pixels(t / "small" /
                                                                          "photo3d.npz")
        row(f"export mesh.usdz ({ldi:,} LDI pixels)",
            py + ["export", "noise", "mesh.usdz", "-o", "x.usdz", "-q"],
            export_memory_estimate(ldi, ["mesh.usdz"]))
        row("export, all five formats", py + ["export", "noise", *EXPORT_FORMATS, "-q"],
            export_memory_estimate(ldi, EXPORT_FORMATS))
        row("export splats.spz splats.ply --splats dense",
            py + ["export", "noise", "splats.spz", "splats.ply", "--splats", "dense", "-q"],
            export_memory_estimate(ldi, ["splats.spz", "splats.ply"]))
        for folder, pixels, size, ssaa in (("noise", ldi, 4000, 1), ("noise", ldi, 3000, 2),
                                           ("small", small, 6000, 1),
                                           ("small", small, 9000, 1)):
            if size == 9000 and skip_9000:
                continue
            row(f"render --still {size}x{size} --ssaa {ssaa} ({pixels:,} LDI pixels)",
                py + ["render", folder, "--still", "--size", f"{size}x{size}", "--ssaa",
                      str(ssaa), "-q"],
                render_memory_estimate(pixels, (size, size), ssaa=ssaa))
        row("render, 4 frames 1920x1080 --ssaa 2",
            py + ["render", "noise", "--size", "1920x1080", "--frames", "4", "--path",
                  "circle", "-q"],
            render_memory_estimate(ldi, (1920, 1080), ssaa=2, video=True))
        row("depth 4000x4000 --depth 16-bit PNG",
            py + ["depth", "big.png", "--depth", "big_depth.png", "-o", "big_out.png"],
            depth_memory_estimate((4000, 4000)))
        row("batch, 2 photos, 2 workers, 512 px",
            py + ["batch", "in", "--depth", "depth", "-o", "batch", "--workers", "2",
                  "--size", "512", "--no-video", "-q"],
            batch_estimate(Config(size=512), workers=2).bytes)
        (t / "request").mkdir()
        ui = ("from pathlib import Path\nfrom photo3d.ui.job import JobOptions, run_job\n"
              "for _ in run_job(Path('left.png'), Path('request'), depth=Path('blocks.npy'),"
              " options=JobOptions(size=1024, videos=False)):\n    pass\n")
        row("UI request, noise blocks, 1024 px", [sys.executable, "-c", ui],
            memory_estimate(shape, Config(size=1024), ("splats.spz",)))
    lines = ["| case | peak | estimate | peak / estimate |", "| --- | --- | --- | --- |"]
    lines += [f"| {r['case']} | {r['peak_mb']} MB | {r['estimate_mb']} MB | {r['ratio']} |"
              for r in rows]
    record = {"command": "python benchmarks/bench_memory.py --commands",
              "machine": machine_info(), "runs": rows, "markdown": "\n".join(lines)}
    (HERE / "results" / "memory_commands.json").write_text(json.dumps(record, indent=2))
    print(record["markdown"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--commands", action="store_true",
                        help="every command's full-size worst case against its estimate")
    parser.add_argument("--skip-9000", action="store_true",
                        help="leave out the 9000x9000 still (about 8 GB)")
    args = parser.parse_args()
    if args.commands:
        commands(args.skip_9000)
    else:
        make_sizes()


if __name__ == "__main__":
    main()
