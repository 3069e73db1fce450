"""Sample grids of a training run: one row per sample, four columns
(input | regions | output | target), written as PNG.

* colour: the net's RGB input, regions (red = context, green = synthesis, blue =
  the gaps the hole channel adds), output, target crop;
* depth: input and output and target as inverse log depth (near = bright), scaled
  per row by the target's range;
* edge: RGB input with its edges in white, regions, output edge probability, target
  edges.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from photo3d.io.images import write_image
from photo3d.train.samples import Sample


def _grey(x: np.ndarray) -> np.ndarray:
    return np.repeat(np.clip(x, 0, 1)[..., None], 3, axis=2)


def sample_row(kind: str, sample: Sample, output: np.ndarray) -> list[np.ndarray]:
    """The four ``(S, S, 3) float32`` cells of one sample (``output``: ``(C, S, S)``).

    Example:
        >>> s = Sample(np.zeros((4, 8, 8), np.float32), np.zeros((1, 8, 8), np.float32),
        ...            *(np.ones((8, 8), bool),) * 3, np.zeros((8, 8), np.float32), 0, 1, False)
        >>> [c.shape for c in sample_row("depth", s, np.zeros((1, 8, 8)))][0]
        (8, 8, 3)
    """
    regions = np.stack([sample.context, sample.synthesis, sample.hole & ~sample.synthesis],
                       axis=2).astype(np.float32)
    if kind == "color":
        return [np.moveaxis(sample.inputs[:3], 0, 2), regions,
                np.moveaxis(output[:3], 0, 2), np.moveaxis(sample.target, 0, 2)]
    if kind == "depth":
        lo, hi = float(sample.target.min()), float(sample.target.max())

        def show(log_depth: np.ndarray) -> np.ndarray:
            return _grey((hi - log_depth) / max(hi - lo, 1e-6))

        return [show(sample.inputs[0]) * sample.context[..., None], regions, show(output[0]),
                show(sample.target[0])]
    rgb = np.moveaxis(sample.inputs[:3], 0, 2)
    rgb = np.where(sample.inputs[4][..., None] > 0, 1.0, rgb)
    return [rgb, regions, _grey(output[0]), _grey(sample.target[0])]


def sample_grid(path: str | Path, kind: str, samples: Sequence[Sample], output: np.ndarray, *,
                rows: int = 4) -> Path:
    """Write the first ``rows`` samples of a batch as a PNG grid (2 px white lines).

    Args:
        path: ``.png`` file.
        kind: ``"edge"``, ``"depth"`` or ``"color"``.
        samples: the batch.
        output: ``(B, C, S, S)`` the net's output on it.
        rows: samples shown.

    Example:
        >>> import tempfile
        >>> s = Sample(np.zeros((6, 8, 8), np.float32), np.zeros((3, 8, 8), np.float32),
        ...            *(np.ones((8, 8), bool),) * 3, np.zeros((8, 8), np.float32), 0, 1, False)
        >>> path = Path(tempfile.mkdtemp()) / "g.png"
        >>> sample_grid(path, "color", [s], np.zeros((1, 3, 8, 8))).name
        'g.png'
    """
    lines = []
    for sample, out in zip(samples[:rows], output[:rows], strict=False):
        cells = [np.pad(c, ((1, 1), (1, 1), (0, 0)), constant_values=1.0)
                 for c in sample_row(kind, sample, out)]
        lines.append(np.concatenate(cells, axis=1))
    path = Path(path)
    write_image(path, np.concatenate(lines, axis=0).astype(np.float32))
    return path
