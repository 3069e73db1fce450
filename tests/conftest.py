"""Synthetic scenes with known answers, shared by the stage tests."""

from __future__ import annotations

import signal
import time

import numpy as np
import pytest

from photo3d.config import Config, PreprocessConfig, RegionConfig
from photo3d.structures.mesh import Mesh

# A shell without job control starts background commands (`make test &`, a CI step
# run with `&`) with SIGINT ignored, `nohup` ignores SIGHUP, and an ignored signal
# stays ignored through exec: every process the tests start would then ignore the
# signals the signal tests send it. A Python handler is reset to the default on exec,
# so a no-op one keeps this process ignoring them and gives the children the
# signals of a foreground run.
for _sig in (signal.SIGINT, getattr(signal, "SIGHUP", None)):
    if _sig is not None and signal.getsignal(_sig) == signal.SIG_IGN:
        signal.signal(_sig, lambda *_: None)


def texture(h: int, w: int, seed: int = 0) -> np.ndarray:
    """``(h, w, 3) float32`` smooth random texture in [0.1, 0.9]."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w] / max(h, w)
    img = np.stack(
        [0.5 + 0.3 * np.sin(2 * np.pi * (rng.random() * 3 * xx + rng.random() * 3 * yy)
                            + rng.random() * 6) for _ in range(3)], axis=2)
    return img.astype(np.float32)


def two_planes(h: int = 64, w: int = 96, split: int = 48) -> tuple[np.ndarray, np.ndarray]:
    """Background plane (disparity 1) on the left, foreground (disparity 2) from ``split``."""
    disp = np.ones((h, w), np.float32)
    disp[:, split:] = 2.0
    return texture(h, w), disp


def exact_config(**regions) -> Config:
    """Config with spatial sizes taken literally (no scaling), no border by default,
    depth edges where the depth map puts them (no foreground growth, hard cuts:
    ``edges="exact"``), the diffusion fill (smooth, exact answers)."""
    base = dict(synthesis_iterations=6, context_iterations=10, edge_dilation=0, border=0)
    base.update(regions)
    return Config(size=None, spatial_scale=1.0, inpainter="diffusion", edges="exact",
                  preprocess=PreprocessConfig(min_edge_length=5, grow_foreground=0.0),
                  regions=RegionConfig(**base))


@pytest.fixture
def planes():
    return two_planes()


def grid_mesh(rows: int = 3, cols: int = 3) -> Mesh:
    """A fronto-parallel grid at z = 2.5 facing the camera, 2 triangles per cell.

    x, y are jittered (not exactly representable decimals); colours cover every
    uint8 level on the red channel once there are 256 vertices; labels cycle 1..5.
    """
    rng = np.random.default_rng(7)
    r, c = np.mgrid[0:rows, 0:cols]
    x = (c - cols / 2) * 0.37 + rng.uniform(-0.01, 0.01, r.shape)
    y = (r - rows / 2) * 0.29 + rng.uniform(-0.01, 0.01, r.shape)
    vertices = np.stack([x, y, np.full(r.shape, 2.5)], -1).reshape(-1, 3).astype(np.float32)
    i = np.arange(rows * cols)
    colors = np.stack([i % 256, 255 - i % 256, (i * 37) % 256], 1).astype(np.uint8)
    q = (r[:-1, :-1] * cols + c[:-1, :-1]).ravel()  # top-left corner of each cell
    faces = np.concatenate(
        [np.stack([q, q + cols, q + 1], 1), np.stack([q + 1, q + cols, q + cols + 1], 1)]
    )
    return Mesh(
        vertices, colors, (i % 5 + 1).astype(np.uint8), faces.astype(np.int32), 640, 480, 1.1, 0.85
    )


def quad(x0, y0, x1, y1, z, color):
    """Two triangles of the rectangle ``[x0, x1] x [y0, y1]`` at depth ``z``."""
    v = np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]], np.float32)
    return v, np.tile(np.float32(color), (4, 1)), np.array([[0, 1, 2], [0, 2, 3]], np.int32)


def merge(*meshes):
    verts, cols, faces, n = [], [], [], 0
    for v, c, f in meshes:
        verts.append(v)
        cols.append(c)
        faces.append(f + n)
        n += len(v)
    return np.concatenate(verts), np.concatenate(cols), np.concatenate(faces)


def wait_for(predicate, timeout: float) -> bool:
    """Poll ``predicate()`` every 50 ms until it is true (True) or ``timeout`` seconds
    pass (False)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.05)
    return False
