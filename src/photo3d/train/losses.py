"""Training objectives (supplement, "Training objective"; EdgeConnect for the edges).

All tensors are ``(B, C, H, W)`` float; masks are ``(B, 1, H, W)`` 0/1 and broadcast
over channels. ``N`` is the number of elements of the output (``B C H W``), so every
term is a mean.

* Colour: ``L_context + 6 L_synthesis + 0.05 L_perceptual + 120 L_style + 0.01 L_tv``
  with ``L_context = |C (I - I_gt)|_1 / N``, ``L_synthesis = |S (I - I_gt)|_1 / N``,
  perceptual and style losses on VGG-16 pool1..pool3 (Liu et al. 2018: per layer the
  mean absolute feature difference, and the mean absolute difference of Gram matrices
  ``psi^T psi / (C_p H_p W_p)``), and total variation over neighbour pairs inside S.
  The VGG losses see the output where the net has a job (context and synthesis) and
  the ground truth elsewhere: pixels outside both regions are unknowable from the
  input and unused at inference, so they are not penalised.
* Depth: ``L_context + L_synthesis`` on the zero-mean log depth.
* Edge (EdgeConnect): the discriminator scores ``(grey image, edges)`` pairs; the
  generator's edges are composited (output under S, target edges elsewhere) and it
  minimises ``L_adv + 10 L_FM`` (feature matching: mean absolute difference of the
  discriminator's layer outputs on fake and real); the discriminator minimises
  ``(L_real + L_fake) / 2``. ``"nsgan"`` = binary cross-entropy on sigmoid scores,
  ``"hinge"`` = hinge loss on raw scores.
* Refine colour net (:func:`refine_loss`): ``5 L_hole + 0.5 L_perceptual + 40 L_hole_style
  + 0.01 L_tv``. ``L_hole`` is the L1 averaged over the hole's pixels
  (``|H (I - I_gt)|_1 / (3 sum H)``: as strong on a thin band as on a large hole);
  ``L_hole_style`` compares Gram matrices of the VGG features *inside the hole*
  (:func:`masked_gram`), not over the whole crop: the whole-crop style loss of the
  paper's weights taught the net to put the crop's texture into flat holes (a grid of
  stripes in skies; held-out LPIPS 0.257 -> 0.40 after 250 steps). There is no context
  term (the net returns the context as given). Optionally an adversarial term: a
  PatchGAN discriminator on (colour, hole) pairs, hinge loss
  (:func:`patch_discriminator_loss`, :func:`patch_generator_loss`).
"""

from __future__ import annotations

from collections.abc import Callable

import torch
import torch.nn.functional as F
from torch import Tensor

COLOR_WEIGHTS = {"context": 1.0, "synthesis": 6.0, "perceptual": 0.05, "style": 120.0,
                 "tv": 0.01}
"""The supplement's weights of the colour net's loss terms."""
REFINE_WEIGHTS = {"hole": 5.0, "perceptual": 0.5, "style": 0.0, "hole_style": 40.0,
                  "tv": 0.01}
"""Weights of the refine net's loss terms (:func:`refine_loss`)."""
FM_WEIGHT = 10.0
"""EdgeConnect's feature-matching weight (adversarial weight 1)."""
GANS = ("nsgan", "hinge")


def masked_l1(output: Tensor, target: Tensor, mask: Tensor) -> Tensor:
    """``|mask (output - target)|_1 / N``.

    Example:
        >>> masked_l1(torch.ones(1, 2, 2, 2), torch.zeros(1, 2, 2, 2), torch.tensor(
        ...     [[[[1.0, 0.0], [0.0, 0.0]]]]))
        tensor(0.2500)
    """
    return (mask * (output - target)).abs().sum() / output.numel()


def tv_loss(output: Tensor, mask: Tensor) -> Tensor:
    """Total variation over horizontal and vertical neighbour pairs both inside ``mask``,
    divided by ``N``.

    Example:
        >>> x = torch.tensor([[[[0.0, 1.0, 3.0]]]])
        >>> tv_loss(x, torch.tensor([[[[1.0, 1.0, 0.0]]]]))  # only the pair (0, 1)
        tensor(0.3333)
    """
    mh = mask[..., :, 1:] * mask[..., :, :-1]
    mv = mask[..., 1:, :] * mask[..., :-1, :]
    dh = (mh * (output[..., :, 1:] - output[..., :, :-1])).abs().sum()
    dv = (mv * (output[..., 1:, :] - output[..., :-1, :])).abs().sum()
    return (dh + dv) / output.numel()


def gram(features: Tensor) -> Tensor:
    """``(B, C, H, W)`` -> ``(B, C, C)`` Gram matrix ``psi^T psi / (C H W)``.

    Example:
        >>> gram(torch.ones(1, 2, 2, 2))
        tensor([[[0.5000, 0.5000],
                 [0.5000, 0.5000]]])
    """
    b, c, h, w = features.shape
    f = features.reshape(b, c, h * w)
    return f @ f.transpose(1, 2) / (c * h * w)


def perceptual_style(output: Tensor, target: Tensor,
                     features: Callable[[Tensor], list[Tensor]]) -> tuple[Tensor, Tensor]:
    """``(L_perceptual, L_style)`` of ``output`` vs ``target`` (``(B, 3, H, W)`` in [0, 1])
    on the layers returned by ``features`` (VGG-16 pool1..pool3).

    Example:
        >>> identity = lambda x: [x]
        >>> perceptual_style(torch.ones(1, 3, 2, 2), torch.zeros(1, 3, 2, 2), identity)
        (tensor(1.), tensor(0.3333))
    """
    with torch.no_grad():
        real = features(target)
    fake = features(output)
    perceptual = sum(((f - r).abs().mean() for f, r in zip(fake, real, strict=True)),
                     output.new_zeros(()))
    style = sum(((gram(f) - gram(r)).abs().mean() for f, r in zip(fake, real, strict=True)),
                output.new_zeros(()))
    return perceptual, style


def color_loss(output: Tensor, target: Tensor, context: Tensor, synthesis: Tensor,
               features: Callable[[Tensor], list[Tensor]]) -> dict[str, Tensor]:
    """The colour net's loss terms and their weighted sum ``"total"``.

    Args:
        output, target: ``(B, 3, H, W)`` in [0, 1].
        context, synthesis: ``(B, 1, H, W)`` 0/1 masks (synthesis = the net's hole channel).
        features: VGG-16 feature extractor (:class:`photo3d.nets.vgg.VGG16Features`).

    Example:
        >>> x = torch.full((1, 3, 4, 4), 0.5); m = torch.ones(1, 1, 4, 4)
        >>> float(color_loss(x, x, m, 0 * m, lambda t: [t])["total"])
        0.0
    """
    known = (context + synthesis).clamp(0, 1)
    composite = known * output + (1 - known) * target
    perceptual, style = perceptual_style(composite, target, features)
    terms = {"context": masked_l1(output, target, context),
             "synthesis": masked_l1(output, target, synthesis),
             "perceptual": perceptual, "style": style, "tv": tv_loss(output, synthesis)}
    terms["total"] = sum(COLOR_WEIGHTS[k] * v for k, v in terms.items())
    return terms


def masked_gram(features: Tensor, mask: Tensor) -> Tensor:
    """Gram matrix of ``features`` ``(B, C, h, w)`` over ``mask`` ``(B, 1, H, W)`` only
    (area-resized to ``h x w``): ``(f m)(f m)^T / (C sum m)``, ``(B, C, C)``.

    Example:
        >>> m = torch.zeros(1, 1, 2, 2); m[..., 0] = 1
        >>> masked_gram(torch.ones(1, 2, 2, 2), m)
        tensor([[[0.5000, 0.5000],
                 [0.5000, 0.5000]]])
    """
    b, c, h, w = features.shape
    m = F.adaptive_avg_pool2d(mask, (h, w)) if mask.shape[-2:] != (h, w) else mask
    f = (features * m).reshape(b, c, h * w)
    return f @ f.transpose(1, 2) / (c * m.sum((1, 2, 3)).clamp(min=1e-6)).view(b, 1, 1)


def refine_loss(output: Tensor, target: Tensor, hole: Tensor,
                features: Callable[[Tensor], list[Tensor]]) -> dict[str, Tensor]:
    """The refine colour net's loss terms and their weighted sum ``"total"``
    (:data:`REFINE_WEIGHTS`; see the module docstring). Terms of weight 0 are left out.

    ``hole_style`` compares :func:`masked_gram` matrices inside the hole (the texture
    the hole should have); ``style`` the Gram matrices of the whole crop, as the
    colour loss does.

    Args:
        output, target: ``(B, 3, H, W)`` in [0, 1] (``output`` equals the input outside
            the hole).
        hole: ``(B, 1, H, W)`` 0/1, the net's hole channel.
        features: VGG-16 feature extractor.

    Example:
        >>> x = torch.full((1, 3, 4, 4), 0.5); m = torch.zeros(1, 1, 4, 4); m[..., :2] = 1
        >>> round(float(refine_loss(x + m * 0.1, x, m, lambda t: [t])["hole"]), 4)
        0.1
    """
    composite = hole * output + (1 - hole) * target
    with torch.no_grad():
        real = features(target)
    fake = features(composite)
    pixels = (3 * hole.sum()).clamp(min=1.0)
    zero = output.new_zeros(())
    terms = {"hole": (hole * (output - target)).abs().sum() / pixels,
             "perceptual": sum(((f - r).abs().mean() for f, r in zip(fake, real, strict=True)),
                               zero),
             "tv": tv_loss(output, hole)}
    if REFINE_WEIGHTS.get("style"):
        terms["style"] = sum(((gram(f) - gram(r)).abs().mean()
                              for f, r in zip(fake, real, strict=True)), zero)
    if REFINE_WEIGHTS.get("hole_style"):
        terms["hole_style"] = sum(((masked_gram(f, hole) - masked_gram(r, hole)).abs().mean()
                                   for f, r in zip(fake, real, strict=True)), zero)
    terms["total"] = sum(REFINE_WEIGHTS[k] * v for k, v in terms.items())
    return terms


def depth_loss(output: Tensor, target: Tensor, context: Tensor,
               synthesis: Tensor) -> dict[str, Tensor]:
    """The depth net's ``L_context + L_synthesis`` (zero-mean log depth).

    Example:
        >>> m = torch.ones(1, 1, 2, 2)
        >>> depth_loss(torch.ones(1, 1, 2, 2), torch.zeros(1, 1, 2, 2), m, 0 * m)["total"]
        tensor(1.)
    """
    terms = {"context": masked_l1(output, target, context),
             "synthesis": masked_l1(output, target, synthesis)}
    terms["total"] = terms["context"] + terms["synthesis"]
    return terms


def adversarial(scores: Tensor, real: bool, *, gan: str = "nsgan",
                discriminator: bool = True) -> Tensor:
    """EdgeConnect's adversarial loss of discriminator ``scores`` labelled ``real``.

    ``nsgan``: binary cross-entropy (scores are sigmoid outputs). ``hinge``: for the
    discriminator ``relu(1 - s)`` (real) / ``relu(1 + s)`` (fake), for the generator
    ``-s``.

    Example:
        >>> adversarial(torch.tensor([0.5]), True)
        tensor(0.6931)
    """
    if gan == "nsgan":
        labels = torch.ones_like(scores) if real else torch.zeros_like(scores)
        return F.binary_cross_entropy(scores, labels)
    if gan == "hinge":
        if not discriminator:
            return -scores.mean()
        return F.relu(1 - scores).mean() if real else F.relu(1 + scores).mean()
    raise ValueError(f"gan must be one of {GANS}, got {gan!r}")


def composite_edges(output: Tensor, target: Tensor, synthesis: Tensor) -> Tensor:
    """The generator's edges under ``synthesis``, the target edges elsewhere."""
    return synthesis * output + (1 - synthesis) * target


def edge_discriminator_loss(discriminator, gray: Tensor, fake: Tensor, real: Tensor, *,
                            gan: str = "nsgan") -> dict[str, Tensor]:
    """EdgeConnect's discriminator loss ``(L_real + L_fake) / 2`` (``fake`` is detached).

    Args:
        discriminator: ``(B, 2, H, W) -> (scores, features)``
            (:class:`photo3d.nets.edge.EdgeDiscriminator` with 2 input channels).
        gray: ``(B, 1, H, W)`` grey target image.
        fake: ``(B, 1, H, W)`` composited generator edges.
        real: ``(B, 1, H, W)`` target edges.

    Example:
        >>> from photo3d.nets.edge import EdgeDiscriminator
        >>> d = EdgeDiscriminator(2, width=0.125).eval()
        >>> x = torch.rand(1, 1, 32, 32)
        >>> bool(edge_discriminator_loss(d, x, x, x)["total"] > 0)
        True
    """
    real_scores, _ = discriminator(torch.cat([gray, real], 1))
    fake_scores, _ = discriminator(torch.cat([gray, fake.detach()], 1))
    terms = {"d_real": adversarial(real_scores, True, gan=gan),
             "d_fake": adversarial(fake_scores, False, gan=gan)}
    terms["total"] = (terms["d_real"] + terms["d_fake"]) / 2
    return terms


def edge_generator_loss(discriminator, gray: Tensor, fake: Tensor,
                        real: Tensor, *, gan: str = "nsgan") -> dict[str, Tensor]:
    """EdgeConnect's generator loss ``L_adv + 10 L_FM`` (arguments as
    :func:`edge_discriminator_loss`; gradients flow into ``fake`` only).

    Example:
        >>> from photo3d.nets.edge import EdgeDiscriminator
        >>> d = EdgeDiscriminator(2, width=0.125).eval()
        >>> x = torch.rand(1, 1, 32, 32)
        >>> edge_generator_loss(d, x, x, x)["fm"].item()
        0.0
    """
    with torch.no_grad():
        _, real_feats = discriminator(torch.cat([gray, real], 1))
    scores, fake_feats = discriminator(torch.cat([gray, fake], 1))
    fm = sum(((f - r).abs().mean() for f, r in zip(fake_feats, real_feats, strict=True)),
             fake.new_zeros(()))
    terms = {"adv": adversarial(scores, True, gan=gan, discriminator=False), "fm": fm}
    terms["total"] = terms["adv"] + FM_WEIGHT * terms["fm"]
    return terms


def patch_discriminator_loss(discriminator, real: Tensor, fake: Tensor) -> dict[str, Tensor]:
    """Hinge loss of a PatchGAN discriminator (the refine net's): ``mean(relu(1 - D(real)))
    + mean(relu(1 + D(fake)))``, halved; ``fake`` is detached.

    Args:
        discriminator: ``(B, C, H, W) -> (scores, features)`` with raw scores
            (:class:`photo3d.nets.edge.EdgeDiscriminator`, ``use_sigmoid=False``).
        real, fake: ``(B, C, H, W)``: the target and the net's output, each with the
            hole mask as the last channel.

    Example:
        >>> from photo3d.nets.edge import EdgeDiscriminator
        >>> d = EdgeDiscriminator(4, width=0.125, use_sigmoid=False)
        >>> x = torch.rand(1, 4, 32, 32)
        >>> sorted(patch_discriminator_loss(d, x, x))
        ['d_fake', 'd_real', 'total']
    """
    real_scores, _ = discriminator(real)
    fake_scores, _ = discriminator(fake.detach())
    terms = {"d_real": adversarial(real_scores, True, gan="hinge"),
             "d_fake": adversarial(fake_scores, False, gan="hinge")}
    terms["total"] = (terms["d_real"] + terms["d_fake"]) / 2
    return terms


def patch_generator_loss(discriminator, fake: Tensor) -> Tensor:
    """The generator's hinge adversarial loss ``-mean(D(fake))`` (gradients flow into
    ``fake``; the discriminator's parameters get gradients too, which its own step
    clears before use).

    Example:
        >>> from photo3d.nets.edge import EdgeDiscriminator
        >>> d = EdgeDiscriminator(4, width=0.125, use_sigmoid=False)
        >>> patch_generator_loss(d, torch.rand(1, 4, 32, 32)).shape
        torch.Size([])
    """
    scores, _ = discriminator(fake)
    return adversarial(scores, True, gan="hinge", discriminator=False)
