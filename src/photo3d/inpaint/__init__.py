"""Inpainting backends behind one interface (see :mod:`photo3d.inpaint.base`).

Example:
    >>> from photo3d.inpaint import available, get_inpainter
    >>> "diffusion" in available()
    True
    >>> get_inpainter("diffusion").name
    'diffusion'
"""

from photo3d.inpaint.base import (
    Inpainter,
    InpaintResult,
    Patch,
    available,
    get_inpainter,
    register,
)

__all__ = ["Inpainter", "InpaintResult", "Patch", "available", "get_inpainter", "register"]
