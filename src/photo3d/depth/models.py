"""Depth from a single photo with a monocular depth network (Hugging Face or ONNX).

``model`` is one of:

* a Hugging Face hub name (``depth-anything/Depth-Anything-V2-Small-hf``,
  ``Intel/dpt-hybrid-midas``, ``Intel/zoedepth-nyu-kitti``, ...) or a local folder
  saved with ``save_pretrained`` (``config.json``, weights and
  ``preprocessor_config.json``): run through ``transformers``'
  ``AutoImageProcessor`` + ``AutoModelForDepthEstimation`` (extra ``photo3d[depth]``).
  A hub model already in the Hugging Face cache is loaded without any network
  access; otherwise it is downloaded (``HF_HUB_OFFLINE=1`` forbids that,
  ``HF_HUB_ETAG_TIMEOUT`` bounds each request, default 10 s).
* a ``.onnx`` file: run with ``onnxruntime`` on normalised RGB ``(1, 3, h, w)``
  float input at the size fixed in the model's input shape, or for dynamic shapes
  the Depth Anything rule (shorter side 518, both sides multiples of 14, aspect
  kept). Mean/std and size come from a ``preprocessor_config.json`` next to the
  file or in its parent folder (the layout of ONNX exports on the hub), else
  ImageNet mean/std. The first output is the prediction.

What the output means (:func:`model_kind`), decided once per model:

* ``"disparity"`` (relative inverse depth, larger = nearer): Depth Anything
  (relative), DPT / MiDaS, and any model whose type is unknown (the common case
  for single-image networks; a warning says so).
* ``"depth"`` (metric depth, near = small): ZoeDepth, GLPN, Depth Pro, Prompt
  Depth Anything, Depth Anything *metric* models (``depth_estimation_type ==
  "metric"`` in the config) and DPT models fine-tuned on KITTI / NYU (name rule).
  ONNX files use a ``config.json`` beside them when present, else their file name
  (``zoe``, ``metric``, ``depth_pro``/``depthpro``, ``glpn``, ``unidepth`` ->
  depth).

Relative disparity is shifted so that its minimum is >= 0 (networks may output
small negative values, which photo3d would otherwise treat as unknown); the shift
changes nothing after the pipeline's min-max normalisation.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

from photo3d.depth.fetch import check_model_name, failure_reason
from photo3d.errors import InputError, require
from photo3d.io.bounded import read_json
from photo3d.io.images import read_image, to_float_image

DEPTH_TYPES = ("zoedepth", "glpn", "depth_pro", "prompt_depth_anything")
"""``model_type`` values whose networks output metric depth."""

DISPARITY_TYPES = ("depth_anything", "dpt")
"""``model_type`` values whose networks output relative inverse depth."""


_DEPTH_NAME_HINTS = ("zoe", "metric", "depth_pro", "depthpro", "glpn", "unidepth", "kitti", "nyu")
_IMAGENET = ((0.485, 0.456, 0.406), (0.229, 0.224, 0.225))


def model_kind(model_type: str | None, name: str = "", *, metric: bool = False) -> tuple[str, str]:
    """What a depth network outputs: ``("disparity" | "depth", reason)``.

    Args:
        model_type: the config's ``model_type`` (None when unknown, e.g. bare ONNX).
        name: the hub name or file path (used for the name rule).
        metric: the config says ``depth_estimation_type == "metric"``.

    Example:
        >>> model_kind("depth_anything")[0], model_kind("zoedepth")[0]
        ('disparity', 'depth')
        >>> model_kind(None, "models/depth_anything_v2_vits.onnx")
        ('disparity', 'assumed relative inverse depth (unknown model type)')
    """
    lowered = name.lower()
    if metric:
        return "depth", f"{model_type} metric model"
    if model_type in DEPTH_TYPES:
        return "depth", f"model type {model_type!r} outputs metric depth"
    if model_type == "dpt" and any(h in lowered for h in ("kitti", "nyu")):
        return "depth", "DPT fine-tuned on KITTI/NYU outputs metric depth"
    if model_type in DISPARITY_TYPES:
        return "disparity", f"model type {model_type!r} outputs relative inverse depth"
    if model_type is None and any(h in lowered for h in _DEPTH_NAME_HINTS):
        return "depth", "metric depth model (by its name)"
    return "disparity", "assumed relative inverse depth (unknown model type)"


@dataclass(frozen=True, eq=False)
class ModelDepth:
    """What a monocular network predicted for one photo.

    Attributes:
        depth: ``(H, W) float32`` at the image size (disparity-kind maps are >= 0).
        kind: ``"disparity"`` or ``"depth"``.
        reason: why that kind, e.g. ``"model type 'dpt' outputs relative inverse depth"``.
    """

    depth: np.ndarray
    kind: str
    reason: str


def estimate_depth(
    image: np.ndarray | str | Path, model: str | Path, *, device: str | None = None,
    kind: str | None = None,
) -> tuple[np.ndarray, str]:
    """Predict depth for one photo with a monocular network.

    Args:
        image: path or ``(H, W, 3)`` image (uint8, uint16 or float in [0, 1]).
        model: hub name, local ``save_pretrained`` folder, or ``.onnx`` file.
        device: torch device for Hugging Face models (default ``cuda`` if
            available, else ``cpu``); ignored for ONNX (CPU).
        kind: override what the output is (``"disparity"`` or ``"depth"``).

    Returns:
        ``(depth, kind)``: ``(H, W) float32`` at the image size and the kind
        (see :func:`run_model` for the reason too).

    Raises:
        MissingExtra: torch, transformers or onnxruntime is not installed (extra
            ``depth``; an :class:`InputError` too).
        InputError: the model cannot be found or loaded (offline and not cached), or
            an invalid ``kind``.

    Example:
        >>> depth, kind = estimate_depth("photo.jpg", "Intel/dpt-hybrid-midas")  # doctest: +SKIP
        >>> estimate_depth(np.zeros((8, 8, 3)), "missing.onnx")  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        photo3d.errors.InputError: ...
    """
    out = run_model(image, model, device=device, kind=kind)
    return out.depth, out.kind


def run_model(
    image: np.ndarray | str | Path, model: str | Path, *, device: str | None = None,
    kind: str | None = None,
) -> ModelDepth:
    """:func:`estimate_depth` with the reason for the kind, as a :class:`ModelDepth`.

    Example:
        >>> run_model(np.zeros((8, 8, 3)), "x.onnx", kind="z")  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        photo3d.errors.InputError: depth kind must be 'disparity' or 'depth', got 'z'
    """
    if kind not in (None, "disparity", "depth"):
        raise InputError(f"depth kind must be 'disparity' or 'depth', got {kind!r}")
    rgb = read_image(image) if isinstance(image, str | Path) else to_float_image(image)
    name = str(model)
    if name.lower().endswith(".onnx"):
        raw, model_type, metric = _run_onnx(rgb, Path(name))
    else:
        check_model_name(name)  # a missing folder or a name the hub refuses: one line
        raw, model_type, metric = _run_transformers(rgb, name, device)
    found, reason = model_kind(model_type, name, metric=metric)
    if kind is not None and kind != found:
        found, reason = kind, f"kind {kind!r} given by the caller"
    raw = raw.astype(np.float32)
    if found == "disparity" and raw.min() < 0:
        raw = raw - raw.min()
    return ModelDepth(raw, found, reason)


def _resize(array: np.ndarray, height: int, width: int) -> np.ndarray:
    """``(h, w)`` float map -> ``(height, width) float32``, bilinear."""
    im = Image.fromarray(np.ascontiguousarray(array, np.float32), "F")
    return np.asarray(im.resize((width, height), Image.Resampling.BILINEAR), np.float32)


@functools.lru_cache(maxsize=2)
def _load_transformers(name: str, device: str):
    require("torch", "depth", purpose="monocular depth", package="PyTorch")
    transformers = require("transformers", "depth", purpose="monocular depth")
    from transformers import AutoImageProcessor, AutoModelForDepthEstimation

    options = {}
    if not Path(name).is_dir():
        from huggingface_hub import try_to_load_from_cache

        cached = try_to_load_from_cache(name, "config.json")
        options["local_files_only"] = isinstance(cached, str)  # cached: no network at all
    elif not (Path(name) / "config.json").is_file():
        raise InputError(f"depth model folder {name} has no config.json (save it with "
                         "save_pretrained, or pass a hub name or an .onnx file)")
    processor_options = dict(options)
    if int(transformers.__version__.split(".")[0]) >= 5:
        processor_options["backend"] = "pil"  # same numbers as torchvision, no extra package
    logging = transformers.utils.logging
    bars = logging.is_progress_bar_enabled()
    logging.disable_progress_bar()  # the library never prints
    try:
        processor = AutoImageProcessor.from_pretrained(name, **processor_options)
        net = AutoModelForDepthEstimation.from_pretrained(name, **options)
    except (OSError, ValueError, KeyError) as err:
        raise InputError(f"cannot load depth model {name!r}: {failure_reason(err, name)}; "
                         "download it once while online (it is then cached) or pass a local "
                         "folder saved with save_pretrained") from err
    finally:
        if bars:
            logging.enable_progress_bar()
    return processor, net.to(device).eval()


def _run_transformers(rgb: np.ndarray, name: str, device: str | None):
    torch = require("torch", "depth", purpose="monocular depth", package="PyTorch")
    if device is None:
        device = "cuda" if torch.cuda.is_available() else "cpu"
    processor, net = _load_transformers(name, device)
    pixels = np.round(rgb * 255.0).astype(np.uint8)
    inputs = processor(images=pixels, return_tensors="pt").to(device)
    with torch.inference_mode():
        pred = net(**inputs).predicted_depth
    pred = pred.reshape(pred.shape[-2], pred.shape[-1])[None, None].float()
    pred = torch.nn.functional.interpolate(pred, size=rgb.shape[:2], mode="bilinear",
                                           align_corners=False)
    config = net.config
    metric = getattr(config, "depth_estimation_type", None) == "metric"
    return pred[0, 0].cpu().numpy(), config.model_type, metric


def _sidecar(path: Path, filename: str) -> dict:
    for folder in (path.parent, path.parent.parent):
        candidate = folder / filename
        if candidate.is_file():
            try:
                return read_json(candidate, max_bytes=1 << 20)
            except InputError:
                raise
            except OSError as err:
                raise InputError(f"cannot read {candidate}: {err}") from err
    return {}


def onnx_input_size(shape: list, image_hw: tuple[int, int], *, lower_bound: int = 518,
                    multiple: int = 14) -> tuple[int, int]:
    """``(h, w)`` to feed an ONNX model whose input has ``shape`` (NCHW).

    Fixed dimensions are used as they are; dynamic ones (strings or None) follow the
    Depth Anything rule: the shorter image side becomes ``lower_bound``, the aspect
    ratio is kept and both sides are rounded to multiples of ``multiple``.

    Example:
        >>> onnx_input_size([1, 3, 392, 518], (480, 640))
        (392, 518)
        >>> onnx_input_size(["batch", 3, "height", "width"], (480, 640))
        (518, 686)
    """
    fixed = [d if isinstance(d, int) and d > 0 else None for d in list(shape)[2:4]]
    if len(fixed) == 2 and None not in fixed:
        return fixed[0], fixed[1]
    scale = lower_bound / min(image_hw)
    h, w = (max(multiple, round(s * scale / multiple) * multiple) for s in image_hw)
    return h, w


def _run_onnx(rgb: np.ndarray, path: Path):
    ort = require("onnxruntime", "depth", purpose="monocular depth")
    if not path.is_file():
        raise InputError(f"depth model file not found: {path}")
    try:
        session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    except Exception as err:  # onnxruntime raises its own untyped errors; re-raised as ours
        raise InputError(f"cannot load ONNX depth model {path}: {err}") from err
    first = session.get_inputs()[0]
    if len(first.shape) != 4:
        raise InputError(f"ONNX depth model {path} has input shape {first.shape}; expected "
                         "(1, 3, height, width)")
    prep = _sidecar(path, "preprocessor_config.json")
    size = prep.get("size") or {}
    bound = int(size.get("height", size.get("shortest_edge", 518)))
    h, w = onnx_input_size(first.shape, rgb.shape[:2], lower_bound=bound,
                           multiple=int(prep.get("ensure_multiple_of", 14)))
    mean = np.asarray(prep.get("image_mean", _IMAGENET[0]), np.float32)
    std = np.asarray(prep.get("image_std", _IMAGENET[1]), np.float32)
    pixels = Image.fromarray(np.round(rgb * 255.0).astype(np.uint8))
    small = np.asarray(pixels.resize((w, h), Image.Resampling.BICUBIC), np.float32) / 255.0
    tensor = ((small - mean) / std).transpose(2, 0, 1)[None]
    dtype = np.float16 if "float16" in first.type else np.float32
    out = session.run(None, {first.name: tensor.astype(dtype)})[0]
    out = np.asarray(out, np.float32)
    out = out.reshape(out.shape[-2], out.shape[-1])
    config = _sidecar(path, "config.json")
    metric = config.get("depth_estimation_type") == "metric"
    return _resize(out, *rgb.shape[:2]), config.get("model_type"), metric
