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
from photo3d.errors import ConfigError, InputError, OutputError, Photo3DError
from photo3d.output import load_photo as load
from photo3d.pipeline import Photo3D, make

__version__ = "0.1.0"

__all__ = [
    "PRESETS",
    "Config",
    "ConfigError",
    "InputError",
    "OutputError",
    "Photo3D",
    "Photo3DError",
    "load",
    "make",
]
