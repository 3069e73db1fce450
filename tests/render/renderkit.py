"""Shared by the render command's tests: a small saved 3D photo."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from conftest import two_planes
from PIL import Image

from photo3d.cli import main


def small_photo(root: Path) -> Path:
    """``root/out``: a 3D photo folder of two planes at 48 px, without videos, GLB or
    viewer (``photo3d make``); its inputs ``a.png`` and ``a.npy`` beside it."""
    img, disparity = two_planes(48, 64, 32)
    Image.fromarray((img * 255).astype(np.uint8)).save(root / "a.png")
    np.save(root / "a.npy", disparity)
    out = root / "out"
    assert main(["make", str(root / "a.png"), "--depth", str(root / "a.npy"), "-o", str(out),
                 "--size", "48", "--no-video", "--no-glb", "--no-viewer", "-q"]) == 0
    return out
