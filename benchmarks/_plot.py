"""A minimal line plot with Pillow (no matplotlib needed for the benchmarks)."""

from __future__ import annotations

from pathlib import Path

from PIL import Image, ImageDraw

COLOURS = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40)]


def line_plot(series: dict[str, list[tuple[float, float]]], path: Path, *, x_label: str,
              y_label: str, title: str, size: tuple[int, int] = (640, 420)) -> None:
    """Draw each series (name -> [(x, y), ...]) as a polyline with markers and a legend."""
    w, h = size
    left, right, top, bottom = 70, 20, 40, 50
    img = Image.new("RGB", size, "white")
    draw = ImageDraw.Draw(img)
    xs = [x for pts in series.values() for x, _ in pts] or [0, 1]
    ys = [y for pts in series.values() for _, y in pts] or [0, 1]
    x_max, y_max = max(xs) * 1.05 or 1, max(ys) * 1.1 or 1

    def to_px(x: float, y: float) -> tuple[float, float]:
        return (left + x / x_max * (w - left - right),
                h - bottom - y / y_max * (h - top - bottom))

    draw.rectangle([left, top, w - right, h - bottom], outline="black")
    for i in range(6):
        gx, gy = x_max * i / 5, y_max * i / 5
        px, _ = to_px(gx, 0)
        _, py = to_px(0, gy)
        draw.line([px, h - bottom, px, h - bottom + 4], fill="black")
        draw.text((px - 10, h - bottom + 6), f"{gx:.2g}", fill="black")
        draw.line([left - 4, py, left, py], fill="black")
        draw.text((8, py - 6), f"{gy:.3g}", fill="black")
    for k, (name, pts) in enumerate(series.items()):
        colour = COLOURS[k % len(COLOURS)]
        pxs = [to_px(x, y) for x, y in sorted(pts)]
        if len(pxs) > 1:
            draw.line(pxs, fill=colour, width=2)
        for px, py in pxs:
            draw.ellipse([px - 3, py - 3, px + 3, py + 3], fill=colour)
        draw.text((left + 10, top + 8 + 14 * k), name, fill=colour)
    draw.text((left, 12), title, fill="black")
    draw.text((w // 2 - 60, h - 20), x_label, fill="black")
    draw.text((4, 20), y_label, fill="black")
    img.save(path)
