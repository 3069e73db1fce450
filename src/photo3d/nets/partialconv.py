"""Partial convolution and the partial-convolution U-Net of the depth and colour nets.

A partial convolution (Liu et al. 2018) convolves only valid pixels and rescales
by the fraction of the window that was valid:

    out = W * (x . m) * (C k_h k_w) / sum_window(m) + b    where sum_window(m) > 0
    out = 0, new mask = 0                                   where sum_window(m) = 0

``m`` is the per-channel 0/1 mask. The authors' checkpoints store the window-sum
kernel as ``mask_conv.weight`` (all ones, never trained); with that kernel the
window sum is a single-channel box sum of the per-pixel count of valid channels,
which is what :func:`partial_conv` computes (a general kernel is also accepted).

:class:`PartialConvUNet` is the authors' ``Inpaint_Depth_Net`` / ``Inpaint_Color_Net``
(supplement, Table "color and depth inpainting models"): ``levels`` stride-2 partial
convolutions (7x7, 5x5, 5x5, then 3x3; BN except the first; ReLU), then per level a
nearest 2x upsampling of features and masks, concatenation with the encoder output
of the same scale (the input itself last), a 3x3 partial convolution (BN,
LeakyReLU 0.2), and a final 3x3 partial convolution without BN or activation. The
input mask is ``clamp(context + synthesis, 0, 1)`` taken from the last two input
channels. Inputs are ``(B, C, H, W)`` float32 with ``H, W`` multiples of
``2**levels``.

photo3d's own colour nets may be *centred* (``center=True``; never the authors'
nets): the net subtracts the mean colour of the context (``rgb`` under the context
channel, per image) from its RGB input, adds 0.5, and adds the mean back to its
sigmoid output (``clamp(sigmoid - 0.5 + mean, 0, 1)``). A fill then starts from the
context's own colour instead of a colour the training photos taught it (docs/learned.md:
a briefly trained net filled every hole with its training set's orange-brown).
Because the net does it itself, training and inference cannot disagree about it.
"""

from __future__ import annotations

from typing import Literal

import torch
import torch.nn.functional as F
from torch import Tensor, nn


def _window_count(count: Tensor, kernel: tuple[int, int], stride: int, padding: int) -> Tensor:
    ones = count.new_ones((1, 1, *kernel))
    return torch.round(F.conv2d(count, ones, None, stride, padding))


def _renormalised_conv(xm: Tensor, count: Tensor, weight: Tensor, bias: Tensor | None,
                       stride: int, padding: int) -> tuple[Tensor, Tensor]:
    """Partial conv of already-masked ``xm`` given ``count`` (B, 1, H, W) = number of
    valid input channels per pixel (ones mask kernel). Returns (out, new mask (B,1,h,w))."""
    raw = F.conv2d(xm, weight, None, stride, padding)
    window = weight.shape[1] * weight.shape[2] * weight.shape[3]
    msum = _window_count(count, tuple(weight.shape[2:]), stride, padding)
    valid = msum > 0
    if not torch.is_grad_enabled():  # inference: in place, fewer full-size temporaries
        out = raw.mul_(window / msum.clamp(min=1.0))  # the scale is one channel: cheap
        if bias is not None:  # out of place under bf16 autocast: promoted to float32 there
            b = bias.view(1, -1, 1, 1)
            out = out.add_(b) if b.dtype == out.dtype else out + b
        return out.mul_(valid), valid.to(out.dtype)
    out = raw * (window / msum.clamp(min=1.0))
    if bias is not None:
        out = out + bias.view(1, -1, 1, 1)
    return out * valid, valid.to(out.dtype)


def partial_conv(
    x: Tensor,
    mask: Tensor,
    weight: Tensor,
    bias: Tensor | None = None,
    *,
    stride: int = 1,
    padding: int = 0,
    mask_weight: Tensor | None = None,
) -> tuple[Tensor, Tensor]:
    """Partial convolution of ``x`` where ``mask`` is 1.

    Args:
        x: ``(B, C_in, H, W)`` float; values where ``mask`` is 0 are never read.
        mask: ``(B, C_in, H, W)`` or ``(B, 1, H, W)`` (same for every channel), 0/1.
        weight: ``(C_out, C_in, k_h, k_w)`` convolution kernel.
        bias: ``(C_out,)`` or None.
        stride, padding: as in ``torch.nn.functional.conv2d`` (zero padding).
        mask_weight: ``(C_out, C_in, k_h, k_w)`` window-sum kernel; None means all
            ones (the authors' fixed value, computed as a cheap box sum).

    Returns:
        ``(out, new_mask)``: ``out (B, C_out, H', W')`` (0 where the window held no
        valid pixel) and ``new_mask`` (1 where it held one) of shape
        ``(B, 1, H', W')``, or ``(B, C_out, H', W')`` with a ``mask_weight``.

    Example:
        >>> x = torch.arange(9.0).view(1, 1, 3, 3)
        >>> m = torch.zeros(1, 1, 3, 3); m[..., 0, :] = 1  # only the top row is valid
        >>> out, new = partial_conv(x, m, torch.ones(1, 1, 3, 3))
        >>> out.item(), new.item()  # (0 + 1 + 2) * 9 / 3
        (9.0, 1.0)
    """
    mask = mask.to(x.dtype)
    if mask_weight is None:
        count = mask.sum(1, keepdim=True) if mask.shape[1] > 1 else mask * x.shape[1]
        return _renormalised_conv(x * mask, count, weight, bias, stride, padding)
    raw = F.conv2d(x * mask, weight, None, stride, padding)
    msum = F.conv2d(mask.expand(-1, x.shape[1], -1, -1), mask_weight, None, stride, padding)
    valid = msum != 0
    window = weight.shape[1] * weight.shape[2] * weight.shape[3]
    out = raw * (window / msum.masked_fill(~valid, 1.0))
    if bias is not None:
        out = out + bias.view(1, -1, 1, 1)
    return out * valid, valid.to(out.dtype)


class _MaskKernel(nn.Module):
    """Holds ``weight``, the window-sum kernel (the authors' ``mask_conv``)."""

    def __init__(self, shape: tuple[int, ...]) -> None:
        super().__init__()
        self.register_buffer("weight", torch.ones(shape))
        self.is_ones = True

    def _load_from_state_dict(self, *args, **kwargs) -> None:
        super()._load_from_state_dict(*args, **kwargs)
        self.is_ones = bool(torch.all(self.weight == 1))


class PartialConv(nn.Module):
    """Module form of :func:`partial_conv` (keys ``input_conv.*``, ``mask_conv.weight``).

    Example:
        >>> pc = PartialConv(3, 8, 5, stride=2, padding=2)
        >>> out, mask = pc(torch.rand(1, 3, 16, 16), torch.ones(1, 1, 16, 16))
        >>> tuple(out.shape), tuple(mask.shape)
        ((1, 8, 8, 8), (1, 1, 8, 8))
    """

    def __init__(self, in_channels: int, out_channels: int, kernel_size: int, *,
                 stride: int = 1, padding: int = 0, bias: bool = True) -> None:
        super().__init__()
        self.input_conv = nn.Conv2d(in_channels, out_channels, kernel_size, stride, padding,
                                    bias=bias)
        self.mask_conv = _MaskKernel(tuple(self.input_conv.weight.shape))
        self.stride, self.padding = stride, padding

    def forward(self, x: Tensor, mask: Tensor) -> tuple[Tensor, Tensor]:
        mw = None if self.mask_conv.is_ones else self.mask_conv.weight
        return partial_conv(x, mask, self.input_conv.weight, self.input_conv.bias,
                            stride=self.stride, padding=self.padding, mask_weight=mw)

    def masked_forward(self, xm: Tensor, count: Tensor) -> tuple[Tensor, Tensor]:
        """Fast path for the U-Net: ``xm`` already zero where invalid, ``count
        (B, 1, H, W)`` the number of valid channels per pixel. Needs the all-ones mask
        kernel (a general kernel needs per-channel masks: use :meth:`forward`)."""
        if not self.mask_conv.is_ones:
            raise ValueError("mask_conv.weight must be all ones in a U-Net layer")
        return _renormalised_conv(xm, count, self.input_conv.weight, self.input_conv.bias,
                                  self.stride, self.padding)


class PartialConvBlock(nn.Module):
    """Partial conv, optional BatchNorm, activation (the authors' ``PCBActiv``).

    ``forward(xm, count)`` takes masked features and the valid-channel count, and
    returns masked features and the new ``(B, 1, H, W)`` mask.
    """

    def __init__(self, in_channels: int, out_channels: int, kernel_size: int, *,
                 stride: int = 1, bias: bool = False, bn: bool = True,
                 activation: Literal["relu", "leaky"] | None = "relu") -> None:
        super().__init__()
        self.conv = PartialConv(in_channels, out_channels, kernel_size, stride=stride,
                                padding=kernel_size // 2, bias=bias)
        if bn:
            self.bn = nn.BatchNorm2d(out_channels)
        self.activation = activation

    def forward(self, xm: Tensor, count: Tensor) -> tuple[Tensor, Tensor]:
        h, m = self.conv.masked_forward(xm, count)
        if hasattr(self, "bn"):
            h = self.bn(h)
        if not torch.is_grad_enabled():  # inference: activation and mask in place
            if self.activation == "relu":
                h = F.relu_(h)
            elif self.activation == "leaky":
                h = F.leaky_relu_(h, 0.2)
            return h.mul_(m), m
        if self.activation == "relu":
            h = F.relu(h)
        elif self.activation == "leaky":
            h = F.leaky_relu(h, 0.2)
        return h * m, m


def _channels(level: int, width: float) -> int:
    return max(1, round(min(64 * 2 ** (level - 1), 512) * width))


class PartialConvUNet(nn.Module):
    """The authors' partial-convolution U-Net, with compact variants.

    Args:
        in_channels: input channels; the last two must be the context and synthesis
            masks (they form the partial-conv mask).
        out_channels: output channels.
        levels: encoder/decoder levels (authors: 7); inputs must be multiples of
            ``2**levels`` in height and width.
        width: channel multiplier (1.0 = the authors' 64..512 channels).
        layout: ``"depth"`` or ``"color"``: the authors' key names, key order and
            which encoder convolutions carry a bias (depth: the first two; colour:
            none; both: the last decoder). ``"color"`` ends with a sigmoid.
        center: centre the colour on the context's mean (colour layout only; see
            the module docstring). Not part of the weights: stored in ``config``.

    ``forward(x)``: ``(B, in_channels, H, W)`` -> ``(B, out_channels, H, W)``.

    Example:
        >>> net = PartialConvUNet(4, 1, levels=3, width=0.125).eval()
        >>> x = torch.rand(2, 4, 16, 16); x[:, 2:] = (x[:, 2:] > 0.5).float()
        >>> tuple(net(x).shape)
        (2, 1, 16, 16)
    """

    def __init__(self, in_channels: int, out_channels: int, *, levels: int = 7,
                 width: float = 1.0, layout: Literal["depth", "color"] = "depth",
                 center: bool = False) -> None:
        super().__init__()
        if layout not in ("depth", "color"):
            raise ValueError(f"layout must be 'depth' or 'color', not {layout!r}")
        if center and (layout != "color" or in_channels != 6 or out_channels != 3):
            raise ValueError("center applies to the colour net only (6 inputs, 3 outputs)")
        self.config = dict(in_channels=in_channels, out_channels=out_channels, levels=levels,
                           width=width, layout=layout)
        if center:  # only when set, so older files' metadata stays what it was
            self.config["center"] = True
        self.levels, self.layout, self.center = levels, layout, bool(center)
        self.input_multiple = 2**levels  # input height and width must be multiples of it
        ch = [in_channels] + [_channels(i, width) for i in range(1, levels + 1)]
        biased = 2 if layout == "depth" else 0
        for i in range(1, levels + 1):
            k = 7 if i == 1 else 5 if i <= 3 else 3
            setattr(self, f"enc_{i}", PartialConvBlock(ch[i - 1], ch[i], k, stride=2,
                                                       bias=i <= biased, bn=i > 1))
        names = self._decoder_names()
        if layout == "depth":  # the authors register the 512-channel decoders first
            order = [i for i in range(5, levels + 1)] + [i for i in range(min(4, levels), 0, -1)]
        else:
            order = list(range(levels, 0, -1))
        for i in order:
            cin, cout = ch[i] + ch[i - 1], (ch[i - 1] if i > 1 else out_channels)
            block = (PartialConvBlock(cin, cout, 3, activation="leaky") if i > 1 else
                     PartialConvBlock(cin, cout, 3, bias=True, bn=False, activation=None))
            setattr(self, names[i], block)

    def _decoder_names(self) -> dict[int, str]:
        if self.layout == "depth":
            return {i: f"dec_{i}" for i in range(1, self.levels + 1)}
        return {i: f"dec_{i}" + ("A" if i <= self.levels - 2 else "")
                for i in range(1, self.levels + 1)}

    def forward(self, x: Tensor) -> Tensor:
        unit = self.input_multiple
        if x.shape[-1] % unit or x.shape[-2] % unit:
            raise ValueError(f"input is {x.shape[-2]}x{x.shape[-1]}; height and width must "
                             f"be multiples of {unit}")
        mean = None
        if self.center:
            ctx = x[:, -2:-1]
            mean = (x[:, :3] * ctx).sum((2, 3), keepdim=True) / ctx.sum(
                (2, 3), keepdim=True).clamp(min=1.0)
            x = torch.cat([(x[:, :3] - mean + 0.5) * ctx, x[:, 3:]], 1)
        mask = (x[:, -2:-1] + x[:, -1:]).clamp(0, 1)
        h = x * mask
        skips = [(h, mask)]
        for i in range(1, self.levels + 1):
            h, mask = getattr(self, f"enc_{i}")(h, mask * h.shape[1])
            skips.append((h, mask))
        names = self._decoder_names()
        skips.pop()  # the bottleneck (h, mask) itself
        for i in range(self.levels, 0, -1):
            h = F.interpolate(h, scale_factor=2.0, mode="nearest")
            mask = F.interpolate(mask, scale_factor=2.0, mode="nearest")
            skip, skip_mask = skips.pop()  # each skip is freed after its last use
            count = mask * h.shape[1] + skip_mask * skip.shape[1]
            h = torch.cat([h, skip], 1)
            del skip
            h, mask = getattr(self, names[i])(h, count)
        if self.layout != "color":
            return h
        return torch.sigmoid(h) if mean is None else (torch.sigmoid(h) - 0.5 + mean).clamp(0, 1)


def depth_net(*, levels: int = 7, width: float = 1.0) -> PartialConvUNet:
    """The depth inpainting net: input (zero-mean log depth, edge, context, synthesis),
    output the zero-mean log depth (raw). Defaults = the authors' ``depth-model.pth``."""
    return PartialConvUNet(4, 1, levels=levels, width=width, layout="depth")


def color_net(*, levels: int = 7, width: float = 1.0) -> PartialConvUNet:
    """The colour inpainting net: input (rgb, edge, context, synthesis), output rgb in
    (0, 1) (sigmoid). Defaults = the authors' ``color-model.pth``."""
    return PartialConvUNet(6, 3, levels=levels, width=width, layout="color")
