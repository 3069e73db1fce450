"""Memory and disk a command needs, estimated before the work from one model, so that
what does not fit is refused at once, in one line.

Every command states its peak as a :class:`~photo3d.resources.model.Estimate` (named
terms, each linear in what the command holds) and checks it with
:func:`~photo3d.resources.model.check` before any work:

* ``make``, ``batch``, the UI: the working pixels, border included, and ``--export``'s
  formats (:mod:`.make`);
* ``render``, videos and stills: the LDI pixels and the output pixels, views and
  supersamples (:mod:`.render`);
* ``export``: the LDI pixels (``photo3d.npz``'s header) and each format (:mod:`.export`);
* ``depth``: the photo's pixels (its header) and its depth source (:mod:`.depth`);
* ``train``: a step's activations, the region pairs, a photo's preparation
  (:mod:`photo3d.train.bounds`, which needs torch).

:mod:`.outputs` checks what would fail after the work otherwise: SPZ's splat limit
and free disk space. ``tests/test_memory_model.py`` runs each command's worst case
scaled down and requires its measured peak to stay within its estimate.

Example:
    >>> from photo3d.config import Config
    >>> round(memory_estimate((768, 1024), Config()) / 1e9, 1)  # with its 60 px border
    2.1
"""

from __future__ import annotations

from photo3d.io import limits
from photo3d.resources.depth import check_depth_memory, depth_estimate, depth_memory_estimate
from photo3d.resources.export import (
    check_export_memory,
    export_estimate,
    export_memory_estimate,
)
from photo3d.resources.make import (
    BYTES_PER_PIXEL,
    check_memory,
    ldi_bound,
    make_estimate,
    memory_estimate,
)
from photo3d.resources.model import BASE_BYTES, Estimate, check
from photo3d.resources.outputs import SPZ_LIMIT, check_free_space, check_spz_limit
from photo3d.resources.render import (
    check_render_memory,
    render_memory_estimate,
    render_terms,
)

__all__ = [
    "BASE_BYTES", "BYTES_PER_PIXEL", "SPZ_LIMIT", "Estimate", "available_memory", "check",
    "check_depth_memory", "check_export_memory", "check_free_space", "check_memory",
    "check_render_memory", "check_spz_limit", "depth_estimate", "depth_memory_estimate",
    "export_estimate", "export_memory_estimate", "ldi_bound", "make_estimate",
    "memory_estimate", "render_memory_estimate", "render_terms",
]


def available_memory() -> int | None:
    """Bytes the system can give this process now (Linux ``MemAvailable``), or None
    (:func:`photo3d.io.limits.available_memory`, which the file readers check). Every
    check of this package reads it here, so a test can stand in a smaller machine.

    Example:
        >>> have = available_memory()
        >>> have is None or have > 0
        True
    """
    return limits.available_memory()
