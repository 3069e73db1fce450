"""photo3d: one photo plus depth -> a 3D photo (layered depth image with inpainted
occlusions), exported as meshes and rendered from new viewpoints.

Implements "3D Photography using Context-aware Layered Depth Inpainting"
(Shih et al., CVPR 2020).

Example:
    >>> import numpy as np, photo3d
    >>> img = np.zeros((32, 32, 3), np.float32)
    >>> disp = np.ones((32, 32), np.float32); disp[8:24, 8:24] = 2.0
    >>> photo = photo3d.make(img, depth=disp, config=photo3d.Config(size=None))
    >>> photo.mesh().faces.shape[1]
    3
"""

from photo3d.config import PRESETS, Config
from photo3d.errors import ConfigError, InputError, MissingExtra, OutputError, Photo3DError

__version__ = "0.1.0"

_LAZY = {"load": ("photo3d.photo", "load"), "make": ("photo3d.pipeline", "make"),
         "Photo3D": ("photo3d.photo", "Photo3D"),
         "SaveOptions": ("photo3d.save_options", "SaveOptions")}


def __getattr__(name: str):
    """Import the pipeline on first use: ``import photo3d`` (and the command line's
    start, where Ctrl-C must already be handled) stays fast."""
    if name in _LAZY:
        import importlib

        module, attr = _LAZY[name]
        return getattr(importlib.import_module(module), attr)
    raise AttributeError(f"module 'photo3d' has no attribute {name!r}")

__all__ = [
    "PRESETS",
    "Config",
    "ConfigError",
    "InputError",
    "MissingExtra",
    "OutputError",
    "Photo3D",
    "Photo3DError",
    "SaveOptions",
    "load",
    "make",
]
