"""Test helpers for memory bounds: the peak of a call's numpy and Python allocations,
and a spy on the LDI reader's allocation limits."""

from __future__ import annotations

import tracemalloc


def traced_peak(fn):
    """``(result, peak bytes numpy and Python allocated during fn())``."""
    tracemalloc.start()
    try:
        result = fn()
        return result, tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def spy_read_npy(monkeypatch) -> list[int]:
    """Record the ``max_items`` every ``photo3d.io.npz`` array read is allowed (the list
    returned fills as the reader runs)."""
    import photo3d.io.npz as npz

    read = npz.read_npy
    sizes: list[int] = []

    def spy(f, *, max_items, size=None):
        sizes.append(max_items)
        return read(f, max_items=max_items, size=size)

    monkeypatch.setattr(npz, "read_npy", spy)
    return sizes
