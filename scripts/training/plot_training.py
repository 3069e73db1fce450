"""Plot a colour-net training run: the training loss and the held-out score per step.

Reads ``RUN_DIR/losses.csv`` (one row per step) and ``RUN_DIR/heldout.csv`` (written
every ``--heldout-every`` steps by ``photo3d train color ... --heldout DIR``) of one or
more runs and draws into one PNG (Pillow only, no matplotlib):

1. per run, the training loss (``total``, and its L1 term: ``5 x hole`` for the refine net,
   ``6 x synthesis`` for the partial-convolution net), a running mean over ``--smooth``
   steps;
2. the held-out regions LPIPS of every run's net, with diffusion's (the reference) as a
   dashed line, the issue's target (25 % below diffusion) and any ``--reference``;
3. the held-out PSNR, likewise (the target: no more than 0.5 dB below diffusion).

Usage: python scripts/training/plot_training.py RUN_DIR [RUN_DIR ...]
           [--out docs/img/training_refine.png] [--smooth 100]
           [--reference structured=0.2164,22.66]
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


def plot(runs: list[Path], out: Path, *, smooth: int = 100,
         references: dict[str, tuple[float, float]] | None = None) -> Path:
    """One loss panel per run, then the held-out LPIPS and PSNR of every run's net
    against diffusion's (read from the first run's ``heldout.csv``), the target, and
    ``references`` (name -> (lpips, psnr), e.g. the structured fill on the same set)."""
    panels = []
    curves: dict[str, list[dict[str, str]]] = {}
    diffusion: list[dict[str, str]] = []
    x_max = 1.0
    for run in runs:
        losses = read_csv(run / "losses.csv")
        held = read_csv(run / "heldout.csv")
        net = [r for r in held if r["method"] == "net"]
        diffusion = diffusion or [r for r in held if r["method"] == "diffusion"]
        steps = np.array([int(r["step"]) for r in losses], float)
        x_max = max([x_max, steps.max() if steps.size else 0.0]
                    + [float(r["step"]) for r in net])
        if net:
            curves[run.name] = net
        if losses:
            series = {f"total loss (mean of {smooth} steps)": (
                steps, running_mean(np.array([float(r["total"]) for r in losses]), smooth))}
            for column, weight in (("hole", 5), ("synthesis", 6)):  # refine, partialconv
                if column in losses[0]:
                    series[f"{weight} x {column} L1"] = (steps, running_mean(
                        weight * np.array([float(r[column] or "nan") for r in losses]),
                        smooth))
            panels.append((series, {}, f"training loss, run {run.name}", "running mean"))
    for k, (metric, label, target) in enumerate((("lpips", "lower is better", 0.75),
                                                 ("psnr", "dB, higher is better", None))):
        if not curves:
            break
        ref = {}
        if diffusion:
            d = float(diffusion[0][metric])
            ref[f"diffusion {d:.3f}" if metric == "lpips" else f"diffusion {d:.2f}"] = d
            ref["target (issue 28)"] = d * target if target else d - 0.5
        for name, values in (references or {}).items():
            ref[f"{name} {values[k]:.3f}" if metric == "lpips" else
                f"{name} {values[k]:.2f}"] = values[k]
        series = {f"{name}, held-out ({len(net)} scores)": (
            np.array([float(r["step"]) for r in net]), np.array([float(r[metric]) for r in net]))
            for name, net in curves.items()}
        panels.append((series, ref, f"held-out regions {metric.upper()}", label))
    if not panels:
        raise SystemExit(f"{', '.join(map(str, runs))}: no losses.csv or heldout.csv")
    images = [panel(series, ref, title=title, y_label=label, x_max=x_max)
              for series, ref, title, label in panels]
    canvas = Image.new("RGB", (images[0].width, sum(p.height for p in images)), "white")
    y = 0
    for p in images:
        canvas.paste(p, (0, y))
        y += p.height
    out.parent.mkdir(parents=True, exist_ok=True)
    canvas.save(out)
    return out


def steps_to(net: list[dict[str, str]], target: float, *, last: int | None = None
             ) -> float | None:
    """Steps at which the held-out LPIPS of ``net`` (``heldout.csv`` rows) would reach
    ``target``, extrapolating a straight line in log(step) through its scores after
    step 0 (the ``last`` of them if given; least squares); None if that line does not
    fall.

    Example:
        >>> rows = [{"step": str(s), "lpips": str(0.5 - 0.1 * np.log10(s))}
        ...         for s in (10, 100, 1000)]
        >>> round(steps_to(rows, 0.1))
        10000
    """
    pts = [(float(r["step"]), float(r["lpips"])) for r in net if float(r["step"]) > 0]
    pts = pts[-last:] if last else pts
    if len(pts) < 2:
        return None
    x = np.log10([p[0] for p in pts])
    slope, intercept = np.polyfit(x, [p[1] for p in pts], 1)
    if slope >= 0:
        return None
    return float(10 ** ((target - intercept) / slope))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", type=Path, nargs="+",
                        help="run folders (photo3d train --out)")
    parser.add_argument("--out", type=Path, default=Path(__file__).parents[2] / "docs" / "img"
                        / "training_refine.png")
    parser.add_argument("--smooth", type=int, default=100)
    parser.add_argument("--reference", action="append", default=[], metavar="NAME=LPIPS,PSNR",
                        help="another fill's held-out score on the same photos, drawn as a "
                             "line (e.g. structured=0.2164,22.66)")
    args = parser.parse_args()
    refs = {}
    for item in args.reference:
        name, _, values = item.partition("=")
        lp, ps = (float(v) for v in values.split(","))
        refs[name] = (lp, ps)
    print(plot(args.runs, args.out, smooth=args.smooth, references=refs))
    for run in args.runs:
        held = read_csv(run / "heldout.csv")
        net = [r for r in held if r["method"] == "net"]
        diffusion = [float(r["lpips"]) for r in held if r["method"] == "diffusion"]
        if not net or not diffusion:
            continue
        target = 0.75 * diffusion[0]
        at = steps_to(net, target)
        print(f"{run.name}: held-out LPIPS {float(net[-1]['lpips']):.4f} at step "
              f"{net[-1]['step']}; target {target:.4f} at step "
              + (f"{at:.2g}" if at else "never") + " (a line in log(step) through its "
              "scores after step 0)")


if __name__ == "__main__":
    main()
