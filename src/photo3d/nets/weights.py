"""Load (and save) the weights of the three inpainting nets.

A weights folder holds, per net, either the authors' checkpoint (``edge-model.pth``,
``depth-model.pth``, ``color-model.pth``: plain state dicts) or our own
``edge.safetensors``, ``depth.safetensors``, ``color.safetensors`` (written by
:func:`save_safetensors`, with the architecture in the file's metadata, so compact
variants load too; a colour file whose ``config`` says ``"arch": "refine"`` holds
the refine colour net, :mod:`photo3d.nets.refine`, and may be stored in float16).
``.pth`` files are read with ``torch.load(weights_only=True)``
only: a file that needs arbitrary unpickling is refused. A ``.pth`` whose SHA-256 is
the authors' is logged as official; any other state dict with exactly the expected
keys and shapes is accepted as custom. Everything else raises
:class:`~photo3d.errors.InputError` with one line naming the file and the key.
"""

from __future__ import annotations

import json
import logging
import zipfile
from dataclasses import dataclass
from pathlib import Path

import torch
from torch import Tensor, nn

from photo3d.errors import InputError
from photo3d.files.atomic import writing
from photo3d.files.download import sha256_of
from photo3d.io.bounded import loads_json
from photo3d.nets.edge import EdgeGenerator
from photo3d.nets.partialconv import PartialConvUNet, color_net, depth_net
from photo3d.nets.refine import RefineNet

logger = logging.getLogger(__name__)

KINDS = ("edge", "depth", "color")

OFFICIAL_SHA256 = {
    "edge": "b1d768bd008ad5fe9f540004f870b8c3d355e4939b2009aa4db493fd313217c9",
    "depth": "2d0e63e89a22762ddfa8bc8c9f8c992e5532b140123274ffc6e4171baa1b76f8",
    "color": "383c9b1db70097907a6f9c8abb0303e7056f50d5456a36f34ab784592b8b2c20",
}
"""SHA-256 of the authors' ``edge-model.pth``, ``depth-model.pth``, ``color-model.pth``."""


@dataclass(frozen=True)
class InpaintingNets:
    """The three nets, in eval mode on ``device``.

    Attributes:
        edge: :class:`~photo3d.nets.edge.EdgeGenerator`.
        depth: :class:`~photo3d.nets.partialconv.PartialConvUNet` (layout ``"depth"``).
        color: :class:`~photo3d.nets.partialconv.PartialConvUNet` (layout ``"color"``)
            or :class:`~photo3d.nets.refine.RefineNet`.
        device: where they live.
        sources: per net, ``"official"``, ``"custom .pth"`` or ``"safetensors"``.
    """

    edge: nn.Module
    depth: nn.Module
    color: nn.Module
    device: torch.device
    sources: dict[str, str]


def resolve_device(device: str | torch.device | None = None) -> torch.device:
    """``device`` if given, else CUDA when available, else CPU."""
    if device is not None:
        return torch.device(device)
    return torch.device("cuda" if torch.cuda.is_available() else "cpu")


def build_net(kind: str, **config) -> nn.Module:
    """A fresh net of ``kind`` (``"edge"``, ``"depth"``, ``"color"``); no ``config`` =
    the authors' architecture, else the keyword arguments its class takes (a colour
    net with ``arch="refine"``: :class:`~photo3d.nets.refine.RefineNet`).

    Example:
        >>> type(build_net("color", arch="refine", channels=4, levels=2, blocks=1)).__name__
        'RefineNet'
    """
    if kind == "edge":
        return EdgeGenerator(**config)
    if kind == "color" and config.get("arch") == "refine":
        return RefineNet(**{k: v for k, v in config.items() if k != "arch"})
    if kind in ("depth", "color"):
        if not config:
            return depth_net() if kind == "depth" else color_net()
        channels = dict(in_channels=4, out_channels=1) if kind == "depth" else dict(
            in_channels=6, out_channels=3)
        return PartialConvUNet(**{**channels, **config, "layout": kind})
    raise ValueError(f"unknown net kind {kind!r}; expected one of {KINDS}")


def _kind_of(module: nn.Module) -> str:
    if isinstance(module, EdgeGenerator):
        return "edge"
    if isinstance(module, PartialConvUNet):
        return module.layout
    if isinstance(module, RefineNet):
        return "color"
    raise TypeError(f"cannot save {type(module).__name__}: not one of the inpainting nets")


def compressed_records(file) -> bool:
    """True if ``file`` (a path or a binary file) is a zip with a compressed record.
    ``torch.load`` inflates those, so a file of a few MB could take many GB;
    ``torch.save`` never compresses (a file that is not a zip: False).

    Example:
        >>> import io
        >>> buffer = io.BytesIO()
        >>> torch.save({"w": torch.zeros(4)}, buffer)
        >>> compressed_records(buffer)
        False
    """
    if not zipfile.is_zipfile(file):
        return False
    try:
        with zipfile.ZipFile(file) as archive:
            return any(info.compress_type != zipfile.ZIP_STORED
                       for info in archive.infolist())
    except zipfile.BadZipFile:
        return False  # a damaged zip: torch.load says so


def read_pth(path: Path) -> dict[str, Tensor]:
    """A plain state dict from a ``.pth`` file (``weights_only`` unpickling only, and
    no compressed records: see :func:`compressed_records`)."""
    try:
        compressed = compressed_records(path)
        state = None if compressed else torch.load(path, map_location="cpu",
                                                   weights_only=True)
    except OSError as err:
        raise InputError(f"cannot read {path}: {err.strerror or err}") from err
    except Exception as err:  # torch.load raises many types on malformed input
        reason = ("refused: it needs unpickling beyond tensors (weights_only)"
                  if "Weights only load failed" in str(err) else type(err).__name__)
        raise InputError(f"cannot read {path.name}: not a PyTorch state dict ({reason})") from err
    if compressed:
        raise InputError(f"cannot read {path.name}: not a PyTorch state dict (its records "
                         "are compressed, which torch.save never does)")
    if not isinstance(state, dict) or not all(
            isinstance(k, str) and isinstance(v, Tensor) for k, v in state.items()):
        raise InputError(f"cannot read {path.name}: not a PyTorch state dict "
                         f"(holds {type(state).__name__}, expected name -> tensor)")
    return state


def read_safetensors(path: Path) -> tuple[dict[str, Tensor], dict[str, str]]:
    """Tensors and metadata of a ``.safetensors`` file."""
    from safetensors import SafetensorError, safe_open

    try:
        with safe_open(str(path), framework="pt") as f:
            meta = f.metadata() or {}
            state = {k: f.get_tensor(k) for k in f.keys()}
    except (SafetensorError, OSError, ValueError) as err:
        raise InputError(f"cannot read {path.name}: not a safetensors file ({err})") from err
    return state, meta


def _fmt(shape) -> str:
    return str(tuple(int(s) for s in shape))


def check_state_dict(state: dict[str, Tensor], module: nn.Module, filename: str) -> None:
    """Raise :class:`InputError` unless ``state`` has exactly ``module``'s keys and shapes
    (and all-ones partial-conv mask kernels, and only finite values: a NaN weight makes
    every fill NaN).

    The message names ``filename``, the first offending key, and expected vs actual
    shape (with a count of further problems).
    """
    expected = module.state_dict()
    problems = [f"{filename}: missing key {k} (expected shape {_fmt(v.shape)})"
                for k, v in expected.items() if k not in state]
    problems += [f"{filename}: key {k} has shape {_fmt(state[k].shape)}, expected "
                 f"{_fmt(v.shape)}" for k, v in expected.items()
                 if k in state and tuple(state[k].shape) != tuple(v.shape)]
    problems += [f"{filename}: unexpected key {k}" for k in state if k not in expected]
    problems += [f"{filename}: key {k} must be all ones (the fixed partial-conv mask kernel)"
                 for k in expected if k.endswith("mask_conv.weight") and k in state
                 and tuple(state[k].shape) == tuple(expected[k].shape)
                 and not bool((state[k] == 1).all())]
    problems += [f"{filename}: key {k} holds NaN or infinite values" for k in expected
                 if k in state and state[k].is_floating_point()
                 and not bool(torch.isfinite(state[k]).all())]
    if problems:
        more = f" (and {len(problems) - 1} more problems)" if len(problems) > 1 else ""
        raise InputError(problems[0] + more)


def _check_counts(config: object, tensors: int) -> None:
    """Raise ValueError if ``config`` asks for more blocks or levels than a file of
    ``tensors`` tensors can hold (each holds at least one): such a net takes hours to
    build, even without memory."""
    for name in ("blocks", "levels"):
        value = config.get(name) if isinstance(config, dict) else None
        if isinstance(value, (int, float)) and value > tensors:
            raise ValueError(f"{name} {value}, but the file holds {tensors} tensors")


def load_net(kind: str, folder: str | Path) -> tuple[nn.Module, str]:
    """Load one net from ``folder``; returns ``(module in eval mode on CPU, source)``."""
    folder = Path(folder)
    pth, st = folder / f"{kind}-model.pth", folder / f"{kind}.safetensors"
    if pth.exists() and st.exists():
        raise InputError(f"{folder} holds both {pth.name} and {st.name}; keep one")
    if pth.exists():
        state = read_pth(pth)
        module = build_net(kind)
        check_state_dict(state, module, pth.name)
        source = "official" if sha256_of(pth) == OFFICIAL_SHA256[kind] else "custom .pth"
        name = pth.name
    elif st.exists():
        state, meta = read_safetensors(st)
        if meta.get("photo3d_net", kind) != kind:
            raise InputError(f"{st.name} holds the {meta['photo3d_net']} net, not {kind}")
        try:  # shapes only, no memory: the metadata may ask for a net of any size
            config = loads_json(meta.get("config", "{}"), what=f"{st.name}'s metadata")
            _check_counts(config, len(state))
            with torch.device("meta"):
                shaped = build_net(kind, **config)
        except (TypeError, ValueError, RuntimeError) as err:  # RuntimeError: sizes overflow
            raise InputError(f"{st.name}: bad architecture metadata ({err})") from err
        check_state_dict(state, shaped, st.name)
        module = build_net(kind, **config)  # as big as the file's tensors
        source, name = "safetensors", st.name
    else:
        raise InputError(f"{folder}: missing {pth.name} (or {st.name})")
    module.load_state_dict(state, strict=True)
    logger.info("%s: loaded %s weights from %s", kind, source, name)
    return module.eval(), source


def load_inpainting_nets(weights_dir: str | Path, *,
                         device: str | torch.device | None = None) -> InpaintingNets:
    """Load the edge, depth and colour nets from ``weights_dir``.

    Args:
        weights_dir: folder with the authors' ``*-model.pth`` or our ``*.safetensors``.
        device: torch device; default CUDA when available, else CPU.

    Returns:
        :class:`InpaintingNets` in eval mode.

    Raises:
        InputError: the folder or a file is missing, unreadable, or its keys/shapes
            do not match the architecture.

    Example:
        >>> import tempfile
        >>> with tempfile.TemporaryDirectory() as d:
        ...     for kind in KINDS:
        ...         cfg = dict(width=0.125, levels=3) if kind != "edge" else dict(width=0.125)
        ...         _ = save_safetensors(build_net(kind, **cfg), Path(d) / f"{kind}.safetensors")
        ...     nets = load_inpainting_nets(d, device="cpu")
        >>> nets.sources["depth"], nets.depth.training
        ('safetensors', False)
    """
    folder = Path(weights_dir)
    if not folder.is_dir():
        raise InputError(f"weights folder {folder} does not exist or is not a folder")
    dev = resolve_device(device)
    loaded = {kind: load_net(kind, folder) for kind in KINDS}
    return InpaintingNets(
        edge=loaded["edge"][0].to(dev), depth=loaded["depth"][0].to(dev),
        color=loaded["color"][0].to(dev), device=dev,
        sources={kind: src for kind, (_, src) in loaded.items()},
    )


def save_safetensors(module: nn.Module, path: str | Path, *,
                     dtype: torch.dtype | None = None) -> Path:
    """Write ``module``'s state dict and architecture to ``path`` (``.safetensors``).

    ``dtype``: store floating-point tensors in this type (e.g. ``torch.float16`` for
    shipped weights: half the size; they load back into float32 nets); None keeps them.
    """
    from safetensors.torch import save_file

    kind = _kind_of(module)
    config = {k: v for k, v in module.config.items() if k != "layout"}
    tensors = {k: v.detach().to("cpu").contiguous().clone()
               for k, v in module.state_dict().items()}
    if dtype is not None:
        tensors = {k: v.to(dtype) if v.is_floating_point() else v for k, v in tensors.items()}
    path = Path(path)
    with writing(path) as target:
        save_file(tensors, str(target),
                  metadata={"photo3d_net": kind, "config": json.dumps(config)})
    return path
