"""Monocular depth models from the Hugging Face hub: which one, and downloading it once.

:func:`default_depth_model` names the model used for photos without depth,
:func:`needs_download` says whether its weights are cached and :func:`fetch_model`
downloads them with a clear one-line error when offline (:func:`failure_reason`
says why a download or a load failed). The hub models live in the Hugging Face
cache; photo3d's own downloads go through :mod:`photo3d.files.download`.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from photo3d.errors import InputError, require
from photo3d.files.download import check_reachable

DEFAULT_MODEL = "depth-anything/Depth-Anything-V2-Small-hf"
"""The monocular model for photos that come with no depth (Apache-2.0, 25 M parameters)."""


def default_depth_model() -> str:
    """The model used when a photo has no depth: ``$PHOTO3D_DEPTH_MODEL`` or :data:`DEFAULT_MODEL`.

    Example:
        >>> import os
        >>> default_depth_model() == os.environ.get("PHOTO3D_DEPTH_MODEL", DEFAULT_MODEL)
        True
    """
    return os.environ.get("PHOTO3D_DEPTH_MODEL") or DEFAULT_MODEL


_HUB_NAME = re.compile(r"(?:[A-Za-z0-9][\w.-]{0,94}/)?[A-Za-z0-9][\w.-]{0,95}", re.ASCII)


def check_model_name(model: str | Path) -> str:
    """``model`` as a string once it names something that can exist: a local folder
    or ``.onnx`` file that exists, or a valid Hugging Face hub name
    (``[owner/]name``, letters, digits, ``-``, ``_`` and ``.``, at most 96 each, not
    starting or ending with ``-`` or ``.``, no ``--`` or ``..``).

    Raises:
        InputError: one line; a local path (``./...``, ``/...``, ``~...``, an
            ``.onnx`` name) that does not exist, or a name the hub refuses.

    Example:
        >>> check_model_name("depth-anything/Depth-Anything-V2-Small-hf")
        'depth-anything/Depth-Anything-V2-Small-hf'
        >>> check_model_name("./missing_dir")
        Traceback (most recent call last):
        photo3d.errors.InputError: depth model ./missing_dir not found: no such folder or .onnx file
    """
    name = str(model)
    shown = name if len(name) <= 60 else name[:57] + "..."
    shown = shown if shown.isprintable() else repr(shown)
    if not name:
        raise InputError("the depth model name is empty")
    try:
        if Path(name).exists():
            return name
    except (OSError, ValueError) as err:  # too long a name, a NUL byte
        raise InputError(f"depth model {shown}: not a usable path or name "
                         f"({getattr(err, 'strerror', None) or err})") from None
    local = (name.lower().endswith(".onnx") or name.startswith((".", "/", "~"))
             or os.sep in name.strip("/").replace("/", "", 1) or "\\" in name)
    if local:
        raise InputError(f"depth model {shown} not found: no such folder or .onnx file")
    if not (_HUB_NAME.fullmatch(name) and "--" not in name and ".." not in name
            and not name.endswith(("-", "."))
            and not any(part.endswith(("-", ".")) for part in name.split("/"))):
        raise InputError(f"depth model {shown} is neither an existing folder or .onnx "
                         "file nor a Hugging Face name (owner/name: letters, digits, "
                         "'-', '_', '.'; e.g. " + DEFAULT_MODEL + ")")
    return name


def _is_hub_name(name: str) -> bool:
    return not name.lower().endswith(".onnx") and not Path(name).exists()


def _weights_cached(name: str) -> bool:
    from huggingface_hub import try_to_load_from_cache

    if not isinstance(try_to_load_from_cache(name, "config.json"), str):
        return False
    return any(isinstance(try_to_load_from_cache(name, f), str)
               for f in ("model.safetensors", "pytorch_model.bin"))


def needs_download(model: str | Path) -> bool:
    """True for a hub model whose weights are not in the Hugging Face cache yet.

    Raises:
        InputError: ``model`` is neither an existing local model nor a valid hub
            name (:func:`check_model_name`).

    Example:
        >>> import tempfile
        >>> needs_download(tempfile.mkdtemp())  # a local folder
        False
    """
    name = check_model_name(model)
    if not _is_hub_name(name):
        return False
    try:
        return not _weights_cached(name)
    except ImportError:
        return False  # no huggingface_hub: loading will say which extra is missing


def fetch_model(model: str | Path, *, bar=None) -> None:
    """Download a hub model into the Hugging Face cache, once (nothing if cached or local).

    Args:
        model: a hub name (local folders and ``.onnx`` files are left alone).
        bar: a ``tqdm`` class for the download's byte progress (default: none shown;
            the library never prints).

    Raises:
        MissingExtra: transformers is not installed (extra ``depth``).
        InputError: ``model`` is not a valid name (:func:`check_model_name`), offline
            (``HF_HUB_OFFLINE`` set or the hub not reachable) or the download failed;
            one line.

    Example:
        >>> import tempfile
        >>> fetch_model(tempfile.mkdtemp())  # a local folder: nothing to download
    """
    name = str(model)
    if not needs_download(name):
        return
    require("transformers", "depth", purpose="monocular depth")
    hub = require("huggingface_hub", "depth", purpose="monocular depth")
    from huggingface_hub.utils import EntryNotFoundError

    constants, hf_hub_download = hub.constants, hub.hf_hub_download
    if constants.HF_HUB_OFFLINE:
        raise InputError(f"depth model {name} is not in the Hugging Face cache and "
                         "HF_HUB_OFFLINE is set")
    # the hub client retries for ~25 s when offline: find out at once
    check_reachable(constants.ENDPOINT, what=f"depth model {name}")
    quiet = _quiet_bar() if bar is None else bar
    try:
        for filename in ("config.json", "preprocessor_config.json"):
            hf_hub_download(name, filename, tqdm_class=quiet)
        try:
            hf_hub_download(name, "model.safetensors", tqdm_class=quiet)
        except EntryNotFoundError:  # older repos keep PyTorch weights only
            hf_hub_download(name, "pytorch_model.bin", tqdm_class=quiet)
    except (OSError, ValueError, EntryNotFoundError) as err:
        raise InputError(f"cannot download depth model {name}: "
                         f"{failure_reason(err, name)}") from err


def failure_reason(err: Exception, name: str) -> str:
    """A short reason (one line, at most 160 characters) why downloading or loading
    the model ``name`` (hub name or local folder) failed with ``err``.

    Example:
        >>> failure_reason(OSError("no   such file"), ".")
        'no such file'
    """
    from huggingface_hub import constants

    if constants.HF_HUB_OFFLINE and not Path(name).is_dir():
        return "not in the Hugging Face cache and HF_HUB_OFFLINE is set"
    text = " ".join(str(err).split()) or type(err).__name__
    return text if len(text) <= 160 else text[:157] + "..."


def _quiet_bar():
    from tqdm import tqdm

    class Quiet(tqdm):
        def __init__(self, *args, **kwargs):
            kwargs.pop("name", None)
            super().__init__(*args, **{**kwargs, "disable": True})

    return Quiet
