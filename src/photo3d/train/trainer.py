"""One net, its optimiser(s), one optimisation step, and checkpoints.

:class:`TrainConfig` holds every option that changes what training computes;
:class:`Trainer` owns the net (plus the EdgeConnect discriminator for the edge net)
and Adam (lr 1e-4, betas (0.9, 0.999); the discriminator at a tenth of the
learning rate, EdgeConnect's ratio). The refine colour net (``arch="refine"``) may add
a PatchGAN discriminator on (colour, hole) pairs (``adversarial`` > 0, hinge loss,
the generator's learning rate). A checkpoint is a folder: the net as
``<kind>.safetensors`` (:func:`photo3d.nets.save_safetensors`, loadable by the
learned inpainter as is), the discriminator as ``discriminator.safetensors``, the
optimiser states as ``optimizer.pt`` (tensors, numbers and lists only: read back with
``torch.load(weights_only=True)``) and ``state.json`` (step, config).
"""

from __future__ import annotations

import dataclasses
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import Tensor, nn

from photo3d.errors import ConfigError, InputError
from photo3d.files.atomic import open_write, write_json, writing
from photo3d.io.bounded import read_bytes, read_json
from photo3d.nets.edge import EdgeDiscriminator
from photo3d.nets.weights import (
    build_net,
    check_state_dict,
    compressed_records,
    read_safetensors,
    resolve_device,
    save_safetensors,
)
from photo3d.train import losses
from photo3d.train.dataset import KINDS
from photo3d.train.samples import Sample

REFINE_D_WIDTH = 0.25
"""Channel multiplier of the refine net's PatchGAN discriminator (EdgeConnect's layout)."""

ARCHITECTURE = ("kind", "arch", "width", "channels", "levels", "blocks", "edges", "gan",
                "center")
"""Fields a resumed run must share with its checkpoint."""
ARCHS = ("partialconv", "refine")
"""Colour net architectures: the paper's partial-convolution U-Net, or the refine net
(:mod:`photo3d.nets.refine`, a residual over the diffusion fill)."""


@dataclass(frozen=True)
class TrainConfig:
    """Everything that changes what training computes (saved as ``config.json``)."""

    kind: str
    """Which net: ``"edge"``, ``"depth"`` or ``"color"``."""
    arch: str = "partialconv"
    """Colour net only: ``"partialconv"`` (the paper's U-Net) or ``"refine"`` (a
    residual over the diffusion fill, :mod:`photo3d.nets.refine`)."""
    width: float = 1.0
    """Channel multiplier of the edge net and the partial-convolution U-Nets (1.0 =
    the authors' nets)."""
    channels: int = 16
    """Refine net only: channels at its finest level (:class:`~photo3d.nets.refine.RefineNet`)."""
    levels: int | None = None
    """U-Net levels of the depth and colour nets (None: the authors' 7, the refine
    net's 4)."""
    blocks: int | None = None
    """Residual blocks of the edge net (None: the authors' 8) or of the refine net
    (None: 4)."""
    edges: bool = True
    """Refine net only: read the edge channel (False: the net zeroes it; for photos
    without depth, whose training crops never hold an edge)."""
    center: bool = True
    """Colour net only: centre its colours on the context's mean (photo3d's nets; see
    :class:`~photo3d.nets.partialconv.PartialConvUNet`; False = the authors' net)."""
    size: int = 256
    """Crop side in pixels (a multiple of ``2**levels``, and of 4 for the edge net)."""
    batch: int = 8
    """Samples per optimisation step (paper: 8)."""
    steps: int = 1000
    """Stop after this many optimisation steps in total (a resumed run continues)."""
    lr: float = 1e-4
    """Adam learning rate (paper: 1e-4)."""
    betas: tuple[float, float] = (0.9, 0.999)
    """Adam betas (paper: beta1 0.9)."""
    seed: int = 0
    """Seeds the initial weights, the data choices and the region-pair choice."""
    region_size: int | None = None
    """Working size (longer side) at which regions are grown and targets cropped
    (None: 4 x ``size``, so a 256 crop sees the paper's 1024 px region sizes)."""
    depth_kind: str = "disparity"
    """What the depth maps hold: ``"disparity"`` or ``"depth"``."""
    gan: str = "nsgan"
    """Edge net adversarial loss: ``"nsgan"`` (BCE) or ``"hinge"``."""
    d_lr_ratio: float = 0.1
    """Discriminator learning rate / generator learning rate (EdgeConnect: 0.1)."""
    swap: float = 0.5
    """Probability of swapping a region pair's context and synthesis (paper: 1/2; the
    swapped pair is a wide hole beside a thin context, which the first pass never asks
    for)."""
    adversarial: float = 0.0
    """Refine net only: weight of a PatchGAN hinge adversarial term (0: none; a run
    resumed with a weight > 0 starts its discriminator then)."""
    checkpoint_every: int = 500
    """Save a checkpoint every this many steps (and at the end)."""
    sample_every: int = 500
    """Write a sample grid every this many steps (and at the end)."""
    heldout_every: int = 250
    """Score the held-out set every this many steps (when the run has one)."""

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ConfigError(f"unknown net {self.kind!r}; expected one of {', '.join(KINDS)}")
        if self.arch not in ARCHS:
            raise ConfigError(f"unknown architecture {self.arch!r}; expected one of "
                              f"{', '.join(ARCHS)}")
        if self.arch != "partialconv" and self.kind != "color":
            raise ConfigError(f"--arch {self.arch} is a colour net; the {self.kind} net has "
                              "one architecture")
        refine = self.arch == "refine"
        if self.levels is None:
            object.__setattr__(self, "levels", 4 if refine else 7)
        if self.blocks is None:
            object.__setattr__(self, "blocks", 4 if refine else 8)
        if not 0 <= self.swap <= 1:
            raise ConfigError(f"swap must be a probability in [0, 1], got {self.swap}")
        if self.adversarial < 0 or (self.adversarial > 0 and not refine):
            raise ConfigError(f"adversarial weight {self.adversarial}: a weight >= 0, for the "
                              "refine net only")
        unit = 4 if self.kind == "edge" else 2**self.levels
        if self.size <= 0 or self.size % unit:
            raise ConfigError(f"--size {self.size} must be a positive multiple of {unit} for "
                              f"the {self.kind} net" + ("" if self.kind == "edge" else
                                                        f" with {self.levels} levels"))
        for name in ("batch", "steps", "checkpoint_every", "sample_every", "heldout_every",
                     "levels", "channels"):
            if getattr(self, name) < (0 if name == "steps" else 1):
                raise ConfigError(f"{name} must be positive, got {getattr(self, name)}")
        if self.blocks < (0 if refine else 1):
            raise ConfigError(f"blocks must be positive, got {self.blocks}")
        if not 0 < self.width < math.inf or not 0 < self.lr < math.inf:
            raise ConfigError(f"width and lr must be positive and finite, got {self.width} "
                              f"and {self.lr}")
        if self.gan not in losses.GANS:
            raise ConfigError(f"gan must be one of {', '.join(losses.GANS)}, got {self.gan!r}")
        if self.depth_kind not in ("disparity", "depth"):
            raise ConfigError(f"depth kind must be disparity or depth, got {self.depth_kind!r}")
        if self.region_size is not None and self.region_size < self.size:
            raise ConfigError(f"region size {self.region_size} is smaller than the crop "
                              f"{self.size}")

    @property
    def working_size(self) -> int:
        """The region size actually used."""
        return self.region_size if self.region_size is not None else 4 * self.size

    def net_config(self) -> dict:
        """Keyword arguments of :func:`photo3d.nets.build_net` for this net."""
        if self.kind == "edge":
            return dict(width=self.width, blocks=self.blocks)
        if self.arch == "refine":
            return dict(arch="refine", channels=self.channels, levels=self.levels,
                        blocks=self.blocks, edges=self.edges)
        if self.kind == "color" and self.center:
            return dict(levels=self.levels, width=self.width, center=True)
        return dict(levels=self.levels, width=self.width)

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> TrainConfig:
        """Inverse of :meth:`to_dict`."""
        data = dict(data)
        if "betas" in data:
            data["betas"] = tuple(data["betas"])
        try:
            return cls(**data)
        except TypeError as err:
            raise ConfigError(f"bad training configuration: {err}") from None


def to_tensors(samples: list[Sample], device: torch.device) -> dict[str, Tensor]:
    """Stack samples into ``(B, C, S, S)`` float32 tensors on ``device``: ``inputs``,
    ``target``, and ``(B, 1, S, S)`` ``context``, ``synthesis``, ``hole``, ``gray``.

    Example:
        >>> s = Sample(np.zeros((6, 4, 4), np.float32), np.zeros((3, 4, 4), np.float32),
        ...            *(np.zeros((4, 4), bool),) * 3, np.zeros((4, 4), np.float32), 0, 1, False)
        >>> {k: tuple(v.shape) for k, v in to_tensors([s, s], torch.device("cpu")).items()}["hole"]
        (2, 1, 4, 4)
    """
    def stack(name: str, channel: bool) -> Tensor:
        arr = np.stack([getattr(s, name) for s in samples]).astype(np.float32)
        return torch.from_numpy(arr[:, None] if channel else arr).to(device)

    out = {"inputs": stack("inputs", False), "target": stack("target", False)}
    out.update({name: stack(name, True) for name in ("context", "synthesis", "hole", "gray")})
    return out


class Trainer:
    """The net being trained, its optimiser(s) and one step.

    Construction seeds torch's global random generator with ``config.seed`` (the
    initial weights depend on it and on nothing else).

    Args:
        config: :class:`TrainConfig`.
        device: torch device (default CUDA when available).
        features: VGG-16 feature extractor for the colour loss (default
            :func:`photo3d.nets.vgg.load_vgg16`).

    Example:
        >>> t = Trainer(TrainConfig("depth", levels=3, width=0.125, size=32), device="cpu")
        >>> type(t.net).__name__, t.discriminator is None
        ('PartialConvUNet', True)
    """

    def __init__(self, config: TrainConfig, *, device: str | torch.device | None = None,
                 features: nn.Module | None = None) -> None:
        self.config = config
        self.device = resolve_device(device)
        torch.manual_seed(config.seed)
        self.net = build_net(config.kind, **config.net_config()).to(self.device).train()
        adam = dict(lr=config.lr, betas=config.betas)
        self.optimizer = torch.optim.Adam(self.net.parameters(), **adam)
        self.discriminator = None
        self.d_optimizer = None
        if config.kind == "edge" or config.adversarial > 0:
            # edge: EdgeConnect's (grey image, edges) at a tenth of the learning rate;
            # refine: (colour, hole) pairs, hinge, at the same learning rate
            edge = config.kind == "edge"
            self.discriminator = EdgeDiscriminator(
                2 if edge else 4, width=config.width if edge else REFINE_D_WIDTH,
                use_sigmoid=edge and config.gan == "nsgan").to(self.device).train()
            ratio = config.d_lr_ratio if edge else 1.0
            self.d_optimizer = torch.optim.Adam(self.discriminator.parameters(),
                                                **{**adam, "lr": config.lr * ratio})
        self.features = None
        if config.kind == "color":
            if features is None:
                from photo3d.nets.vgg import load_vgg16

                features = load_vgg16()
            self.features = features.to(self.device).eval()

    def step(self, batch: dict[str, Tensor]) -> tuple[dict[str, float], Tensor]:
        """One optimisation step on a batch from :func:`to_tensors`.

        Returns:
            ``(losses, output)``: the loss terms (``"total"`` is the one minimised;
            the edge net also reports the discriminator's ``d_*`` terms) and the net
            output ``(B, C, S, S)`` (detached).
        """
        kind = self.config.kind
        out = self.net(batch["inputs"])
        if kind == "edge":
            fake = losses.composite_edges(out, batch["target"], batch["synthesis"])
            d_terms = losses.edge_discriminator_loss(self.discriminator, batch["gray"], fake,
                                                     batch["target"], gan=self.config.gan)
            self.d_optimizer.zero_grad(set_to_none=True)
            d_terms["total"].backward()
            self.d_optimizer.step()
            terms = losses.edge_generator_loss(self.discriminator, batch["gray"], fake,
                                               batch["target"], gan=self.config.gan)
            terms.update({f"d_{k}" if k == "total" else k: v for k, v in d_terms.items()})
        elif kind == "depth":
            terms = losses.depth_loss(out, batch["target"], batch["context"], batch["hole"])
        elif self.config.arch == "refine":
            terms = losses.refine_loss(out, batch["target"], batch["hole"], self.features)
            if self.discriminator is not None:
                real = torch.cat([batch["target"], batch["hole"]], 1)
                fake = torch.cat([out, batch["hole"]], 1)
                d_terms = losses.patch_discriminator_loss(self.discriminator, real, fake)
                self.d_optimizer.zero_grad(set_to_none=True)
                d_terms["total"].backward()
                self.d_optimizer.step()
                terms["adv"] = losses.patch_generator_loss(self.discriminator, fake)
                terms["total"] = terms["total"] + self.config.adversarial * terms["adv"]
                terms.update({f"d_{k}" if k == "total" else k: v for k, v in d_terms.items()})
        else:
            terms = losses.color_loss(out, batch["target"], batch["context"], batch["hole"],
                                      self.features)
        self.optimizer.zero_grad(set_to_none=True)
        terms["total"].backward()
        self.optimizer.step()
        return {k: float(v.detach()) for k, v in terms.items()}, out.detach()

    def save(self, folder: str | Path, step: int) -> Path:
        """Write a checkpoint folder (see the module docstring)."""
        from safetensors.torch import save_file

        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        save_safetensors(self.net, folder / f"{self.config.kind}.safetensors")
        optim = {"generator": self.optimizer.state_dict()}
        if self.discriminator is not None:
            with writing(folder / "discriminator.safetensors") as target:
                save_file({k: v.detach().cpu().contiguous() for k, v in
                           self.discriminator.state_dict().items()}, str(target))
            optim["discriminator"] = self.d_optimizer.state_dict()
        with open_write(folder / "optimizer.pt") as file:
            torch.save(optim, file)
        write_json(folder / "state.json", {"step": int(step), "config": self.config.to_dict()})
        return folder

    def load(self, folder: str | Path) -> int:
        """Restore a checkpoint written by :meth:`save`; returns its step."""
        folder = Path(folder)
        state = read_json(folder / "state.json")
        _load_module(self.net, folder / f"{self.config.kind}.safetensors")
        path = folder / "optimizer.pt"
        optim = self._read_optimizer(path)
        _load_optimizer(self.optimizer, optim["generator"], path)
        if self.discriminator is not None:
            if self.config.kind != "edge" and "discriminator" not in optim:
                return int(state["step"])  # the adversarial term starts with this run
            _load_module(self.discriminator, folder / "discriminator.safetensors")
            _load_optimizer(self.d_optimizer, optim.get("discriminator"), path)
        return int(state["step"])

    def _read_optimizer(self, path: Path) -> dict:
        """The optimizer states of ``optimizer.pt``, its size bounded before it is read
        (Adam keeps two tensors a parameter; 4x the nets' bytes plus 16 MB is far
        more than any photo3d writes); anything torch cannot read is one line."""
        nets = [self.net] + ([self.discriminator] if self.discriminator is not None else [])
        limit = (16 << 20) + 4 * sum(p.numel() * p.element_size()
                                     for net in nets for p in net.parameters())
        data = read_bytes(path, max_bytes=limit)
        if compressed_records(io.BytesIO(data)):
            raise InputError(f"cannot read {path}: not a checkpoint photo3d train wrote (its "
                             "records are compressed, which torch.save never does)")
        try:
            optim = torch.load(io.BytesIO(data), map_location=self.device, weights_only=True)
        except Exception as err:  # noqa: BLE001 - torch.load raises many types on bad input
            first = (str(err).strip().splitlines() or [type(err).__name__])[0]
            raise InputError(f"cannot read {path}: not a checkpoint photo3d train wrote "
                             f"({first[:160]})") from None
        if not isinstance(optim, dict) or "generator" not in optim:
            raise InputError(f"cannot read {path}: not a checkpoint photo3d train wrote")
        return optim

    def export(self, path: str | Path) -> Path:
        """Write the net as ``.safetensors`` for ``photo3d make --inpainter learned``."""
        return save_safetensors(self.net, path)


def _load_module(module: nn.Module, path: Path) -> None:
    if not path.is_file():
        raise InputError(f"checkpoint file missing: {path}")
    state, _ = read_safetensors(path)
    check_state_dict(state, module, path.name)
    module.load_state_dict(state, strict=True)


def _load_optimizer(optimizer: torch.optim.Optimizer, saved: object, path: Path) -> None:
    """Restore Adam's per-parameter state ``saved`` (one of ``optimizer.pt``'s) into
    ``optimizer``, each tensor checked against its parameter (shape, finite values: a
    tampered file is one line, not a traceback at the first step); the learning rate
    and betas stay this run's (``--lr`` of a resumed run is the one used)."""
    groups = optimizer.state_dict()["param_groups"]
    params = [p for group in optimizer.param_groups for p in group["params"]]
    state = saved.get("state") if isinstance(saved, dict) else None
    if not isinstance(state, dict):
        raise InputError(f"cannot read {path}: not a checkpoint photo3d train wrote")
    for index, entry in state.items():
        param = params[index] if isinstance(index, int) and 0 <= index < len(params) else None
        if param is None or not _adam_entry(entry, param):
            raise InputError(f"cannot read {path}: not a checkpoint photo3d train wrote "
                             f"(bad optimiser state of parameter {index!r})")
    optimizer.load_state_dict({"state": state, "param_groups": groups})


def _adam_entry(entry: object, param: Tensor) -> bool:
    """True if ``entry`` is Adam's state of ``param``: its moments (finite, of its
    shape; the second >= 0) and a step count >= 0."""
    if not isinstance(entry, dict) or set(entry) != {"step", "exp_avg", "exp_avg_sq"}:
        return False
    step, moments = entry["step"], (entry["exp_avg"], entry["exp_avg_sq"])
    return (all(isinstance(m, Tensor) and m.is_floating_point() and m.shape == param.shape
                and bool(torch.isfinite(m).all()) for m in moments)
            and bool((moments[1] >= 0).all())
            and isinstance(step, Tensor) and step.numel() == 1 and not step.is_complex()
            and bool(torch.isfinite(step).all()) and float(step) >= 0)


def parameter_count(module: nn.Module) -> int:
    """Number of trainable parameters.

    Example:
        >>> parameter_count(nn.Linear(3, 2))
        8
    """
    return sum(p.numel() for p in module.parameters() if p.requires_grad)
