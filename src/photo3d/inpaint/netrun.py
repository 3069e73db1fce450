"""Running the inpainting nets on lists of arrays: padding and batching (the learned
backend's device side, :mod:`photo3d.inpaint.learned`).

Inputs are zero-padded, centred, to a multiple of the net's unit and stacked into
batches of equal padded shape; each batch goes to the device once and its result
comes back once (no per-patch transfers).
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # torch is imported lazily: photo3d works without it
    import torch

UNIT = 128
"""Net inputs are padded to multiples of this (the authors' ``unit_length``)."""

PRECISIONS = ("fp32", "bf16")



def padded_shape(h: int, w: int, unit: int = UNIT) -> tuple[int, int]:
    """``(h, w)`` rounded up to multiples of ``unit``."""
    return -(-h // unit) * unit, -(-w // unit) * unit


def net_unit(net) -> int:
    """The multiple the learned backend pads ``net``'s input to by default.

    :data:`UNIT` (128, the authors' ``unit_length``) for a net with the authors'
    architecture (full width, 8 residual blocks or 7 levels), or one whose
    architecture is unknown (no ``config`` or ``input_multiple``); otherwise the
    smallest multiple the net accepts, its ``input_multiple``: 4 for an
    :class:`~photo3d.nets.edge.EdgeGenerator`, ``2**levels`` for a
    :class:`~photo3d.nets.partialconv.PartialConvUNet`.

    Example:
        >>> from photo3d.nets import build_net
        >>> net_unit(build_net("edge", width=0.25, blocks=4)), net_unit(build_net("edge"))
        (4, 128)
        >>> net_unit(build_net("depth", levels=5, width=0.25))
        32
    """
    config, multiple = getattr(net, "config", None), getattr(net, "input_multiple", None)
    if not isinstance(config, dict) or multiple is None:
        return UNIT
    authors = (config.get("width") == 1.0 and config.get("blocks", 8) == 8
               and config.get("levels", 7) == 7)
    return UNIT if authors else int(multiple)


def color_scale(h: int, w: int, size: int = 512) -> float:
    """The authors' colour-net resize factor (< 1 only for large patches).

    Example:
        >>> color_scale(256, 256), color_scale(1000, 1000)
        (2.0, 0.512)
    """
    frac = size / math.sqrt(h * w)
    return math.floor(max(h, w) * frac / 128) * 128 / max(h, w)


def run_batched(net: Callable, inputs: Sequence[np.ndarray], *, device, batch_size: int = 8,
                batch_pixels: int = 8 * 256 * 256, unit: int = UNIT,
                autocast: torch.dtype | None = None) -> list[np.ndarray]:
    """Run ``net`` on ``(C, h, w)`` arrays, zero-padded (centred) to multiples of
    ``unit``, batching equal padded shapes; returns ``(C_out, h, w) float32`` arrays.
    ``autocast``: run under ``torch.autocast`` with this dtype (None = as is).

    Example:
        >>> import torch
        >>> outs = run_batched(lambda x: x[:, :1] * 2, [np.ones((2, 5, 7), np.float32)],
        ...                    device=torch.device("cpu"), unit=8)
        >>> outs[0].shape, float(outs[0].max())
        ((1, 5, 7), 2.0)
    """
    import torch

    out: list[np.ndarray | None] = [None] * len(inputs)
    groups: dict[tuple[int, int], list[int]] = {}
    for i, x in enumerate(inputs):
        groups.setdefault(padded_shape(*x.shape[1:], unit), []).append(i)
    for (hp, wp), idx in groups.items():
        step = max(1, min(batch_size, batch_pixels // (hp * wp)))
        for s in range(0, len(idx), step):
            chunk = idx[s:s + step]
            batch = np.zeros((len(chunk), inputs[chunk[0]].shape[0], hp, wp), np.float32)
            anchors = []
            for b, i in enumerate(chunk):
                h, w = inputs[i].shape[1:]
                y0, x0 = (hp - h) // 2, (wp - w) // 2
                batch[b, :, y0:y0 + h, x0:x0 + w] = inputs[i]
                anchors.append((y0, x0, h, w))
            cast = (torch.autocast(device.type, dtype=autocast) if autocast is not None
                    else contextlib.nullcontext())
            with torch.inference_mode(), cast:
                res = net(torch.from_numpy(batch).to(device)).float().cpu().numpy()
            for b, (i, (y0, x0, h, w)) in enumerate(zip(chunk, anchors, strict=True)):
                out[i] = res[b, :, y0:y0 + h, x0:x0 + w]
    return out  # type: ignore[return-value]


def release_memory() -> None:
    """Hand freed heap memory back to the operating system (glibc's ``malloc_trim``;
    nothing elsewhere). A net run frees hundreds of MB of activations, part of which
    glibc keeps on its heap, where it would count towards the process's peak memory
    while the pipeline's own arrays grow afterwards.

    Example:
        >>> release_memory()  # no effect on results
    """
    import ctypes

    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass
