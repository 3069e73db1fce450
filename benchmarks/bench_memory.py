"""Peak memory of ``photo3d demo --no-video`` at several working sizes.

Each size runs in its own process; its peak resident set comes from ``os.wait4``
(the child's own ``ru_maxrss``). The fit (base + bytes per working pixel) is what
``photo3d.resources`` uses to refuse sizes that cannot fit in memory.

    python benchmarks/bench_memory.py            # writes results/memory.json
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from _machine import machine_info

HERE = Path(__file__).parent
SIZES = (256, 512, 1024)


def peak_rss(size: int, out: Path) -> tuple[int, int]:
    """``(peak bytes, working pixels incl. border)`` of one demo run at ``size``."""
    cmd = [sys.executable, "-m", "photo3d", "demo", "-o", str(out), "--size", str(size),
           "--no-video", "--no-glb", "-q"]
    proc = subprocess.Popen(cmd)
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode:
        raise SystemExit(f"{' '.join(cmd)} failed")
    meta = json.loads((out / "config.json").read_text())
    w, h = meta["stats"]["working_size"]
    from photo3d.config import Config

    border = 2 * Config(size=size).spatial(Config().regions.border, max(w, h))
    return usage.ru_maxrss * 1024, (w + border) * (h + border)


def main() -> None:
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
              + ", ".join(f"{s:.0f}" for s in slopes) + ". `photo3d.resources` estimates "
              "200 MB + 1400 B per working pixel and refuses a size that exceeds the "
              "available memory (MemAvailable) before the work; the machine was shared "
              "with other jobs while measuring."]
    record = {"command": "python benchmarks/bench_memory.py", "machine": machine_info(),
              "runs": rows, "bytes_per_pixel": slopes, "markdown": "\n".join(lines)}
    (HERE / "results" / "memory.json").write_text(json.dumps(record, indent=2))
    print(record["markdown"])


if __name__ == "__main__":
    main()
