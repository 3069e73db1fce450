"""Small numba helpers shared by the LDI kernels (lattice steps, union-find)."""

from __future__ import annotations

import numba


@numba.njit(cache=True, inline="always")
def step(pos, d, rows, cols):  # pragma: no cover - jit
    """Flat lattice position one step from ``pos`` in direction ``d`` (L, R, U, D),
    or -1 outside the lattice."""
    r = pos // cols
    c = pos - r * cols
    if d == 0:
        return pos - 1 if c > 0 else -1
    if d == 1:
        return pos + 1 if c < cols - 1 else -1
    if d == 2:
        return pos - cols if r > 0 else -1
    return pos + cols if r < rows - 1 else -1


@numba.njit(cache=True)
def find_root(parent, i):  # pragma: no cover - jit
    """Union-find root of ``i`` with path halving."""
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@numba.njit(cache=True)
def union(parent, a, b):  # pragma: no cover - jit
    """Join the sets of ``a`` and ``b``; the smaller root index wins."""
    ra, rb = find_root(parent, a), find_root(parent, b)
    if ra != rb:
        parent[max(ra, rb)] = min(ra, rb)
