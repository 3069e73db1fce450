"""Plot a colour-net training run: the training loss and the held-out score per step.

Reads ``RUN_DIR/losses.csv`` (one row per step) and ``RUN_DIR/heldout.csv`` (written
every ``--heldout-every`` steps by ``photo3d train color ... --heldout DIR``) and draws
three panels into one PNG (Pillow only, no matplotlib):

1. the training loss (``total``, and its L1 term: ``5 x hole`` for the refine net,
   ``6 x synthesis`` for the partial-convolution net), a running mean over ``--smooth``
   steps;
2. the held-out regions LPIPS of the net, with diffusion's (the reference) as a
   dashed line and the issue's target (25 % below diffusion) dotted;
3. the held-out PSNR, with diffusion's and the target (no more than 0.5 dB below).

Usage: python benchmarks/plot_training.py RUN_DIR [--out docs/img/training_refine.png]
           [--smooth 100]
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

COLOURS = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40)]
GREY = (120, 120, 120)


def read_csv(path: Path) -> list[dict[str, str]]:
    if not path.is_file():
        return []
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def running_mean(y: np.ndarray, n: int) -> np.ndarray:
    """Mean of the last ``n`` values at each position (fewer at the start)."""
    c = np.cumsum(np.insert(y, 0, 0.0))
    i = np.arange(1, y.size + 1)
    lo = np.maximum(0, i - n)
    return (c[i] - c[lo]) / (i - lo)


def panel(series: dict[str, tuple[np.ndarray, np.ndarray]], lines: dict[str, float], *,
          title: str, y_label: str, x_max: float, size=(760, 300)) -> Image.Image:
    """Polylines (name -> (x, y)) and horizontal reference lines (name -> y), y range
    fitted to the data."""
    w, h = size
    left, right, top, bottom = 70, 20, 36, 40
    img = Image.new("RGB", size, "white")
    draw = ImageDraw.Draw(img)
    ys = [v for _, y in series.values() for v in y] + list(lines.values())
    lo, hi = (min(ys), max(ys)) if ys else (0.0, 1.0)
    pad = (hi - lo) * 0.08 or abs(hi) * 0.05 or 1.0
    lo, hi = lo - pad, hi + pad
    x_max = x_max or 1.0

    def px(x: float, y: float) -> tuple[float, float]:
        return (left + x / x_max * (w - left - right),
                h - bottom - (y - lo) / (hi - lo) * (h - top - bottom))

    draw.rectangle([left, top, w - right, h - bottom], outline="black")
    for i in range(6):
        gx, gy = x_max * i / 5, lo + (hi - lo) * i / 5
        x, _ = px(gx, lo)
        _, y = px(0, gy)
        draw.line([x, h - bottom, x, h - bottom + 4], fill="black")
        draw.text((x - 12, h - bottom + 6), f"{gx:.0f}", fill="black")
        draw.line([left - 4, y, left, y], fill="black")
        draw.text((6, y - 6), f"{gy:.3g}", fill="black")
    legend = 0
    for k, (name, yv) in enumerate(lines.items()):
        _, y = px(0, yv)
        dash = 8 if k == 0 else 3
        for x0 in range(left, w - right, 2 * dash):
            draw.line([x0, y, min(x0 + dash, w - right), y], fill=GREY, width=1)
        draw.text((w - right - 8 - 7 * len(name), y - 13), name, fill=GREY)
    for k, (name, (xv, yv)) in enumerate(series.items()):
        colour = COLOURS[k % len(COLOURS)]
        pts = [px(x, y) for x, y in zip(xv, yv, strict=True)]
        if len(pts) > 1:
            draw.line(pts, fill=colour, width=2)
        if len(pts) < 60:
            for x, y in pts:
                draw.ellipse([x - 3, y - 3, x + 3, y + 3], fill=colour)
        draw.text((left + 10, top + 6 + 14 * legend), name, fill=colour)
        legend += 1
    draw.text((left, 12), f"{title} ({y_label})", fill="black")
    draw.text((w // 2 - 20, h - 18), "step", fill="black")
    return img


def plot(run: Path, out: Path, *, smooth: int = 100) -> Path:
    losses = read_csv(run / "losses.csv")
    held = read_csv(run / "heldout.csv")
    steps = np.array([int(r["step"]) for r in losses], float)
    net = [r for r in held if r["method"] == "net"]
    diffusion = [r for r in held if r["method"] == "diffusion"]
    x_max = max([steps.max() if steps.size else 0.0]
                + [float(r["step"]) for r in net]) or 1.0
    panels = []
    if losses:
        series = {f"total loss (mean of {smooth} steps)": (
            steps, running_mean(np.array([float(r["total"]) for r in losses]), smooth))}
        for column, weight in (("hole", 5), ("synthesis", 6)):  # refine, partialconv
            if column in losses[0]:
                series[f"{weight} x {column} L1"] = (steps, running_mean(
                    weight * np.array([float(r[column]) for r in losses]), smooth))
        panels.append(panel(series, {}, title=f"training loss, run {run.name}",
                            y_label="running mean", x_max=x_max))
    if net:
        xs = np.array([float(r["step"]) for r in net])
        for metric, label, target in (("lpips", "lower is better", 0.75),
                                      ("psnr", "dB, higher is better", None)):
            ref = {}
            if diffusion:
                d = float(diffusion[0][metric])
                ref[f"diffusion {d:.3f}" if metric == "lpips" else f"diffusion {d:.2f}"] = d
                ref["target (issue 28)"] = d * target if target else d - 0.5
            ys = np.array([float(r[metric]) for r in net])
            panels.append(panel({f"net, held-out ({len(net)} scores)": (xs, ys)}, ref,
                                title=f"held-out regions {metric.upper()}", y_label=label,
                                x_max=x_max))
    if not panels:
        raise SystemExit(f"{run}: no losses.csv or heldout.csv")
    canvas = Image.new("RGB", (panels[0].width, sum(p.height for p in panels)), "white")
    y = 0
    for p in panels:
        canvas.paste(p, (0, y))
        y += p.height
    out.parent.mkdir(parents=True, exist_ok=True)
    canvas.save(out)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path, help="the run folder (photo3d train --out)")
    parser.add_argument("--out", type=Path, default=Path(__file__).parents[1] / "docs" / "img"
                        / "training_refine.png")
    parser.add_argument("--smooth", type=int, default=100)
    args = parser.parse_args()
    print(plot(args.run, args.out, smooth=args.smooth))


if __name__ == "__main__":
    main()
