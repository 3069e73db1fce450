"""The edge inpainting net: an EdgeConnect generator with spectral norm, and its
discriminator (for training).

Generator (the authors' ``Inpaint_Edge_Net``, supplement Table "edge inpainting"):
reflection-padded 7x7 conv -> two stride-2 4x4 convs (zero padding 1) -> 8 residual
blocks (reflection-padded 3x3 conv with dilation 2, LeakyReLU 0.2, 3x3 conv, no
activation after the sum) -> two stride-2 4x4 transposed convs, each fed the
concatenation of the previous output and the encoder output of the same scale ->
reflection-padded 7x7 conv (plain, no spectral norm) on the concatenation with the
first encoder output -> sigmoid. Every conv but the last is spectrally normalised and
followed by an instance norm without affine parameters; ReLU except in the blocks.

Spectral norm uses the state-dict layout of PyTorch's ``torch.nn.utils.spectral_norm``
hook (``weight_orig``, ``weight_u``, ``weight_v``). In eval mode the weight is
``weight_orig / (u . (W v))`` with ``W`` the weight as a matrix (rows = output
channels; for transposed convolutions dimension 1) and no power iteration, so the
forward pass is deterministic; in training mode one power iteration updates ``u`` and
``v`` first, as PyTorch does.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor, nn


def _as_matrix(weight: Tensor, dim: int) -> Tensor:
    if dim != 0:
        weight = weight.transpose(0, dim)
    return weight.reshape(weight.shape[0], -1)


def spectral_norm_weight(weight_orig: Tensor, u: Tensor, v: Tensor, *, dim: int = 0) -> Tensor:
    """``weight_orig / sigma`` with ``sigma = u . (W v)`` (no power iteration).

    Args:
        weight_orig: ``(C_out, C_in, k, k)`` (``dim=0``) or a transposed conv's
            ``(C_in, C_out, k, k)`` (``dim=1``).
        u: ``(n,)`` left singular vector estimate, ``n = weight_orig.shape[dim]``.
        v: ``(numel / n,)`` right singular vector estimate.
        dim: the output-channel dimension.

    Returns:
        The normalised weight, same shape as ``weight_orig``.

    Example:
        >>> w = torch.diag(torch.tensor([3.0, 1.0])).view(2, 2, 1, 1)
        >>> spectral_norm_weight(w, torch.tensor([1.0, 0.0]), torch.tensor([1.0, 0.0]))[0, 0]
        tensor([[1.]])
    """
    sigma = torch.dot(u, torch.mv(_as_matrix(weight_orig, dim), v))
    return weight_orig / sigma


def power_iteration(weight_orig: Tensor, u: Tensor, v: Tensor, *, dim: int = 0,
                    eps: float = 1e-12) -> tuple[Tensor, Tensor]:
    """One power iteration: ``v = normalise(W^T u)``, then ``u = normalise(W v)``."""
    mat = _as_matrix(weight_orig.detach(), dim)
    v = F.normalize(torch.mv(mat.t(), u), dim=0, eps=eps)
    u = F.normalize(torch.mv(mat, v), dim=0, eps=eps)
    return u, v


class SpectralNormConv(nn.Module):
    """A (transposed) 2-D convolution with a spectrally normalised weight.

    Keys ``bias`` (optional), ``weight_orig``, ``weight_u``, ``weight_v``, in that
    order, like a module wrapped by ``torch.nn.utils.spectral_norm``.

    Example:
        >>> conv = SpectralNormConv(3, 8, 4, stride=2, padding=1).eval()
        >>> tuple(conv(torch.rand(1, 3, 16, 16)).shape)
        (1, 8, 8, 8)
    """

    def __init__(self, in_channels: int, out_channels: int, kernel_size: int, *,
                 stride: int = 1, padding: int = 0, dilation: int = 1, bias: bool = True,
                 transposed: bool = False) -> None:
        super().__init__()
        ref = (nn.ConvTranspose2d if transposed else nn.Conv2d)(
            in_channels, out_channels, kernel_size, stride=stride, padding=padding,
            dilation=dilation, bias=bias)
        self.register_parameter("bias", ref.bias)
        self.weight_orig = ref.weight
        self.dim = 1 if transposed else 0
        mat = _as_matrix(ref.weight.detach(), self.dim)
        u = F.normalize(torch.randn(mat.shape[0]), dim=0)
        v = F.normalize(torch.randn(mat.shape[1]), dim=0)
        for _ in range(15):
            u, v = power_iteration(ref.weight, u, v, dim=self.dim)
        self.register_buffer("weight_u", u)
        self.register_buffer("weight_v", v)
        self.stride, self.padding, self.dilation = stride, padding, dilation
        self.transposed = transposed

    def weight(self) -> Tensor:
        """The normalised weight (one power iteration first in training mode)."""
        u, v = self.weight_u, self.weight_v
        if self.training:
            with torch.no_grad():
                new_u, new_v = power_iteration(self.weight_orig, u, v, dim=self.dim)
                u.copy_(new_u)
                v.copy_(new_v)
            u, v = u.clone(), v.clone()
        return spectral_norm_weight(self.weight_orig, u, v, dim=self.dim)

    def forward(self, x: Tensor) -> Tensor:
        if self.transposed:
            return F.conv_transpose2d(x, self.weight(), self.bias, self.stride, self.padding,
                                      dilation=self.dilation)
        return F.conv2d(x, self.weight(), self.bias, self.stride, self.padding, self.dilation)


def _norm_act(channels: int, act: nn.Module | None) -> list[nn.Module]:
    layers: list[nn.Module] = [nn.InstanceNorm2d(channels, track_running_stats=False)]
    return layers + ([act] if act is not None else [])


class ResnetBlock(nn.Module):
    """``x + IN(conv3(LeakyReLU(IN(conv3_dilated(x)))))`` with reflection padding."""

    def __init__(self, channels: int, dilation: int = 2) -> None:
        super().__init__()
        self.conv_block = nn.Sequential(
            nn.ReflectionPad2d(dilation),
            SpectralNormConv(channels, channels, 3, dilation=dilation, bias=False),
            *_norm_act(channels, nn.LeakyReLU(0.2)),
            nn.ReflectionPad2d(1),
            SpectralNormConv(channels, channels, 3, bias=False),
            *_norm_act(channels, None),
        )

    def forward(self, x: Tensor) -> Tensor:
        return x + self.conv_block(x)


class EdgeGenerator(nn.Module):
    """The edge inpainting generator; defaults = the authors' ``edge-model.pth``.

    Args:
        in_channels: 7 = rgb (3), disparity / max (1), edges (1), context (1),
            synthesis (1).
        width: channel multiplier (1.0 = 64/128/256 channels).
        blocks: residual blocks (authors: 8).

    ``forward(x)``: ``(B, in_channels, H, W)`` with ``H, W`` multiples of 4 ->
    ``(B, 1, H, W)`` edge probability in (0, 1).

    Example:
        >>> net = EdgeGenerator(width=0.125, blocks=1).eval()
        >>> tuple(net(torch.rand(1, 7, 16, 16)).shape)
        (1, 1, 16, 16)
    """

    input_multiple = 4
    """Input height and width must be multiples of this (two stride-2 stages)."""

    def __init__(self, in_channels: int = 7, *, width: float = 1.0, blocks: int = 8) -> None:
        super().__init__()
        self.config = dict(in_channels=in_channels, width=width, blocks=blocks)
        c1, c2, c3 = (max(1, round(c * width)) for c in (64, 128, 256))
        self.encoder_0 = nn.Sequential(nn.ReflectionPad2d(3),
                                       SpectralNormConv(in_channels, c1, 7),
                                       *_norm_act(c1, nn.ReLU()))
        self.encoder_1 = nn.Sequential(SpectralNormConv(c1, c2, 4, stride=2, padding=1),
                                       *_norm_act(c2, nn.ReLU()))
        self.encoder_2 = nn.Sequential(SpectralNormConv(c2, c3, 4, stride=2, padding=1),
                                       *_norm_act(c3, nn.ReLU()))
        self.middle = nn.Sequential(*[ResnetBlock(c3, 2) for _ in range(blocks)])
        self.decoder_0 = nn.Sequential(
            SpectralNormConv(2 * c3, c2, 4, stride=2, padding=1, transposed=True),
            *_norm_act(c2, nn.ReLU()))
        self.decoder_1 = nn.Sequential(
            SpectralNormConv(2 * c2, c1, 4, stride=2, padding=1, transposed=True),
            *_norm_act(c1, nn.ReLU()))
        self.decoder_2 = nn.Sequential(nn.ReflectionPad2d(3), nn.Conv2d(2 * c1, 1, 7))

    def forward(self, x: Tensor) -> Tensor:
        unit = self.input_multiple
        if x.shape[-1] % unit or x.shape[-2] % unit:
            raise ValueError(f"input is {x.shape[-2]}x{x.shape[-1]}; height and width must "
                             f"be multiples of {unit}")
        if not torch.is_grad_enabled():
            return self._lean_forward(x)
        x1 = self.encoder_0(x)
        x2 = self.encoder_1(x1)
        x3 = self.encoder_2(x2)
        x4 = self.middle(x3)
        x5 = self.decoder_0(torch.cat([x4, x3], 1))
        x6 = self.decoder_1(torch.cat([x5, x2], 1))
        return torch.sigmoid(self.decoder_2(torch.cat([x6, x1], 1)))


    def _lean_forward(self, x: Tensor) -> Tensor:
        """:meth:`forward` without autograd, in less memory (same result up to float
        rounding): activations in place, every tensor dropped after its last use, and
        the last convolution split over the two halves of its concatenated input (a
        convolution is linear in its input channels), so the full-resolution
        ``cat`` + padding (4x a 64-channel image) is never built."""
        x1 = _lean(self.encoder_0, x)
        x2 = _lean(self.encoder_1, x1)
        x3 = _lean(self.encoder_2, x2)
        x4 = self.middle(x3)
        x5 = _lean(self.decoder_0, torch.cat([x4, x3], 1))
        del x3, x4
        x6 = _lean(self.decoder_1, torch.cat([x5, x2], 1))
        del x2, x5
        pad, conv = self.decoder_2
        c = x6.shape[1]
        out = F.conv2d(pad(x6), conv.weight[:, :c], conv.bias)
        del x6
        out += F.conv2d(pad(x1), conv.weight[:, c:])
        return torch.sigmoid_(out)


def _lean(seq: nn.Sequential, x: Tensor) -> Tensor:
    """Run ``seq`` with its ReLUs in place (inference only)."""
    for layer in seq:
        x = torch.relu_(x) if isinstance(layer, nn.ReLU) else layer(x)
    return x


class EdgeDiscriminator(nn.Module):
    """The EdgeConnect PatchGAN discriminator (training only).

    Five spectrally normalised 4x4 convs without bias (strides 2, 2, 2, 1, 1;
    64/128/256/512/1 channels), LeakyReLU 0.2 between them.

    ``forward(x)`` returns ``(scores, features)``: ``scores (B, 1, h, w)`` (sigmoid if
    ``use_sigmoid``) and the five layer outputs for feature matching.

    Example:
        >>> d = EdgeDiscriminator(1, width=0.125)
        >>> scores, feats = d(torch.rand(2, 1, 32, 32))
        >>> tuple(scores.shape), len(feats)
        ((2, 1, 2, 2), 5)
    """

    def __init__(self, in_channels: int = 1, *, width: float = 1.0,
                 use_sigmoid: bool = True) -> None:
        super().__init__()
        chans = [in_channels] + [max(1, round(c * width)) for c in (64, 128, 256, 512)] + [1]
        strides = (2, 2, 2, 1, 1)
        for i in range(5):
            conv = SpectralNormConv(chans[i], chans[i + 1], 4, stride=strides[i], padding=1,
                                    bias=False)
            layers = [conv] + ([nn.LeakyReLU(0.2)] if i < 4 else [])
            setattr(self, f"conv{i + 1}", nn.Sequential(*layers))
        self.use_sigmoid = use_sigmoid

    def forward(self, x: Tensor) -> tuple[Tensor, list[Tensor]]:
        feats = []
        for i in range(5):
            x = getattr(self, f"conv{i + 1}")(x)
            feats.append(x)
        return (torch.sigmoid(x) if self.use_sigmoid else x), feats
