"""The refine colour net: a residual over the diffusion fill (photo3d's own colour net).

Instead of painting the hole from zeros (the paper's partial-convolution U-Net,
:mod:`photo3d.nets.partialconv`), the net starts from the classical fill: its RGB
input holds the context's colours and, under the hole, the harmonic (diffusion) fill
of :func:`photo3d.inpaint.diffusion.diffuse`; it predicts a residual that is added
under the hole only:

    out = clamp(fill + hole * residual, 0, 1)          (:func:`compose`)

so context pixels (and everything outside the hole) come back exactly as they went
in, and a net whose last layer is zero (how it starts training) *is* the diffusion
fill. The input channels are the colour net's (``rgb, edge, context, hole``, each
``(B, 1, H, W)`` except rgb ``(B, 3, H, W)``), so the learned backend builds them the
same way; only the RGB under the hole differs (the fill instead of zeros).

Architecture (:class:`RefineNet`): a small U-Net of gated convolutions (Yu et al.
2019, :func:`gated_conv`: LeakyReLU features times a sigmoid gate, one convolution
with twice the output channels): a 5x5 stride-2 gated stem, ``levels - 1`` stride-2
gated 3x3 convolutions (channels ``channels * 2**i`` at scale ``1 / 2**(i + 1)``),
``blocks`` residual blocks of 3x3 convolutions at the coarsest scale (1/16 by
default: a receptive field of about 400 px), then per level a 1x1 projection, a
bilinear 2x upsampling added to the encoder's output of that scale and a gated 3x3
convolution; at full resolution one gated 3x3 convolution over the upsampled
features and the input, and a 3x3 convolution (initialised to zero) gives the
residual. All the width sits at coarse scales, so it costs about 18 k multiply-adds
per pixel (the shipped compact colour U-Net: 10 k). Inputs ``(B, 6, H, W)`` float32
with ``H, W`` multiples of ``2**levels``. With ``edges=False`` the net zeroes its edge channel
itself (a net trained on photos without depth never saw an edge; training and
inference then cannot disagree about it).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor, nn

DILATIONS = (1, 2)
"""Dilations of the residual blocks, cycled (small: the coarsest maps of a 128 px
training crop are 8 x 8, and taps that only ever saw padding in training would meet
real features at inference)."""
SLOPE = 0.2
"""LeakyReLU slope of the features."""
FULL = 16
"""Channels of the one gated convolution at full resolution."""


def gated_conv(x: Tensor, weight: Tensor, bias: Tensor | None = None, *, stride: int = 1,
               padding: int = 0, dilation: int = 1) -> Tensor:
    """Gated convolution: ``leaky_relu(f, 0.2) * sigmoid(g)`` where ``(f, g)`` are the two
    halves of one convolution's output channels.

    Args:
        x: ``(B, C_in, H, W)`` float.
        weight: ``(2 C_out, C_in, k, k)``: features first, gates second.
        bias: ``(2 C_out,)`` or None.
        stride, padding, dilation: as in ``torch.nn.functional.conv2d`` (zero padding).

    Returns:
        ``(B, C_out, H', W')``.

    Example:
        >>> w = torch.zeros(2, 1, 1, 1); w[0] = 2.0  # feature 2x, gate sigmoid(0) = 0.5
        >>> gated_conv(torch.ones(1, 1, 2, 2), w)[0, 0].tolist()
        [[1.0, 1.0], [1.0, 1.0]]
    """
    f, g = F.conv2d(x, weight, bias, stride, padding, dilation).chunk(2, dim=1)
    return F.leaky_relu(f, SLOPE) * torch.sigmoid(g)


def compose(fill: Tensor, hole: Tensor, residual: Tensor) -> Tensor:
    """``clamp(fill + hole * residual, 0, 1)``: the residual under the hole only.

    Args:
        fill: ``(B, 3, H, W)`` in [0, 1]: context colours, the diffusion fill under the
            hole, zeros elsewhere.
        hole: ``(B, 1, H, W)`` 0/1.
        residual: ``(B, 3, H, W)``.

    Example:
        >>> fill = torch.full((1, 3, 1, 2), 0.5); hole = torch.tensor([[[[0.0, 1.0]]]])
        >>> compose(fill, hole, torch.full((1, 3, 1, 2), 0.25))[0, 0].tolist()
        [[0.5, 0.75]]
    """
    return (fill + hole * residual).clamp(0.0, 1.0)


class GatedConv(nn.Module):
    """Module form of :func:`gated_conv` (one ``conv`` with ``2 out_channels`` outputs).

    Example:
        >>> tuple(GatedConv(6, 8, 3, stride=2)(torch.rand(1, 6, 16, 16)).shape)
        (1, 8, 8, 8)
    """

    def __init__(self, in_channels: int, out_channels: int, kernel_size: int = 3, *,
                 stride: int = 1, dilation: int = 1) -> None:
        super().__init__()
        self.conv = nn.Conv2d(in_channels, 2 * out_channels, kernel_size, stride,
                              dilation * (kernel_size // 2), dilation)

    def forward(self, x: Tensor) -> Tensor:
        c = self.conv
        return gated_conv(x, c.weight, c.bias, stride=c.stride[0], padding=c.padding[0],
                          dilation=c.dilation[0])


class ResBlock(nn.Module):
    """``x + conv2(leaky_relu(conv1(x)))``, 3x3 convolutions, the first dilated."""

    def __init__(self, channels: int, dilation: int) -> None:
        super().__init__()
        self.conv1 = nn.Conv2d(channels, channels, 3, padding=dilation, dilation=dilation)
        self.conv2 = nn.Conv2d(channels, channels, 3, padding=1)

    def forward(self, x: Tensor) -> Tensor:
        return x + self.conv2(F.leaky_relu(self.conv1(x), SLOPE))


class RefineNet(nn.Module):
    """Residual refinement of the diffusion fill (see the module docstring).

    Args:
        in_channels: 6 (rgb fill, edge, context, hole).
        channels: channels at full resolution; level ``i`` has ``channels * 2**i``.
        levels: stride-2 levels; inputs must be multiples of ``2**levels``.
        blocks: dilated residual blocks at the coarsest level.
        edges: read the edge channel (False: the net zeroes it).
        upsample: ``"bilinear"`` or ``"nearest"`` (nearest left a 16 px grid in flat
            regions early in training).

    ``forward(x)``: ``(B, 6, H, W)`` -> ``(B, 3, H, W)`` in [0, 1], equal to
    ``x[:, :3]`` wherever the hole channel ``x[:, 5]`` is 0.

    Example:
        >>> net = RefineNet(channels=4, levels=2, blocks=1).eval()
        >>> x = torch.rand(1, 6, 16, 16); x[:, 4:] = (x[:, 4:] > 0.5).float()
        >>> bool(torch.equal(net(x), x[:, :3]))  # the residual starts at zero
        True
    """

    def __init__(self, in_channels: int = 6, *, channels: int = 16, levels: int = 4,
                 blocks: int = 4, edges: bool = True, upsample: str = "bilinear") -> None:
        super().__init__()
        if in_channels != 6:
            raise ValueError(f"the refine net takes 6 input channels, not {in_channels}")
        if upsample not in ("bilinear", "nearest"):
            raise ValueError(f"upsample must be bilinear or nearest, not {upsample!r}")
        if channels < 1 or levels < 1 or blocks < 0:
            raise ValueError(f"bad refine net size: channels {channels}, levels {levels}, "
                             f"blocks {blocks}")
        self.config = dict(arch="refine", channels=channels, levels=levels, blocks=blocks,
                           edges=bool(edges), upsample=upsample)
        self.levels, self.edges, self.upsample = levels, bool(edges), upsample
        self.input_multiple = 2**levels  # input height and width must be multiples of it
        ch = [channels * 2**i for i in range(levels)]  # scales 1/2 .. 1/2**levels
        self.stem = GatedConv(in_channels, ch[0], 5, stride=2)
        self.down = nn.ModuleList(GatedConv(ch[i], ch[i + 1], 3, stride=2)
                                  for i in range(levels - 1))
        self.blocks = nn.Sequential(*(ResBlock(ch[-1], DILATIONS[i % len(DILATIONS)])
                                      for i in range(blocks)))
        self.project = nn.ModuleList(nn.Conv2d(ch[i + 1], ch[i], 1) for i in range(levels - 1))
        self.up = nn.ModuleList(GatedConv(ch[i], ch[i], 3) for i in range(levels - 1))
        self.full = GatedConv(ch[0] + in_channels, FULL, 3)
        self.head = nn.Conv2d(FULL, 3, 3, padding=1)
        nn.init.zeros_(self.head.weight)
        nn.init.zeros_(self.head.bias)

    def residual(self, x: Tensor) -> Tensor:
        """The residual ``(B, 3, H, W)`` (before :func:`compose`)."""
        unit = self.input_multiple
        if x.shape[-1] % unit or x.shape[-2] % unit:
            raise ValueError(f"input is {x.shape[-2]}x{x.shape[-1]}; height and width must "
                             f"be multiples of {unit}")
        known = (x[:, 4:5] + x[:, 5:6]).clamp(0, 1)
        edge = x[:, 3:4] if self.edges else torch.zeros_like(x[:, 3:4])
        x = torch.cat([(x[:, :3] - 0.5) * known, edge, x[:, 4:6]], 1)
        h = self.stem(x)
        skips = [h]
        for down in self.down:
            h = down(h)
            skips.append(h)
        h = self.blocks(skips.pop())
        for i in range(self.levels - 2, -1, -1):
            h = F.interpolate(self.project[i](h), scale_factor=2.0, mode=self.upsample)
            h = self.up[i](h + skips.pop())
        h = F.interpolate(h, scale_factor=2.0, mode=self.upsample)
        return self.head(self.full(torch.cat([h, x], 1)))

    def forward(self, x: Tensor) -> Tensor:
        return compose(x[:, :3], x[:, 5:6], self.residual(x))
