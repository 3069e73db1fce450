"""Inpainting backends behind one interface (:mod:`photo3d.inpaint.base`), found by name.

The built-in backends are imported only when asked for (``learned`` brings torch);
:func:`register` adds one of your own. See ``docs/fills.md``.

Example:
    >>> from photo3d.inpaint import available, get_inpainter
    >>> "diffusion" in available()
    True
    >>> get_inpainter("diffusion").name
    'diffusion'
"""

from __future__ import annotations

import importlib
from collections.abc import Callable

from photo3d.errors import ConfigError
from photo3d.inpaint.base import Inpainter
from photo3d.structures.patch import InpaintResult, Patch

_BUILTIN = {
    "diffusion": ("photo3d.inpaint.diffusion", "DiffusionInpainter"),
    "structured": ("photo3d.inpaint.structured", "StructuredInpainter"),
    "learned": ("photo3d.inpaint.learned", "LearnedInpainter"),
}
"""Name -> (module, class) of the backends photo3d ships."""
_REGISTERED: dict[str, Callable[..., Inpainter]] = {}


def register(name: str, factory: Callable[..., Inpainter]) -> None:
    """Make a backend available under ``name`` (``factory(**options)`` builds it).

    Example:
        >>> from photo3d.inpaint.diffusion import DiffusionInpainter
        >>> register("mine", DiffusionInpainter)
        >>> "mine" in available()
        True
    """
    _REGISTERED[name] = factory


def available() -> list[str]:
    """Names of the backends, built in and registered."""
    return sorted({*_BUILTIN, *_REGISTERED})


def get_inpainter(name: str, **options) -> Inpainter:
    """Build the backend ``name`` with backend-specific ``options``.

    Raises:
        ConfigError: ``name`` is not a backend.
    """
    if name in _REGISTERED:
        return _REGISTERED[name](**options)
    if name not in _BUILTIN:
        raise ConfigError(f"unknown inpainter {name!r}; available: {', '.join(available())}")
    module, cls = _BUILTIN[name]
    return getattr(importlib.import_module(module), cls)(**options)


__all__ = ["Inpainter", "InpaintResult", "Patch", "available", "get_inpainter", "register"]
