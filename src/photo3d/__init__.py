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

import os as _os

from photo3d.config import PRESETS, Config
from photo3d.errors import ConfigError, InputError, MissingExtra, OutputError, Photo3DError
from photo3d.parallel import library_defaults as _library_defaults

# OpenMP threads (numba's parallel kernels) that finish a parallel region spin ~300,000
# times before they sleep (GOMP's default): between photo3d's kernels (Python, serial
# steps, the video encoder's and writer threads) that spinning takes a core the
# process needs (a 1280x720 video frame on 2 busy cores: 76 ms of CPU, 46 ms with
# this). A short spin instead (set before any kernel loads OpenMP); a value the user
# set is kept.
_os.environ.setdefault("GOMP_SPINCOUNT", "10000")
# NumPy asks Linux for transparent huge pages (madvise) for every array of 4 MB or
# more, and on a machine whose memory is fragmented the first touch of each 2 MB page
# can wait for the kernel to compact memory. photo3d makes many large short-lived
# arrays: on such a machine (the one docs/speed.md was measured on) a `make` of the
# sample spent 0.3-0.4 s more system CPU that way (0.6-0.7 s against 0.8-1.3 s), its
# raw disparity about 1 s (0.9 s against 1.75-2.1 s), for no gain in user time. So
# off, unless the user set it; NumPy reads it when it is imported, so this holds when
# photo3d is imported first (the command line, its workers).
_os.environ.setdefault("NUMPY_MADVISE_HUGEPAGE", "0")
# numba and torch size their thread pools by the host's cores when they load, which
# ignores a cgroup CPU quota (a container of 2 CPUs on a 64-core host: 64 threads);
# from photo3d's budget instead (photo3d.parallel: affinity, quota, PHOTO3D_THREADS),
# unless the user set NUMBA_NUM_THREADS / OMP_NUM_THREADS.
_library_defaults()

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
